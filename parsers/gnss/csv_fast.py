"""The vectorized path of the device-CSV reader: a batch of rows at a time, no Python loop per row.

:func:`fast_batch` reads the rows of a batch that are in the common shape
(ASCII, no quotes, the header's field count, ISO 8601 times, plain decimal
numbers in range, known roles and fix qualities) with pyarrow and pandas,
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


def _strip(col: pa.Array) -> pa.Array:
    return pc.utf8_trim_whitespace(col)


def _numbers(col: pa.Array | None, n: int, factor: float) -> tuple[np.ndarray, np.ndarray]:
    """(values × factor with NaN for empty, mask of cells read here)."""
    if col is None:
        return np.full(n, np.nan), np.ones(n, bool)
    text = _strip(col)
    empty = pc.equal(pc.utf8_length(text), 0).to_numpy(zero_copy_only=False)
    good = pc.match_substring_regex(text, _FAST_NUMBER).to_numpy(zero_copy_only=False)
    ok = empty | good
    cleaned = pc.if_else(pa.array(good), pc.replace_substring(text, ",", "."), pa.scalar("0"))
    values = pc.cast(cleaned, pa.float64()).to_numpy(zero_copy_only=False) * factor
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
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)
    out = []
    for value in encoded.dictionary.to_pylist():
        try:
            out.append(fn(value))
        except RowError:
            out.append(none)
    return out, codes


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
    if not data.isascii() or b'"' in data or b"\x00" in data or b"\r" in data:
        return None
    try:
        default_device.encode("utf-8")  # a file name of undecodable bytes (surrogate escapes): per row
    except UnicodeEncodeError:
        return None
    n = len(raw_lines)
    lines = pa.array(raw_lines, pa.binary()).cast(pa.string())  # ASCII, checked above
    cells = pc.split_pattern(lines, delimiter)
    ok = pc.equal(pc.list_value_length(cells), header.width).to_numpy(zero_copy_only=False)
    # Rows of another width are read per row (to say why); a placeholder keeps positions.
    filler = pa.scalar([""] * header.width, pa.list_(pa.string()))
    cells = pc.if_else(pa.array(ok), cells, filler)

    def column(name: str) -> pa.Array | None:
        at = header.at.get(name)
        return None if at is None else pc.utf8_ltrim(pc.list_element(cells, at), characters=" ")

    if "time" in header.at:
        time_text = _strip(column("time"))
    else:
        time_text = pc.binary_join_element_wise(_strip(column("date")), _strip(column("tod")), " ")
    ok &= pc.match_substring_regex(time_text, _FAST_TIME).to_numpy(zero_copy_only=False)
    years = pc.cast(pc.if_else(pa.array(ok), pc.utf8_slice_codeunits(time_text, 0, 4), pa.scalar("1970")), pa.int32())
    year = years.to_numpy(zero_copy_only=False)
    ok &= (year >= _FIRST_YEAR) & (year <= _LAST_YEAR)
    import pandas as pd

    times = pd.to_datetime(
        pc.if_else(pa.array(ok), time_text, pa.scalar("1970-01-01T00:00:00Z")).to_pandas(),
        format="ISO8601",
        utc=True,
        errors="coerce",
    )
    ok &= times.notna().to_numpy()
    # pandas may hold microseconds; the fast pattern allows no finer fraction, so ns are exact.
    time_ns = np.asarray(times.dt.tz_convert(None).dt.as_unit("ns").to_numpy(), dtype="datetime64[ns]").view(np.int64)

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
        named = pc.if_else(pc.equal(pc.utf8_length(stripped), 0), pa.scalar(default_device), stripped)
        encoded = pc.dictionary_encode(named)
        devices = encoded.dictionary.to_pylist()
        device_code = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64)

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
