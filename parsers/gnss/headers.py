"""The header lines of GNSS tables: which column holds what, read by name.

A monitoring-centre table (:func:`parse_centre_header`, read by :mod:`parsers.gnss.centre`) and a device-stream
CSV export (:func:`parse_device_header`, read by :mod:`parsers.gnss.csv`; its column names and units are
described there).  :mod:`parsers.kinds` tells the two apart by trying them, so they live here, below both
parsers.
"""

from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass, field

from parsers.gnss.fields import RowError, cells_of, header_key

# ------------------------------------------------------------- centre table

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


# ------------------------------------------------------ device-stream CSV

KNOT_MPS = 1852 / 3600

DEVICE_NAMES: dict[str, tuple[str, ...]] = {
    "time": ("time", "timestamp", "utc", "datetime", "date time", "time utc", "utc timestamp", "gps time", "ts"),
    "date": ("date", "utc date", "gps date", "date utc"),
    "tod": ("time of day", "utc time", "time utc of day", "tod"),
    "device": ("device", "device id", "unit", "unit id", "imei", "device name"),
    "role": ("role",),
    "lat": ("lat", "latitude"),
    "lon": ("lon", "lng", "long", "longitude"),
    "speed": ("speed", "ground speed", "gspeed", "sog", "speed over ground", "velocity", "speed mps"),
    "course": ("course", "heading", "track", "cog", "course over ground", "headmot", "bearing", "course deg"),
    "valid": ("valid", "fix valid", "gnssfixok", "fix ok"),
    "quality": (
        "fix",
        "fix type",
        "fixtype",
        "gps fix",
        "fix quality",
        "quality",
        "gga quality",
        "status",
        "fix status",
        "solution",
        "solution status",
        "pos mode",
        "position mode",
        "mode",
        "fix mode",
    ),
}
DEVICE_COLUMN_BY_NAME = {alias: name for name, aliases in DEVICE_NAMES.items() for alias in aliases}


def quality_codes_of(name: str) -> str:
    """Which codes a fix-quality column's numbers are, by its (normalised) name: u-blox ``fixType`` when it says
    *type*, NMEA GGA when it says *quality* (or is ``fix``), gpsd's TPV / NMEA GSA mode when it says *mode*
    (gpsd's gpscsv writes ``mode``); "" when it says none of these (numbers refused, not guessed)."""
    if "type" in name:
        return "ublox"
    if "quality" in name or name == "fix":
        return "gga"
    return "mode" if "mode" in name else ""


# Unit spelled in the header → (kind, factor to our unit: deg, m/s, deg).
UNIT_FACTORS: dict[str, float] = {
    "": 1.0,
    "deg": 1.0,
    "degs": 1.0,
    "degree": 1.0,
    "degrees": 1.0,
    "°": 1.0,
    "dd": 1.0,
    "e7": 1e-7,
    "1e7": 1e-7,
    "deg*1e7": 1e-7,
    "deg 1e7": 1e-7,
    "1e-7deg": 1e-7,
    "1e 7deg": 1e-7,
    "1e-7": 1e-7,
    "e6": 1e-6,
    "1e6": 1e-6,
    "deg*1e6": 1e-6,
    "microdeg": 1e-6,
    "udeg": 1e-6,
    "1e-6deg": 1e-6,
    "e5": 1e-5,
    "1e5": 1e-5,
    "deg*1e5": 1e-5,
    "1e-5deg": 1e-5,
    "m/s": 1.0,
    "mps": 1.0,
    "m s": 1.0,
    "ms": 1.0,
    "km/h": 1 / 3.6,
    "kmh": 1 / 3.6,
    "kph": 1 / 3.6,
    "km h": 1 / 3.6,
    "mm/s": 1e-3,
    "mm s": 1e-3,
    "mms": 1e-3,
    "cm/s": 1e-2,
    "cm s": 1e-2,
    "cms": 1e-2,
    "kn": KNOT_MPS,
    "kt": KNOT_MPS,
    "kts": KNOT_MPS,
    "knot": KNOT_MPS,
    "knots": KNOT_MPS,
    "mph": 0.44704,
}
_ANGLE_UNITS = frozenset(
    {"", "deg", "degs", "degree", "degrees", "°", "dd"}
    | {"e7", "1e7", "deg*1e7", "deg 1e7", "1e-7deg", "1e 7deg", "1e-7"}
    | {"e6", "1e6", "deg*1e6", "microdeg", "udeg", "1e-6deg"}
    | {"e5", "1e5", "deg*1e5", "1e-5deg"}
)
_SPEED_UNITS = frozenset(UNIT_FACTORS) - _ANGLE_UNITS | {""}
_BRACKET_UNIT_RE = re.compile(r"^(.*?)\s*[\(\[]\s*([^)\]]*?)\s*[\)\]]$")
# Units written as the name's last words: lat_e7, speed_mm_s, speed_kmh, speed_knots.
_SUFFIX_UNITS = ("mm s", "cm s", "m s", "km h", "kmh", "kph", "mps", "knots", "kn", "mph", "e7", "e6", "e5", "deg")


@dataclass
class DeviceHeader:
    """Where each field is read from, and with what factor."""

    width: int
    at: dict[str, int] = field(default_factory=dict)
    factor: dict[str, float] = field(default_factory=dict)
    quality_codes: str = ""  # "ublox", "gga", "mode" or "" (numbers refused): quality_codes_of
    extra: list[str] = field(default_factory=list)


def normal_name(cell: str) -> str:
    text = unicodedata.normalize("NFC", cell).casefold().replace("_", " ").replace("-", " ").replace(".", " ")
    return " ".join(text.split())


def split_unit(cell: str) -> tuple[str, str]:
    """A header cell → (name, unit).

    ``Latitude [deg]`` → (``latitude``, ``deg``); ``lat_e7`` → (``lat``, ``e7``);
    ``speed_mm_s`` → (``speed``, ``mm s``).
    """
    raw = unicodedata.normalize("NFC", cell).strip()
    m = _BRACKET_UNIT_RE.match(raw)
    if m:
        return normal_name(m.group(1)), m.group(2).casefold().replace(" ", "")
    name = normal_name(raw)
    if name in DEVICE_COLUMN_BY_NAME:
        return name, ""
    for unit in _SUFFIX_UNITS:
        if name.endswith(" " + unit) and name[: -len(unit) - 1] in DEVICE_COLUMN_BY_NAME:
            return name[: -len(unit) - 1], unit
    return name, ""


def parse_device_header(cells: list[str]) -> DeviceHeader:
    """Header cells → a :class:`DeviceHeader`; ValueError with the reason if not a device-stream header."""
    header = DeviceHeader(len(cells))
    for i, cell in enumerate(cells):
        name, unit = split_unit(cell)
        column = DEVICE_COLUMN_BY_NAME.get(name)
        if column is None:
            header.extra.append(cell.strip())
            continue
        if column in header.at:
            if column == "time" and "tod" not in header.at:
                column = "tod"  # "date, time": the second is the time of day
            else:
                raise ValueError(f"column '{cell.strip()}' given twice")
        if column in ("lat", "lon", "course", "speed"):
            factor = UNIT_FACTORS.get(unit)
            allowed = _SPEED_UNITS if column == "speed" else _ANGLE_UNITS
            if factor is None or unit not in allowed:
                raise ValueError(f"column '{cell.strip()}': unit '{unit}' is not one we know for {column}")
            header.factor[column] = factor
        if column == "quality":
            header.quality_codes = quality_codes_of(name)
        header.at[column] = i
    if "date" in header.at and "time" in header.at and "tod" not in header.at:
        header.at["tod"] = header.at.pop("time")
    has_time = "time" in header.at or ("date" in header.at and "tod" in header.at)
    missing = [c for c, ok in (("time", has_time), ("lat", "lat" in header.at), ("lon", "lon" in header.at)) if not ok]
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    return header


def commented_header_cells(text: str, delimiter: str) -> list[str] | None:
    """A ``#`` comment line's cells when the rest is a device CSV's header (gpsd's gpscsv --header 2 writes
    ``# time,lat,lon,altHAE``); None for any other line."""
    body = text.strip()
    if not body.startswith("#"):
        return None
    try:
        cells = cells_of(body[1:].strip(), delimiter)
        parse_device_header(cells)
    except (ValueError, RowError):
        return None
    return cells
