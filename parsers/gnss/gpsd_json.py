"""JSON lines as the world writes them: hostile-safe loading, and gpsd's TPV reports.

:func:`load_object` reads one line of JSON into a dict, or raises
:class:`JsonRowError` with a reason a person can act on, whatever the line
holds: nesting a thousand deep (RecursionError inside the json module), a
lone surrogate escape (``"\\ud800"``, which would fail later, when written
out as UTF-8), integers beyond 64 bits or of thousands of digits (Python
refuses over 4300 digits with ValueError; shorter ones would overflow where
a float is needed), non-finite numbers.  Only the fields we read are
checked: a huge integer in a field we ignore is not a reason to lose a fix.

gpsd's JSON (``gpspipe -w``, gpsd's own logs): one object a line with a
``class``.  A ``TPV`` is a fix (:func:`tpv_fix`): ``time`` (ISO 8601, UTC),
``lat``/``lon`` (degrees), ``speed`` (m/s), ``track`` (degrees true),
``mode`` (0/1 no fix, 2 2D, 3 3D) and ``status`` (gpsd's fix status:
5 and 6 are dead reckoning, 8 simulated); ``device`` names the receiver
(its path, e.g. ``/dev/ttyUSB0``; we keep its last path part).  Objects of
any other class (``SKY``, ``VERSION``, ``DEVICES``, ``WATCH``, ``ATT`` …)
carry no fix: they are counted, not rejected.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Final

# Digits an integer may have in a field we read: 2^63 has 19.
_MAX_INT_DIGITS: Final = 19
MAX_DEPTH: Final = 64  # deeper than any record we read; json recursion stays far from its limit

# gpsd's TPV "status" values (gpsd_json(5)): 5 DR, 6 GNSS + DR, 8 simulated.
GPSD_DEAD_RECKONING: Final = (5, 6)
GPSD_SIMULATED: Final = 8


class JsonRowError(Exception):
    """A JSON line that cannot be used: ``category`` for the counts, ``reason`` for people."""

    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


@dataclass(frozen=True)
class BigInt:
    """An integer literal too long to be any value we read; kept as text so the field can be named."""

    digits: int


def _int(text: str) -> int | BigInt:
    digits = len(text.lstrip("-"))
    return BigInt(digits) if digits > _MAX_INT_DIGITS else int(text)


def _constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


def _depth(text: str) -> int:
    """Deepest bracket nesting outside strings (a cheap guard before the recursive parser)."""
    depth = deepest = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif ch in "]}":
            depth -= 1
    return deepest


def load_object(text: str) -> dict[str, Any]:
    """One JSON line → a dict; :class:`JsonRowError` with the reason otherwise."""
    if text.count("[") + text.count("{") > MAX_DEPTH and _depth(text) > MAX_DEPTH:
        raise JsonRowError("json", f"JSON nested more than {MAX_DEPTH} deep")
    try:
        obj = json.loads(text, parse_int=_int, parse_constant=_constant)
    except json.JSONDecodeError as exc:
        raise JsonRowError("json", f"not valid JSON: {exc.msg} at column {exc.colno}") from None
    except (ValueError, RecursionError) as exc:
        raise JsonRowError("json", f"not valid JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise JsonRowError("json", f"expected a JSON object {{…}}, found a {type(obj).__name__}")
    return obj


def number(obj: dict[str, Any], key: str) -> float:
    """A numeric field → float (NaN when absent or null); JsonRowError naming the field otherwise."""
    value = obj.get(key)
    if value is None:
        return math.nan
    if isinstance(value, BigInt):
        raise JsonRowError("number", f"field '{key}': an integer of {value.digits} digits is out of range")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise JsonRowError("number", f"field '{key}': expected a number, found {type(value).__name__}")
    result = float(value)
    if not math.isfinite(result):
        raise JsonRowError("number", f"field '{key}': expected a finite number, found {value}")
    return result


def text_field(obj: dict[str, Any], key: str) -> str | None:
    """A text field → str (None when absent or null); JsonRowError on a non-string or a lone surrogate."""
    value = obj.get(key)
    if value is None:
        return None
    if not isinstance(value, str):
        raise JsonRowError("json", f"field '{key}': expected text, found {type(value).__name__}")
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        raise JsonRowError("json", f"field '{key}': a lone surrogate escape is not text") from None
    return value


def plain(obj: dict[str, Any], key: str) -> Any:
    """A scalar field for the device-stream reader: BigInt and surrogates refused, containers refused."""
    value = obj.get(key)
    if isinstance(value, BigInt):
        raise JsonRowError("number", f"field '{key}': an integer of {value.digits} digits is out of range")
    if isinstance(value, dict | list):
        raise JsonRowError("json", f"key '{key}': expected a number or text, found a {type(value).__name__}")
    if isinstance(value, str):
        return text_field(obj, key)
    if isinstance(value, float) and not math.isfinite(value):
        raise JsonRowError("number", f"field '{key}': expected a finite number, found {value}")
    return value


@dataclass
class TpvFix:
    """The fields of one gpsd TPV report (NaN/None where absent)."""

    time: str | None
    device: str | None
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    valid: bool
    quality: str  # "gnss", "dead_reckoning" or "no_fix" (also for a simulated fix)


def gpsd_class(obj: dict[str, Any]) -> str | None:
    """The ``class`` of a gpsd object, or None if it is not one."""
    value = obj.get("class")
    return value if isinstance(value, str) and value.isascii() and value.isupper() else None


def tpv_fix(obj: dict[str, Any]) -> TpvFix:
    """A gpsd TPV object → its fix fields; JsonRowError naming the bad field."""
    lat, lon = number(obj, "lat"), number(obj, "lon")
    if not math.isnan(lat) and abs(lat) > 90:
        raise JsonRowError("range", f"field 'lat': {lat:g}° is out of range ±90°")
    if not math.isnan(lon) and abs(lon) > 180:
        raise JsonRowError("range", f"field 'lon': {lon:g}° is out of range ±180°")
    speed = number(obj, "speed")
    if speed < 0:
        raise JsonRowError("range", f"field 'speed': a speed cannot be negative ({speed:g})")
    mode = number(obj, "mode")
    status = number(obj, "status")
    device = text_field(obj, "device")
    if device is not None:
        device = device.rstrip("/").rsplit("/", 1)[-1] or None
    has_fix = (not math.isnan(mode) and mode >= 2) and not math.isnan(lat) and not math.isnan(lon)
    if not has_fix:
        quality = "no_fix"
    elif status in GPSD_DEAD_RECKONING:
        quality = "dead_reckoning"
    elif status == GPSD_SIMULATED:
        quality = "no_fix"  # a simulator's position is not where any train is
    else:
        quality = "gnss"
    return TpvFix(
        time=text_field(obj, "time"),
        device=device,
        lat=lat,
        lon=lon,
        speed_mps=speed,
        course_deg=number(obj, "track"),
        valid=quality != "no_fix",
        quality=quality,
    )
