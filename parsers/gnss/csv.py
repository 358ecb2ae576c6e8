"""GNSS device exports as the world writes them: CSV (any delimiter) and JSON lines.

Columns are recognised by name, whatever the case, spacing, ``_``/``-``
and unit notation (``lat``, ``Latitude``, ``Latitude [deg]``, ``lat_e7``,
``Speed (km/h)``, ``speed_mm_s``, ``gSpeed [mm/s]``):

=============  ===========================================================
``time``       date and time (``time``, ``timestamp``, ``utc``, ``datetime``,
               ``time utc``, ``gps time``), or seconds since 1970 (9-10 digits
               before the point); or a date column (``date``,
               ``utc date``, ``gps date``) beside a time-of-day column
               (``time``, ``utc time``, ``time of day``), combined per row.
``lat, lon``   ``lat``/``latitude``, ``lon``/``lng``/``long``/``longitude``;
               degrees, or scaled integers when the name or unit says so
               (``e7``, ``deg*1e7``, ``1e-7 deg``: ×1e-7; ``e6``/``microdeg``).
``speed``      ``speed``, ``ground speed``, ``gspeed``, ``sog``, ``speed over
               ground``; unit m/s unless given: km/h, mm/s, cm/s, knots, mph.
               **No speed column: speed NaN**, never 0.
``course``     ``course``, ``heading``, ``track``, ``cog``, ``course over
               ground``, ``headmot``; degrees (``e5``: ×1e-5, u-blox).
``device``     ``device``, ``device id``, ``unit``, ``unit id``, ``imei``
               (default: the file's stem).
``role``       ``head``/``eot`` (also locomotive/LTĐK, tail/end of train/MCĐT).
``valid``      true/false, 1/0, yes/no, A/V.
fix quality    ``fix``, ``fix type``, ``fix quality``, ``quality``,
               ``status``, ``solution``, ``pos mode``, ``mode``: words
               (``3D``, ``2D``, ``DGPS``, ``RTK fixed``, ``float``, ``no
               fix``, ``invalid``, ``DR``, ``dead reckoning``, ``estimated``,
               ``propagated``, ``time only`` …) or numbers — u-blox
               ``fixType`` codes when the name says *type* (0 no fix,
               1 dead reckoning, 2 2D, 3 3D, 4 GNSS+DR, 5 time only), NMEA GGA
               codes when it says *quality* (0 invalid, 1–5 fix, 6 dead
               reckoning, 7 manual, 8 simulator), gpsd / NMEA GSA mode codes
               when it says *mode* (0 not seen, 1 no fix, 2 2D, 3 3D).  Dead-reckoned fixes keep
               ``valid`` and are marked ``fix_quality = "dead_reckoning"``.
=============  ===========================================================

Any other column is read past and listed once per file in
``report.skipped`` (``CSV column 'hdop' (not read)``): not a reason to
reject the file.  A unit we do not know on a column we read is a header
error (we will not guess a scale).  JSON lines use the same names as keys;
other keys are ignored.  Times are ISO 8601 (``T`` or space; ``Z`` or an
offset → UTC, no zone → UTC) or ``DD/MM/YYYY HH:MM:SS``.

A broken row (a stray CR, a NUL, a wrong field count, a number beyond any
range, a lone surrogate, JSON nested a thousand deep) is rejected alone,
with the field named; the header line and ``#`` comments are blank.
"""

from __future__ import annotations

import math
import unicodedata
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from parsers.gnss.fields import (
    FALSE_WORDS,
    ROLE_ALIASES,
    TRUE_WORDS,
    RowError,
    cells_of,
    decode_line,
    delimiter_of,
    parse_decimal,
    time_field,
)
from parsers.gnss.fix_table import FixRows
from parsers.gnss.gpsd_json import JsonRowError, load_object, plain
from parsers.gnss.headers import (
    DEVICE_COLUMN_BY_NAME,
    UNIT_FACTORS,
    DeviceHeader,
    commented_header_cells,
    normal_name,
    parse_device_header,
    quality_codes_of,
    split_unit,
)
from parsers.gnss.lines import open_lines
from parsers.report import FileReport, ParseReport, device_of_file

if TYPE_CHECKING:
    pass

_QUALITY_WORDS_NO_FIX = frozenset(
    {"no fix", "nofix", "none", "invalid", "not valid", "no", "n", "v", "false", "time only", "time", "0 no fix"}
)
_QUALITY_WORDS_DR = frozenset(
    {"dr", "dead reckoning", "dead reckoned", "dead-reckoning", "estimated", "e", "propagated", "extrapolated"}
)
_QUALITY_WORDS_FIX = frozenset(
    {
        "fix",
        "2d",
        "3d",
        "2d fix",
        "3d fix",
        "gps",
        "gnss",
        "dgps",
        "dgnss",
        "differential",
        "sps",
        "pps",
        "rtk",
        "rtk fixed",
        "rtk float",
        "fixed",
        "float",
        "single",
        "sbas",
        "a",
        "d",
        "r",
        "f",
        "valid",
        "ok",
        "yes",
        "true",
        "gnss+dr",
        "gnss + dr",
        "gps+dr",
    }
)


def _flag(value: Any) -> bool:
    if value is None or isinstance(value, bool):
        return value is not False
    text = str(value).strip().casefold()
    if text in TRUE_WORDS or text == "":
        return True
    if text in FALSE_WORDS:
        return False
    raise RowError("valid", f"valid: expected true/false, 1/0 or yes/no, found '{value}'")


def fix_quality(value: Any, codes: str) -> tuple[bool, str]:
    """A fix-quality cell → (valid, ``fix_quality``); RowError when it cannot be read."""
    if value is None:
        return True, ""
    text = " ".join(str(value).strip().casefold().replace("_", " ").split())
    if text == "":
        return True, ""
    if text.isascii() and text.isdigit():
        code = int(text) if len(text) <= 3 else 999
        if codes == "ublox" and code <= 5:
            return {0: (False, "no_fix"), 1: (True, "dead_reckoning"), 5: (False, "no_fix")}.get(code, (True, "gnss"))
        if codes == "gga" and code <= 8:
            if code == 6:
                return True, "dead_reckoning"
            return (True, "gnss") if 1 <= code <= 5 else (False, "no_fix")
        if codes == "mode" and code <= 3:  # 0 not seen, 1 no fix, 2 2D, 3 3D
            return (True, "gnss") if code >= 2 else (False, "no_fix")
        hint = (
            ""
            if codes
            else " (name the column 'fix type' for u-blox codes, 'fix quality' for NMEA GGA codes or 'mode' for gpsd's)"
        )
        raise RowError("quality", f"fix quality: code '{text[:12]}' is not known{hint}")
    if text in _QUALITY_WORDS_NO_FIX:
        return False, "no_fix"
    if text in _QUALITY_WORDS_DR or text.startswith(("dead reck", "dr only")):
        return True, "dead_reckoning"
    if text in _QUALITY_WORDS_FIX or text.startswith(("rtk", "dgps", "3d", "2d")):
        return True, "gnss"
    raise RowError("quality", f"fix quality: '{str(value).strip()[:40]}' is not known (e.g. 3D, DGPS, no fix, DR)")


def _scaled(value: Any, what: str, factor: float) -> float:
    number = parse_decimal(value, what)
    return number * factor


def _row(values: Mapping[str, Any], header: DeviceHeader, default_device: str, roles: Mapping[str, str]) -> dict:
    """One row (field name → raw value) → fix fields."""
    if "time" in values:
        time_ns = time_field(values.get("time"))
    else:
        date, tod = str(values.get("date") or "").strip(), str(values.get("tod") or "").strip()
        if not date or not tod:
            raise RowError("time", "time: the date and the time-of-day columns must both be given")
        time_ns = time_field(f"{date} {tod}")
    device = values.get("device")
    device = default_device if device is None or str(device).strip() == "" else str(device).strip()
    role_raw = values.get("role")
    role_text = "" if role_raw is None else " ".join(unicodedata.normalize("NFC", str(role_raw)).casefold().split())
    if role_text not in ROLE_ALIASES:
        raise RowError("role", f"role: '{role_raw}' is not head or eot")
    role = ROLE_ALIASES[role_text] or roles.get(device, "")
    f = header.factor
    lat = _scaled(values.get("lat"), "latitude", f.get("lat", 1.0))
    lon = _scaled(values.get("lon"), "longitude", f.get("lon", 1.0))
    if abs(lat) > 90:
        raise RowError("range", f"latitude {lat:g}° is out of range ±90°")
    if abs(lon) > 180:
        raise RowError("range", f"longitude {lon:g}° is out of range ±180°")
    if math.isnan(lat) != math.isnan(lon):
        raise RowError("position", "latitude and longitude must be given together")
    speed = _scaled(values.get("speed"), "speed", f.get("speed", 1.0))
    if speed < 0:
        raise RowError("range", f"speed: a speed cannot be negative ({speed:g} m/s)")
    course = _scaled(values.get("course"), "course", f.get("course", 1.0))
    valid, quality = fix_quality(values.get("quality"), header.quality_codes)
    valid = valid and _flag(values.get("valid")) and not math.isnan(lat)
    if not valid:
        quality = "no_fix"
    return {
        "time_ns": time_ns,
        "device": device,
        "role": role,
        "lat": lat,
        "lon": lon,
        "speed_mps": speed,
        "course_deg": course,
        "valid": valid,
        "fix_quality": quality,
    }


# JSON keys carry no unit brackets: the few names that imply one.
_JSON_KEY_UNITS = {"speed kmh": ("speed", 1 / 3.6), "speed mps": ("speed", 1.0)}


def _json_values(text: str) -> tuple[dict[str, Any], DeviceHeader]:
    try:
        obj = load_object(text)
    except JsonRowError as exc:
        raise RowError(exc.category, exc.reason) from None
    values: dict[str, Any] = {}
    header = DeviceHeader(0)
    for key in obj:
        name, unit = split_unit(str(key))
        column = DEVICE_COLUMN_BY_NAME.get(name)
        if (name, unit) == ("speed", "kmh") or normal_name(str(key)) in _JSON_KEY_UNITS:
            column = "speed"
            header.factor["speed"] = _JSON_KEY_UNITS.get(normal_name(str(key)), ("speed", 1 / 3.6))[1]
        elif column in ("lat", "lon", "course", "speed") and unit:
            if unit not in UNIT_FACTORS:
                raise RowError("json", f"key '{key}': unit '{unit}' is not one we know")
            header.factor[column] = UNIT_FACTORS[unit]
        if column is None:
            continue
        if column in values:
            raise RowError("json", f"key '{key}' repeats column {column}")
        try:
            values[column] = plain(obj, key)
        except JsonRowError as exc:
            raise RowError(exc.category, exc.reason) from None
        if column == "quality":
            header.quality_codes = quality_codes_of(name)
    missing = [c for c in ("lat", "lon") if c not in values]
    if "time" not in values and not ("date" in values and "tod" in values):
        missing.insert(0, "time")
    if missing:
        raise RowError("json", f"missing key(s) {', '.join(missing)}")
    return values, header


# Rows of a CSV read together on the vectorized path (parsers.gnss.csv_fast); smaller
# batches (a short file, the tail) are read per row, where the fixed cost would dominate.
FAST_BATCH_ROWS = 50_000
FAST_MIN_ROWS = 64
FAST_PATH = True  # False: every row per row (the tests compare the two paths)


def _one_line(
    text: str, fmt: str, header: DeviceHeader | None, delimiter: str, stem: str, roles: Mapping[str, str]
) -> dict[str, Any]:
    """One data line → fix fields; RowError with the reason."""
    if fmt == "jsonl":
        values, json_header = _json_values(text)
        return _row(values, json_header, stem, roles)
    assert header is not None
    cells = cells_of(text, delimiter)
    if len(cells) != header.width:
        hint = " (a decimal comma in a ','-separated file needs quotes)" * (len(cells) > header.width)
        raise RowError("fields", f"expected {header.width} fields, found {len(cells)}{hint}")
    return _row({name: cells[i] for name, i in header.at.items()}, header, stem, roles)


class DeviceLines:
    """One device export's lines, read as they come (all at once, or a block at a time as a file grows).

    Every line is counted; rows are appended to ``rows`` in line order.  A
    data row depends only on the header, so a block's rows are final.
    """

    def __init__(
        self, fr: FileReport, report: ParseReport, rows: FixRows, fmt: str, stem: str, roles: Mapping[str, str]
    ) -> None:
        self.fr, self.report, self.rows = fr, report, rows
        self.fmt, self.stem, self.roles = fmt, stem, roles
        self.header: DeviceHeader | None = None
        self.delimiter = ","

    def _per_row(self, number: int, raw: bytes) -> None:
        fr = self.fr
        text = decode_line(raw, fr)
        if not text.strip() or text.lstrip().startswith("#"):
            fr.blank += 1
            return
        try:
            fix = _one_line(text, self.fmt, self.header, self.delimiter, self.stem, self.roles)
        except RowError as exc:
            self.report.reject(fr, number, exc.category, exc.reason, raw)
            return
        fr.records += 1
        self.rows.add(**fix, source=self.fmt, sentence="", file=fr.file, line=number)

    def _flush(self, batch: list[tuple[int, bytes]]) -> None:
        fast = None
        header, fr = self.header, self.fr
        if FAST_PATH and header is not None and len(batch) >= FAST_MIN_ROWS:
            from parsers.gnss.csv_fast import fast_batch  # pyarrow: loaded by the first device CSV batch

            fast = fast_batch(
                [raw for _, raw in batch], header, self.delimiter, self.stem, self.roles, fix_quality, _flag
            )
        if fast is None:
            for number, raw in batch:
                self._per_row(number, raw)
            return
        start = len(self.rows)
        ok = fast.ok
        numbers = np.fromiter((number for number, _ in batch), np.int64, len(batch))
        self.rows.extend(
            time_ns=fast.time_ns[ok],
            device_names=fast.device,
            device_code=fast.device_code[ok],
            role=fast.role[ok],
            lat=fast.lat[ok],
            lon=fast.lon[ok],
            speed_mps=fast.speed_mps[ok],
            course_deg=fast.course_deg[ok],
            valid=fast.valid[ok],
            source=self.fmt,
            file=fr.file,
            line=numbers[ok],
            fix_quality=fast.fix_quality[ok],
        )
        fr.records += int(ok.sum())
        for k in np.flatnonzero(~ok):
            self._per_row(*batch[k])
        if not ok.all():
            self.rows.sort_by_line_from(start)  # rows read per row came after the batch's vectorized ones

    def add(self, lines: Iterable[tuple[int, bytes]]) -> None:
        """Lines (number, text without its end); the caller counts them in ``lines_read``."""
        fr = self.fr
        batch: list[tuple[int, bytes]] = []
        for number, raw in lines:
            if self.header is not None:
                batch.append((number, raw))
                if len(batch) >= FAST_BATCH_ROWS:
                    self._flush(batch)
                    batch.clear()
                continue
            text = decode_line(raw, fr)
            if not text.strip() or text.lstrip().startswith("#"):
                fr.blank += 1
                if self.fmt == "csv" and (cells := commented_header_cells(text, delimiter_of(text))) is not None:
                    self._take_header(cells, delimiter_of(text))  # gpscsv --header 2: "# time,lat,lon,…"
                continue
            if self.fmt == "jsonl":
                self._per_row(number, raw)
                continue
            delimiter = delimiter_of(text)
            try:
                cells = cells_of(text, delimiter)
                parse_device_header(cells)
            except (ValueError, RowError) as exc:
                reason = f"not the device-stream header: {exc}; expected time, lat, lon, …"
                self.report.reject(fr, number, "header", reason, raw)
                continue
            self._take_header(cells, delimiter)
            fr.blank += 1  # the header: no record, nothing lost
        self._flush(batch)

    def _take_header(self, cells: list[str], delimiter: str) -> None:
        self.delimiter = delimiter
        self.header = parse_device_header(cells)
        for name in self.header.extra:
            self.report.skipped[f"CSV column '{name[:40]}' (not read)"] += 1


def parse_device_file(path: Path, report: ParseReport, rows: FixRows, fmt: str, roles: Mapping[str, str]) -> None:
    """One device export (``fmt`` ``"csv"`` or ``"jsonl"``); rows appended, every line counted."""
    fr, lines = open_lines(path, report)
    DeviceLines(fr, report, rows, fmt, device_of_file(path), roles).add(lines)
