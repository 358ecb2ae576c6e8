"""GNSS telemetry: monitoring-centre tables, device streams, and format recognition.

All sources give the one fix table of :data:`FIX_COLUMNS` (defined and
documented in ``parsers.nmea``, re-exported here); the centre table also
gives crossing states (:data:`CROSSING_COLUMNS`).

Monitoring-centre table (seed 004, Table 1)
-------------------------------------------
::

    TIMESTAMP  Mã tàu  Vĩ độ  Kinh độ  Vận tốc (km/h)  Mã đường ngang 1  Trạng thái kết nối đường ngang 1  …
    2026-01-19 17:06:41  VN0001  20,7  105,9  54,6  11+850  Cảnh báo  …

* delimiter: tab, ``;`` or ``,``, taken from the header line in that order
  of preference; decimal commas (``20,7``) as is with tab or ``;``, inside
  quotes with ``,``;
* headers in Vietnamese or English, any order, case and spacing free:
  ``TIMESTAMP``; ``Mã tàu`` / ``train code``; ``Vĩ độ`` / ``latitude``;
  ``Kinh độ`` / ``longitude``; ``Vận tốc (km/h)`` / ``speed (km/h)`` (a bare
  ``speed`` is km/h here); then any number N of crossing pairs ``Mã đường
  ngang N`` / ``crossing N code`` and ``Trạng thái kết nối đường ngang N`` /
  ``crossing N state``;
* times ``YYYY-MM-DD HH:MM:SS[.fff]`` (or ``DD/MM/YYYY HH:MM:SS``), without a
  zone: read as UTC unless ``utc_offset_h`` says the table is local time
  (the paper does not say; Vietnam is UTC+7);
* crossing codes are kilometre posts ``km+metres``: ``11+850`` is km 11.850
  (``chainage_m`` 11850.0); an optional ``Km`` prefix and a decimal metre
  part are accepted and the code is written back as ``11+850``;
* states: ``Cảnh báo``/``warning``, ``Bình thường``/``normal``, ``Mất kết
  nối``/``disconnected`` → ``warning``, ``normal``, ``disconnected``; any other
  state is kept verbatim in ``state`` and counted in the report's
  ``unknown_labels``; ``state_raw`` always holds the text as written.  A pair
  with neither code nor state gives no crossing row;
* the centre writes newest first; rows come back in time order (stable),
  each with its original line number.

Each data row gives one fix: ``device`` = the train code, ``role`` ``head``
(the centre reports the locomotive unit), ``source`` ``centre``, speed from
km/h, ``valid`` True (the centre gives no fix quality), no course.

Device streams
--------------
CSV (delimiter as above) with a header, or JSON lines (one object a line)
with the same keys: ``time`` (required), ``device`` (default: the file name
stem), ``role`` (``head``/``eot``; also ``locomotive``/``LTĐK`` and
``end of train``/``tail``/``MCĐT``; default ``""``), ``lat``, ``lon``,
``speed`` or ``speed_mps`` (m/s) or ``speed_kmh`` / ``speed (km/h)``, optional
``course``/``course_deg``, optional ``valid`` (true/false, 1/0, yes/no).
Other keys of a JSON object are ignored.  Times are ISO 8601 with a date and
a time (``T`` or a space between); ``Z`` or an offset is converted to UTC, a
time without a zone is taken as UTC.  A row without a position, or with
``valid`` false, is a no-fix row (``valid`` False).

Line accounting: a header line and ``#`` comment lines are counted as blank
(no record, nothing lost); lines before the header, and rows that do not
parse, are rejected with the reason.

Format recognition (:func:`parse_gnss`)
---------------------------------------
From the first line that is not blank or a ``#`` comment: ``$`` or ``!``
(possibly after a device tag) → NMEA; ``{`` → JSON lines; a header that
reads as a centre table (it has a train column) → centre; a header that
reads as a device stream → CSV.  Anything else: every line is rejected with
the reason, no exception.
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
import re
import unicodedata
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd

from parsers.fix_table import FIX_COLUMNS, FixRows, check_roles, utc_times
from parsers.gnss_lines import open_lines
from parsers.gnss_stream import StreamParser
from parsers.gnss_time import parse_time_ns
from parsers.nmea import DEVICE_TAG_RE, KMH_MPS
from parsers.report import FileReport, ParseReport
from parsers.sources import open_input

__all__ = [
    "CROSSING_COLUMNS",
    "CROSSING_STATES",
    "FIX_COLUMNS",
    "GnssFormat",
    "parse_centre_table",
    "parse_crossing_code",
    "parse_device_stream",
    "parse_gnss",
    "parse_time_ns",
    "recognise_format",
]

CROSSING_COLUMNS = ("time", "train", "crossing", "chainage_m", "state", "state_raw", "file", "line")
CROSSING_STATES = ("warning", "normal", "disconnected")

GnssFormat = Literal["nmea", "jsonl", "csv", "centre", "unknown"]
_PEEK_BYTES = 64 * 1024

_NS = 1_000_000_000
_EPOCH = dt.date(1970, 1, 1)

_STATE_ALIASES = {
    "cảnh báo": "warning",
    "warning": "warning",
    "bình thường": "normal",
    "normal": "normal",
    "mất kết nối": "disconnected",
    "disconnected": "disconnected",
}
_ROLE_ALIASES = {
    "": "",
    "head": "head",
    "locomotive": "head",
    "loco": "head",
    "ltđk": "head",
    "eot": "eot",
    "end of train": "eot",
    "tail": "eot",
    "mcđt": "eot",
}
_TRUE = {"true", "1", "yes", "y", "a"}
_FALSE = {"false", "0", "no", "n", "v"}

_CENTRE_ALIASES: dict[str, tuple[str, ...]] = {
    "time": ("timestamp", "time", "thời gian", "thời điểm"),
    "train": ("mã tàu", "train code", "train", "train id"),
    "lat": ("vĩ độ", "latitude", "lat"),
    "lon": ("kinh độ", "longitude", "lon"),
    "speed_kmh": ("vận tốc kmh", "vận tốc", "tốc độ kmh", "tốc độ", "speed kmh", "speed"),
}
_CENTRE_KEYS = {alias: column for column, aliases in _CENTRE_ALIASES.items() for alias in aliases}
_CROSSING_CODE_RE = re.compile(r"(?:mã đường ngang|crossing) (\d+)(?: code)?|crossing code (\d+)")
_CROSSING_STATE_RE = re.compile(
    r"(?:trạng thái kết nối đường ngang|trạng thái đường ngang) (\d+)|crossing (\d+) (?:connection )?(?:state|status)"
)
_DEVICE_ALIASES: dict[str, tuple[str, ...]] = {
    "time": ("time", "timestamp", "utc", "datetime", "time utc"),
    "device": ("device", "device id", "unit", "unit id"),
    "role": ("role",),
    "lat": ("lat", "latitude"),
    "lon": ("lon", "lng", "long", "longitude"),
    "speed_mps": ("speed", "speed mps"),
    "speed_kmh": ("speed kmh",),
    "course_deg": ("course", "course deg", "heading", "track", "cog"),
    "valid": ("valid", "fix"),
}
_DEVICE_KEYS = {alias: column for column, aliases in _DEVICE_ALIASES.items() for alias in aliases}
_UNITS = {"km/h": "kmh", "kmh": "kmh", "kph": "kmh", "m/s": "mps", "mps": "mps", "deg": "deg", "°": "deg"}
_UNIT_RE = re.compile(r"^(.*?)\s*\(\s*([^)]*?)\s*\)$")

_NUMBER_RE = re.compile(r"[+-]?\d+(?:[.,]\d+)?")
_KM_POST_RE = re.compile(r"(?:km\s*)?(\d{1,4})\s*\+\s*(\d{3}(?:[.,]\d+)?)", re.IGNORECASE)
_MINUS = str.maketrans({"−": "-", "–": "-"})


class RowError(Exception):
    """A row that cannot be used: ``category`` for the counts, ``reason`` for people."""

    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


# ------------------------------------------------------------------- fields


def header_key(cell: str) -> str:
    """``Vận tốc (km/h)`` → ``vận tốc kmh``; ``speed_kmh`` → ``speed kmh``: case, spacing, ``_``/``-`` free."""
    text = " ".join(unicodedata.normalize("NFC", cell).casefold().replace("_", " ").replace("-", " ").split())
    m = _UNIT_RE.match(text)
    if m:
        base, unit = m.group(1), m.group(2).replace(" ", "")
        text = f"{base} {_UNITS.get(unit, unit)}".strip()
    return text


def parse_decimal(value: Any, what: str) -> float:
    """``20,7`` / ``20.7`` / ``−3`` / a JSON number → float; empty or null → NaN; RowError otherwise."""
    if value is None:
        return math.nan
    if isinstance(value, bool):
        raise RowError("number", f"{what}: expected a number, found {json.dumps(value)}")
    if isinstance(value, int | float):
        if not math.isfinite(value):
            raise RowError("number", f"{what}: expected a finite number, found {value}")
        return float(value)
    text = str(value).strip().translate(_MINUS)
    if not text:
        return math.nan
    if not _NUMBER_RE.fullmatch(text):
        raise RowError("number", f"{what}: expected a number (e.g. 20,7 or 20.7), found '{text}'")
    return float(text.replace(",", "."))


def _position(lat_raw: Any, lon_raw: Any) -> tuple[float, float]:
    lat = parse_decimal(lat_raw, "latitude")
    lon = parse_decimal(lon_raw, "longitude")
    if not math.isnan(lat) and abs(lat) > 90:
        raise RowError("range", f"latitude {lat:g}° is out of range ±90°")
    if not math.isnan(lon) and abs(lon) > 180:
        raise RowError("range", f"longitude {lon:g}° is out of range ±180°")
    if math.isnan(lat) != math.isnan(lon):
        raise RowError("position", "latitude and longitude must be given together")
    return lat, lon


def _speed(value: Any, what: str, factor: float) -> float:
    speed = parse_decimal(value, what)
    if speed < 0:
        raise RowError("range", f"{what}: a speed cannot be negative ({speed:g})")
    return speed * factor


def parse_crossing_code(text: str) -> tuple[str, float]:
    """Kilometre post ``11+850`` (or ``Km11+850``, ``11 + 850,5``) → (``11+850``, 11850.0 m); ValueError otherwise."""
    m = _KM_POST_RE.fullmatch(text.strip())
    if m is None:
        raise ValueError(f"crossing code '{text.strip()}' is not a kilometre post km+metres (e.g. 11+850)")
    km, metres = int(m.group(1)), float(m.group(2).replace(",", "."))
    return f"{km}+{m.group(2).replace(',', '.')}", km * 1000.0 + metres


def _time(value: Any, utc_offset_h: float = 0.0) -> int:
    if value is None or (isinstance(value, str) and not value.strip()):
        raise RowError("time", "time: empty; every row needs a date and time")
    try:
        return parse_time_ns(str(value), utc_offset_h)
    except ValueError as exc:
        raise RowError("time", f"time: {exc}") from None


def _decode(raw: bytes, fr: FileReport) -> str:
    """UTF-8, else CP1258 (Vietnamese Windows, whose tone marks are combining): NFC either way."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        fr.encoding = "cp1258"
        text = raw.decode("cp1258", errors="replace")
    return unicodedata.normalize("NFC", text)


def _delimiter(line: str) -> str:
    return "\t" if "\t" in line else ";" if ";" in line else ","


def _cells(line: str, delimiter: str) -> list[str]:
    return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])


# ------------------------------------------------------------- centre table


@dataclass
class CentreHeader:
    """Column positions of a centre table."""

    width: int
    columns: dict[str, int]
    crossings: list[tuple[int, int, int]]  # (N, code column, state column), by N


def parse_centre_header(cells: list[str]) -> CentreHeader:
    """Header cells → column positions; ValueError with the reason if not a centre table header."""
    columns: dict[str, int] = {}
    codes: dict[int, int] = {}
    states: dict[int, int] = {}
    for i, cell in enumerate(cells):
        key = header_key(cell)
        if (code := _CROSSING_CODE_RE.fullmatch(key)) is not None:
            n, target = int(code.group(1) or code.group(2)), codes
        elif (state := _CROSSING_STATE_RE.fullmatch(key)) is not None:
            n, target = int(state.group(1) or state.group(2)), states
        elif key in _CENTRE_KEYS:
            column = _CENTRE_KEYS[key]
            if column in columns:
                raise ValueError(f"column '{cell.strip()}' given twice")
            columns[column] = i
            continue
        else:
            raise ValueError(f"unknown column '{cell.strip()}'")
        if n in target:
            raise ValueError(f"column '{cell.strip()}' given twice")
        target[n] = i
    missing = [c for c in _CENTRE_ALIASES if c not in columns]
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    unpaired = sorted(set(codes) ^ set(states))
    if unpaired:
        raise ValueError(f"crossing {unpaired[0]} needs both a code and a state column")
    return CentreHeader(len(cells), columns, [(n, codes[n], states[n]) for n in sorted(codes)])


@dataclass
class CrossingRows:
    """Crossing-state rows being collected."""

    time: list[int] = field(default_factory=list)
    train: list[str] = field(default_factory=list)
    crossing: list[str] = field(default_factory=list)
    chainage_m: list[float] = field(default_factory=list)
    state: list[str] = field(default_factory=list)
    state_raw: list[str] = field(default_factory=list)
    file: list[str] = field(default_factory=list)
    line: list[int] = field(default_factory=list)

    def frame(self) -> pd.DataFrame:
        return pd.DataFrame(
            {
                "time": utc_times(self.time),
                "train": pd.Categorical(self.train),
                "crossing": pd.Categorical(self.crossing),
                "chainage_m": np.array(self.chainage_m, dtype="float64"),
                "state": pd.Categorical(self.state),
                "state_raw": pd.Series(self.state_raw, dtype=str),
                "file": pd.Categorical(self.file),
                "line": np.array(self.line, dtype="int64"),
            },
            columns=list(CROSSING_COLUMNS),
        )


def _centre_row(
    cells: list[str], header: CentreHeader, utc_offset_h: float
) -> tuple[int, str, float, float, float, list[tuple[str, float, str, str]]]:
    if len(cells) != header.width:
        hint = " (a decimal comma in a ','-separated file needs quotes)" if len(cells) > header.width else ""
        raise RowError("fields", f"expected {header.width} fields, found {len(cells)}{hint}")
    col = header.columns
    time_ns = _time(cells[col["time"]], utc_offset_h)
    train = cells[col["train"]].strip()
    if not train:
        raise RowError("train", "train code: empty")
    lat, lon = _position(cells[col["lat"]], cells[col["lon"]])
    speed = _speed(cells[col["speed_kmh"]], "speed (km/h)", KMH_MPS)
    crossings = []
    for n, code_at, state_at in header.crossings:
        code_raw, state_raw = cells[code_at].strip(), cells[state_at].strip()
        if not code_raw and not state_raw:
            continue
        if not code_raw or not state_raw:
            raise RowError("crossing", f"crossing {n}: a code needs a state and a state a code")
        try:
            code, chainage = parse_crossing_code(code_raw)
        except ValueError as exc:
            raise RowError("crossing", f"crossing {n}: {exc}") from None
        state = _STATE_ALIASES.get(" ".join(unicodedata.normalize("NFC", state_raw).casefold().split()), state_raw)
        crossings.append((code, chainage, state, state_raw))
    return time_ns, train, lat, lon, speed, crossings


def _parse_centre_file(
    path: Path, report: ParseReport, fixes: FixRows, crossings: CrossingRows, utc_offset_h: float
) -> None:
    fr, lines = open_lines(path, report)
    header: CentreHeader | None = None
    delimiter = "\t"
    for number, raw in lines:
        text = _decode(raw, fr)
        if not text.strip() or text.lstrip().startswith("#"):
            fr.blank += 1
            continue
        if header is None:
            delimiter = _delimiter(text)
            try:
                header = parse_centre_header(_cells(text, delimiter))
            except ValueError as exc:
                reason = f"not the centre table header: {exc}; expected TIMESTAMP, train code, latitude, …"
                report.reject(fr, number, "header", reason, raw)
                continue
            fr.blank += 1  # the header: no record, nothing lost
            continue
        try:
            time_ns, train, lat, lon, speed, states = _centre_row(_cells(text, delimiter), header, utc_offset_h)
        except RowError as exc:
            report.reject(fr, number, exc.category, exc.reason, raw)
            continue
        fr.records += 1
        fixes.add(
            time_ns=time_ns,
            device=train,
            role="head",
            lat=lat,
            lon=lon,
            speed_mps=speed,
            course_deg=math.nan,
            valid=not math.isnan(lat),
            source="centre",
            sentence="",
            file=fr.file,
            line=number,
        )
        for code, chainage, state, state_raw in states:
            if state not in CROSSING_STATES:
                report.unknown_labels[f"crossing state '{state_raw}'"] += 1
            crossings.time.append(time_ns)
            crossings.train.append(train)
            crossings.crossing.append(code)
            crossings.chainage_m.append(chainage)
            crossings.state.append(state)
            crossings.state_raw.append(state_raw)
            crossings.file.append(fr.file)
            crossings.line.append(number)


def _in_time_order(frame: pd.DataFrame) -> pd.DataFrame:
    """Stable sort by time, unknown times last."""
    return frame.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)


def parse_centre_table(
    paths: Iterable[Path | str], *, utc_offset_h: float = 0.0
) -> tuple[pd.DataFrame, pd.DataFrame, ParseReport]:
    """Parse monitoring-centre tables: (fixes in time order, crossing states in time order, report).

    ``utc_offset_h``: the tables' local time zone, hours east of UTC (times
    carry no zone; default: they are UTC).
    """
    report = ParseReport()
    fixes, crossings = FixRows(), CrossingRows()
    for path in paths:
        _parse_centre_file(Path(path), report, fixes, crossings, utc_offset_h)
    report.check()
    return _in_time_order(fixes.frame()), _in_time_order(crossings.frame()), report


# ------------------------------------------------------------ device streams


def parse_device_header(cells: list[str]) -> list[str | None]:
    """Header cells → canonical column names; ValueError with the reason if not a device-stream header."""
    columns: list[str | None] = []
    for cell in cells:
        column = _DEVICE_KEYS.get(header_key(cell))
        if column is None:
            raise ValueError(f"unknown column '{cell.strip()}'")
        if column in columns:
            raise ValueError(f"column '{cell.strip()}' given twice")
        columns.append(column)
    missing = [c for c in ("time", "lat", "lon") if c not in columns]
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    return columns


def _flag(value: Any) -> bool:
    if value is None or isinstance(value, bool):
        return value is not False
    text = str(value).strip().casefold()
    if text in _TRUE or text == "":
        return True
    if text in _FALSE:
        return False
    raise RowError("valid", f"valid: expected true/false, 1/0 or yes/no, found '{value}'")


def _device_row(values: Mapping[str, Any], default_device: str, roles: Mapping[str, str]) -> dict[str, Any]:
    """One device-stream row (canonical keys → raw values) → fix fields."""
    time_ns = _time(values.get("time"))
    device = values.get("device")
    device = default_device if device is None or str(device).strip() == "" else str(device).strip()
    role_raw = values.get("role")
    role_text = "" if role_raw is None else " ".join(unicodedata.normalize("NFC", str(role_raw)).casefold().split())
    if role_text not in _ROLE_ALIASES:
        raise RowError("role", f"role: '{role_raw}' is not head or eot")
    role = _ROLE_ALIASES[role_text] or roles.get(device, "")
    lat, lon = _position(values.get("lat"), values.get("lon"))
    speed = _speed(values.get("speed_mps"), "speed (m/s)", 1.0)
    if math.isnan(speed):
        speed = _speed(values.get("speed_kmh"), "speed (km/h)", KMH_MPS)
    course = parse_decimal(values.get("course_deg"), "course")
    valid = _flag(values.get("valid")) and not math.isnan(lat)
    return {
        "time_ns": time_ns,
        "device": device,
        "role": role,
        "lat": lat,
        "lon": lon,
        "speed_mps": speed,
        "course_deg": course,
        "valid": valid,
    }


def _json_values(text: str) -> dict[str, Any]:
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as exc:
        raise RowError("json", f"not valid JSON: {exc.msg} at column {exc.colno}") from None
    if not isinstance(obj, dict):
        raise RowError("json", f"expected a JSON object {{…}}, found a {type(obj).__name__}")
    values: dict[str, Any] = {}
    for key, value in obj.items():
        column = _DEVICE_KEYS.get(header_key(str(key)))
        if column is None:
            continue
        if column in values:
            raise RowError("json", f"key '{key}' repeats column {column}")
        if isinstance(value, dict | list):
            raise RowError("json", f"key '{key}': expected a number or text, found a {type(value).__name__}")
        values[column] = value
    missing = [c for c in ("time", "lat", "lon") if c not in values]
    if missing:
        raise RowError("json", f"missing key(s) {', '.join(missing)}")
    return values


def _parse_device_file(path: Path, report: ParseReport, rows: FixRows, fmt: str, roles: Mapping[str, str]) -> None:
    fr, lines = open_lines(path, report)
    columns: list[str | None] | None = None
    delimiter = ","
    for number, raw in lines:
        text = _decode(raw, fr)
        if not text.strip() or text.lstrip().startswith("#"):
            fr.blank += 1
            continue
        try:
            if fmt == "jsonl":
                values = _json_values(text)
            elif columns is None:
                delimiter = _delimiter(text)
                try:
                    columns = parse_device_header(_cells(text, delimiter))
                except ValueError as exc:
                    raise RowError(
                        "header", f"not the device-stream header: {exc}; expected time, lat, lon, …"
                    ) from None
                fr.blank += 1  # the header: no record, nothing lost
                continue
            else:
                cells = _cells(text, delimiter)
                if len(cells) != len(columns):
                    hint = (
                        " (a decimal comma in a ','-separated file needs quotes)" if len(cells) > len(columns) else ""
                    )
                    raise RowError("fields", f"expected {len(columns)} fields, found {len(cells)}{hint}")
                values = {c: v for c, v in zip(columns, cells, strict=True) if c is not None}
            fix = _device_row(values, path.stem, roles)
        except RowError as exc:
            report.reject(fr, number, exc.category, exc.reason, raw)
            continue
        fr.records += 1
        rows.add(**fix, source=fmt, sentence="", file=fr.file, line=number)


def parse_device_stream(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Parse device streams (CSV or JSON lines, told apart by content) into a fix table in file order.

    ``roles`` fills in the role of rows that give none (device → head/eot).
    """
    report = ParseReport()
    rows = FixRows()
    role_map = check_roles(roles)
    for path in paths:
        p = Path(path)
        fmt = recognise_format(p)
        _parse_device_file(p, report, rows, "jsonl" if fmt == "jsonl" else "csv", role_map)
    report.check()
    return rows.frame(), report


# -------------------------------------------------------------- recognition


def _first_line(path: Path) -> str | None:
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_PEEK_BYTES)
    finally:
        stream.close()
        raw.close()
    for line in head.split(b"\n"):
        text = line.strip()
        if text and not text.startswith(b"#"):
            try:
                return text.decode("utf-8")
            except UnicodeDecodeError:
                return text.decode("cp1258", errors="replace")
    return None


def recognise_format(path: Path | str) -> GnssFormat:
    """``"nmea"``, ``"jsonl"``, ``"centre"``, ``"csv"`` or ``"unknown"``, from the file's first record line."""
    first = _first_line(Path(path))
    if first is None:
        return "unknown"
    if first[:1] in ("$", "!") or DEVICE_TAG_RE.match(first.encode("utf-8", errors="replace")):
        return "nmea"
    if first[:1] == "{":
        return "jsonl"
    cells = _cells(first, _delimiter(first))
    try:
        parse_centre_header(cells)
        return "centre"
    except ValueError:
        pass
    try:
        parse_device_header(cells)
        return "csv"
    except ValueError:
        return "unknown"


def _reject_all(path: Path, report: ParseReport) -> None:
    fr, lines = open_lines(path, report)
    reason = (
        "unrecognised GNSS format: expected NMEA sentences ($…), JSON lines ({…}), "
        "a device CSV (time, device, role, lat, lon, speed) or a monitoring-centre table (TIMESTAMP, Mã tàu, …)"
    )
    for number, raw in lines:
        if raw.strip():
            report.reject(fr, number, "format", reason, raw)
        else:
            fr.blank += 1


def parse_gnss(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None, utc_offset_h: float = 0.0
) -> tuple[pd.DataFrame, ParseReport, pd.DataFrame]:
    """Parse GNSS files of any known format: (fixes in time order, report, crossing states).

    Each file's format is recognised by content (:func:`recognise_format`).
    Fixes are sorted by time, stably (unknown times last); crossing states
    come from centre tables, empty if there are none.  ``roles`` (device →
    head/eot) applies to NMEA devices and to stream rows that give no role;
    ``utc_offset_h`` to the zone-less times of centre tables.
    """
    report = ParseReport()
    role_map = check_roles(roles)
    rows, crossings = FixRows(), CrossingRows()  # one table, in file order, before the sort
    nmea = StreamParser(report, role_map, rows)
    for path in map(Path, paths):
        fmt = recognise_format(path)
        if fmt == "nmea":
            nmea.parse_file(path)
        elif fmt == "centre":
            _parse_centre_file(path, report, rows, crossings, utc_offset_h)
        elif fmt in ("csv", "jsonl"):
            _parse_device_file(path, report, rows, fmt, role_map)
        else:
            _reject_all(path, report)
    report.check()
    return _in_time_order(rows.frame()), report, _in_time_order(crossings.frame())
