"""Fields of GNSS tables as exports write them: numbers, positions, speeds, times, header names, cells.

Shared by the monitoring-centre table (``parsers.gnss.centre``) and device CSV /
JSON-lines exports (``parsers.gnss.csv``).  Every failure is a
:class:`RowError` naming the field, so that one bad row is rejected alone.
"""

from __future__ import annotations

import csv
import json
import math
import re
import unicodedata
from typing import Any

from parsers.gnss.times import parse_epoch_s_ns, parse_time_ns
from parsers.report import FileReport

ROLE_ALIASES = {
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
TRUE_WORDS = {"true", "1", "yes", "y", "a"}
FALSE_WORDS = {"false", "0", "no", "n", "v"}

_NUMBER_RE = re.compile(r"[+-]?\d+(?:[.,]\d+)?")
_MINUS = str.maketrans({"−": "-", "–": "-"})
_UNITS = {"km/h": "kmh", "kmh": "kmh", "kph": "kmh", "m/s": "mps", "mps": "mps", "deg": "deg", "°": "deg"}
_UNIT_RE = re.compile(r"^(.*?)\s*\(\s*([^)]*?)\s*\)$")


class RowError(Exception):
    """A row that cannot be used: ``category`` for the counts, ``reason`` for people."""

    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


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
        raise RowError("number", f"{what}: expected a number (e.g. 20,7 or 20.7), found '{text[:40]}'")
    number = float(text.replace(",", "."))
    if not math.isfinite(number) or len(text) > 40:
        # 2^64, a 5000-digit number: no field of ours holds such a value.
        raise RowError("number", f"{what}: a number of {len(text)} characters is out of range")
    return number


def position(lat_raw: Any, lon_raw: Any) -> tuple[float, float]:
    lat = parse_decimal(lat_raw, "latitude")
    lon = parse_decimal(lon_raw, "longitude")
    if not math.isnan(lat) and abs(lat) > 90:
        raise RowError("range", f"latitude {lat:g}° is out of range ±90°")
    if not math.isnan(lon) and abs(lon) > 180:
        raise RowError("range", f"longitude {lon:g}° is out of range ±180°")
    if math.isnan(lat) != math.isnan(lon):
        raise RowError("position", "latitude and longitude must be given together")
    return lat, lon


def speed(value: Any, what: str, factor: float) -> float:
    speed = parse_decimal(value, what)
    if speed < 0:
        raise RowError("range", f"{what}: a speed cannot be negative ({speed:g})")
    return speed * factor


def time_field(value: Any, utc_offset_h: float = 0.0) -> int:
    if value is None or (isinstance(value, str) and not value.strip()):
        raise RowError("time", "time: empty; every row needs a date and time")
    if isinstance(value, bool):
        raise RowError("time", f"time: {value!r} is not a date and time")
    try:
        # A number is seconds since 1970 (UTC whatever the offset: a count of seconds has no zone).
        epoch_ns = parse_epoch_s_ns(format(value, ".9f") if isinstance(value, float) else str(value))
        return epoch_ns if epoch_ns is not None else parse_time_ns(str(value), utc_offset_h)
    except ValueError as exc:
        raise RowError("time", f"time: {exc}") from None


def decode_line(raw: bytes, fr: FileReport) -> str:
    """UTF-8, else CP1258 (Vietnamese Windows, whose tone marks are combining): NFC either way."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        fr.encoding = "cp1258"
        text = raw.decode("cp1258", errors="replace")
    return unicodedata.normalize("NFC", text)


def delimiter_of(line: str) -> str:
    return "\t" if "\t" in line else ";" if ";" in line else ","


def cells_of(line: str, delimiter: str) -> list[str]:
    """One line's cells; RowError for a line the csv module refuses (a stray CR, a NUL)."""
    if "\x00" in line:
        raise RowError("binary", f"a NUL byte at column {line.index(chr(0)) + 1}")
    try:
        return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])
    except csv.Error as exc:
        raise RowError("fields", f"not a CSV row: {exc}") from None
