"""The vectorized path of the device-CSV reader: a batch of rows at a time, no Python loop per row.

:func:`fast_batch` reads the rows of a batch that are in the common shape
(ASCII, no quotes, the header's field count, ISO 8601 times, plain decimal
numbers in range, known roles and fix qualities) with pyarrow and numpy,
and hands back the others, which the per-row reader
(:func:`parsers.gnss.csv.parse_device_file`) reads or rejects with their
reason.  The two paths give the same rows: tests/test_gnss_realworld.py
checks it as a property over random rows of every shape.

Work per row is vectorized; Python runs once per *distinct* value of the
device, role, valid and fix-quality columns (a table of devices, not of
records).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from parsers.gnss.fields import ROLE_ALIASES, RowError

if TYPE_CHECKING:
    from parsers.gnss.headers import DeviceHeader

# The time shapes read here; any other (DD/MM/YYYY, a decimal comma, nanoseconds, a space
# before the zone) goes to the per-row reader, which knows them all.
_FAST_TIME = r"^\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}:\d{2}(\.\d{1,6})?(Z|z|[+-]\d{2}:\d{2})?$"
_FAST_NUMBER = r"^[+-]?\d{1,20}([.,]\d{1,18})?$"
_FIRST_YEAR, _LAST_YEAR = 1678, 2261


@dataclass
class FastRows:
    """The rows read here (``ok`` marks them, by position in the batch) as columns."""

    ok: np.ndarray
    time_ns: np.ndarray
    device: list[str]  # distinct devices, in order of first sight
    device_code: np.ndarray  # per row, into ``device``
    role: np.ndarray  # per row: "head", "eot" or ""
    lat: np.ndarray
    lon: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray
    valid: np.ndarray
    fix_quality: np.ndarray


_NUMPY_OF = {"int8": np.int8, "int16": np.int16, "int32": np.int32, "int64": np.int64, "double": np.float64}


def _np(arr: pa.Array) -> np.ndarray:
    """An Arrow array as numpy, read off its buffers: Arrow's own conversion (``to_numpy``) imports pandas,
    some 40 MB that a JSON-only command does not otherwise load."""
    kind = str(arr.type)
    if arr.null_count or (kind != "bool" and kind not in _NUMPY_OF):
        return arr.to_numpy(zero_copy_only=False)
    n, at = len(arr), arr.offset
    data = arr.buffers()[1]
    if kind == "bool":
        bits = np.frombuffer(data, np.uint8) if data is not None else np.zeros(0, np.uint8)
        return np.unpackbits(bits, count=at + n, bitorder="little")[at:].astype(bool)
    return np.frombuffer(data, _NUMPY_OF[kind])[at : at + n].copy()


def _mask(values: np.ndarray) -> pa.Array:
    """A numpy bool array as an Arrow one (``pa.array`` would import pandas)."""
    bits = np.packbits(np.asarray(values, bool), bitorder="little")
    return pa.Array.from_buffers(pa.bool_(), len(values), [None, pa.py_buffer(bits)])


def _text(value: str) -> pa.Scalar:
    """A string as an Arrow scalar (``pa.scalar`` and a Python value given to a kernel import pandas)."""
    return _string_array([value.encode("utf-8")])[0]


def _int(value: int) -> pa.Scalar:
    return pa.Array.from_buffers(pa.int64(), 1, [None, pa.py_buffer(np.array([value], np.int64))])[0]


def _string_array(raw_lines: list[bytes]) -> pa.Array:
    """The lines (ASCII: checked by the caller) as an Arrow string array, made from one buffer
    (``pa.array`` of a list would import pandas to look at it)."""
    ends = np.cumsum(np.fromiter(map(len, raw_lines), np.int64, len(raw_lines)))
    offsets = np.concatenate([np.zeros(1, np.int32), ends.astype(np.int32)])
    data = pa.py_buffer(b"".join(raw_lines))
    return pa.Array.from_buffers(pa.string(), len(raw_lines), [None, pa.py_buffer(offsets), data])


def _strip(col: pa.Array) -> pa.Array:
    return pc.utf8_trim_whitespace(col)


def _numbers(col: pa.Array | None, n: int, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """(values × factor with NaN for empty, mask of cells read here)."""
    if col is None:
        return np.full(n, np.nan), np.ones(n, bool)
    text = _strip(col)
    empty = _np(pc.utf8_length(text)) == 0
    good = _np(pc.match_substring_regex(text, _FAST_NUMBER))
    ok = empty | good
    cleaned = pc.if_else(_mask(good), pc.replace_substring(text, ",", "."), _text("0"))
    values = _np(pc.cast(cleaned, pa.float64())) * factor
    values[empty] = np.nan
    return values, ok


def _per_distinct(col: pa.Array | None, n: int, fn: Callable[[Any], Any], none: Any) -> tuple[list[Any], np.ndarray]:
    """Apply ``fn`` once per distinct value: (results per distinct value, code per row); a RowError → None."""
    if col is None:
        try:
            return [fn(None)], np.zeros(n, np.int64)
        except RowError:
            return [none], np.zeros(n, np.int64)
    encoded = pc.dictionary_encode(col)
    codes = _np(encoded.indices).astype(np.int64)
    out = []
    for value in encoded.dictionary.to_pylist():
        try:
            out.append(fn(value))
        except RowError:
            out.append(none)
    return out, codes


def _ints(text: pa.Array, start: int, stop: int | None) -> np.ndarray:
    """The digits at [start, stop) of each string (all digits there: the fast pattern matched) as int64."""
    part = pc.utf8_slice_codeunits(text, start, stop) if stop is not None else pc.utf8_slice_codeunits(text, start)
    return _np(pc.cast(part, pa.int64()))


def iso_times_ns(text: pa.Array, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(UTC ns since the epoch, mask of times read here) of the strings marked ``ok``, which match
    :data:`_FAST_TIME` with a year in range; a time without a zone is UTC.

    Read by field, vectorized (the pattern fixes where each field is).  The times read are those
    pandas' ISO 8601 parser reads (``to_datetime(format="ISO8601", utc=True)``, which this replaces:
    pandas is not loaded for it); the others (a date that does not exist, hour 24, second 60, an offset of
    24 h or 60 min, a lower-case ``z``) are left to the per-row reader, as pandas' NaT left them.
    """
    text = pc.if_else(_mask(ok), text, _text("1970-01-01T00:00:00Z"))
    year, month, day = _ints(text, 0, 4), _ints(text, 5, 7), _ints(text, 8, 10)
    hour, minute, second = _ints(text, 11, 13), _ints(text, 14, 16), _ints(text, 17, 19)
    zone = pc.extract_regex(text, r"(?P<z>Z|z|[+-]\d{2}:\d{2})?$").field("z")
    zone = pc.if_else(pc.is_null(zone), _text(""), zone)
    lower_z = _np(pc.equal(zone, _text("z")))
    has_offset = _np(pc.utf8_length(zone)) == 6
    offset_text = pc.if_else(_mask(has_offset), zone, _text("+00:00"))
    sign = np.where(_np(pc.equal(pc.utf8_slice_codeunits(offset_text, 0, 1), _text("-"))), -1, 1)
    offset_h, offset_m = _ints(offset_text, 1, 3), _ints(offset_text, 4, 6)
    # The fraction's digits (none to six), read as nanoseconds: padded right to nine digits.
    body = pc.utf8_slice_codeunits(pc.replace_substring_regex(text, r"(Z|z|[+-]\d{2}:\d{2})$", ""), 20)
    frac_ns = _np(pc.cast(pc.utf8_rpad(body, 9, "0"), pa.int64()))
    good = ok & ~lower_z & (month >= 1) & (month <= 12) & (day >= 1) & (day <= 31)
    good &= (hour <= 23) & (minute <= 59) & (second <= 59) & (offset_h <= 23) & (offset_m <= 59)
    months = np.where(good, (year - 1970) * 12 + month - 1, 0).astype("datetime64[M]")
    days = months.astype("datetime64[D]") + np.where(good, day - 1, 0).astype("timedelta64[D]")
    good &= days.astype("datetime64[M]") == months  # 30 February and the like: not a date
    seconds = days.astype(np.int64) * 86_400 + (hour * 60 + minute) * 60 + second
    seconds -= sign * (offset_h * 60 + offset_m) * 60
    time_ns = np.where(good, seconds * 1_000_000_000 + frac_ns, 0).astype(np.int64, copy=False)
    return time_ns, good


def fast_batch(
    raw_lines: list[bytes],
    header: DeviceHeader,
    delimiter: str,
    default_device: str,
    roles: Mapping[str, str],
    fix_quality: Callable[[Any, str], tuple[bool, str]],
    flag: Callable[[Any], bool],
) -> FastRows | None:
    """Read what can be read of a batch of data lines (no line ends); None if the batch is not for this path."""
    data = b"\n".join(raw_lines)
    if not data.isascii() or b'"' in data or b"\x00" in data or b"\r" in data or len(data) >= 2**31:
        return None
    try:
        default_device.encode("utf-8")  # a file name of undecodable bytes (surrogate escapes): per row
    except UnicodeEncodeError:
        return None
    n = len(raw_lines)
    lines = _string_array(raw_lines)
    cells = pc.split_pattern(lines, delimiter)
    ok = _np(pc.list_value_length(cells)) == header.width
    # Rows of another width are read per row (to say why); a placeholder keeps positions.
    blank = np.array([0, header.width], np.int32)
    offsets = pa.Array.from_buffers(pa.int32(), 2, [None, pa.py_buffer(blank)])
    filler = pa.ListArray.from_arrays(offsets, _string_array([b""] * header.width))[0]
    cells = pc.if_else(_mask(ok), cells, filler)

    def column(name: str) -> pa.Array | None:
        at = header.at.get(name)
        return None if at is None else pc.utf8_ltrim(pc.list_element(cells, _int(at)), characters=" ")

    if "time" in header.at:
        time_text = _strip(column("time"))
    else:
        time_text = pc.binary_join_element_wise(_strip(column("date")), _strip(column("tod")), _text(" "))
    ok &= _np(pc.match_substring_regex(time_text, _FAST_TIME))
    years = pc.cast(pc.if_else(_mask(ok), pc.utf8_slice_codeunits(time_text, 0, 4), _text("1970")), pa.int32())
    year = _np(years)
    ok &= (year >= _FIRST_YEAR) & (year <= _LAST_YEAR)
    time_ns, ok_time = iso_times_ns(time_text, ok)
    ok &= ok_time

    f = header.factor
    lat, ok_lat = _numbers(column("lat"), n, f.get("lat", 1.0))
    lon, ok_lon = _numbers(column("lon"), n, f.get("lon", 1.0))
    speed, ok_speed = _numbers(column("speed"), n, f.get("speed", 1.0))
    course, ok_course = _numbers(column("course"), n, f.get("course", 1.0))
    ok &= ok_lat & ok_lon & ok_speed & ok_course
    with np.errstate(invalid="ignore"):
        ok &= ~(np.abs(lat) > 90) & ~(np.abs(lon) > 180) & (np.isnan(lat) == np.isnan(lon)) & ~(speed < 0)

    device_col = column("device")
    if device_col is None:
        devices, device_code = [default_device], np.zeros(n, np.int64)
    else:
        stripped = _strip(device_col)
        named = pc.if_else(_mask(_np(pc.utf8_length(stripped)) == 0), _text(default_device), stripped)
        encoded = pc.dictionary_encode(named)
        devices = encoded.dictionary.to_pylist()
        device_code = _np(encoded.indices).astype(np.int64)

    def role_of(value: Any) -> str | None:
        text = "" if value is None else " ".join(str(value).lower().split())
        if text not in ROLE_ALIASES:
            raise RowError("role", "")
        return ROLE_ALIASES[text]

    role_values, role_code = _per_distinct(column("role"), n, role_of, None)
    role_known = np.array([r is not None for r in role_values], bool)[role_code]
    ok &= role_known
    given_role = np.array([r or "" for r in role_values], dtype=object)[role_code]
    device_role = np.array([roles.get(d, "") for d in devices], dtype=object)[device_code]
    role = np.where(given_role != "", given_role, device_role)

    quality_values, quality_code = _per_distinct(
        column("quality"), n, lambda v: fix_quality(v, header.quality_codes), None
    )
    ok &= np.array([q is not None for q in quality_values], bool)[quality_code]
    q_valid = np.array([bool(q and q[0]) for q in quality_values], bool)[quality_code]
    q_name = np.array([q[1] if q else "" for q in quality_values], dtype=object)[quality_code]
    flag_values, flag_code = _per_distinct(column("valid"), n, flag, None)
    ok &= np.array([v is not None for v in flag_values], bool)[flag_code]
    flagged = np.array([bool(v) for v in flag_values], bool)[flag_code]
    valid = q_valid & flagged & ~np.isnan(lat)
    quality = np.where(valid, q_name, "no_fix")
    return FastRows(ok, time_ns, devices, device_code, role, lat, lon, speed, course, valid, quality)
