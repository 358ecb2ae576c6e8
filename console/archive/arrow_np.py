"""numpy arrays and Arrow arrays, one into the other, without waking pyarrow's pandas shim.

``pa.array``, ``pa.scalar`` and ``Array.to_numpy`` ask pyarrow's lazy pandas
shim whether their argument is a pandas object, and the first question
imports pandas (+46 MB RSS, ~0.4 s).  An ingest builds Arrow columns from
the parser's numpy arrays for every chunk: with these helpers its read
never imports pandas (``analyze`` does not either), so the read's peak
memory does not carry it; the derivation's end, which needs pandas,
imports it after the read has let its memory go.  Arrays these helpers
cannot build from buffers (object arrays, another requested type) go
through ``pa.array`` as before: the same values either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pyarrow as pa

# numpy dtypes whose bytes are Arrow's (the values buffer as it is), by the Arrow type pa.array gives them.
_PRIMITIVE: dict[np.dtype[Any], pa.DataType] = {
    np.dtype(np.int8): pa.int8(),
    np.dtype(np.int16): pa.int16(),
    np.dtype(np.int32): pa.int32(),
    np.dtype(np.int64): pa.int64(),
    np.dtype(np.uint8): pa.uint8(),
    np.dtype(np.uint16): pa.uint16(),
    np.dtype(np.uint32): pa.uint32(),
    np.dtype(np.uint64): pa.uint64(),
    np.dtype(np.float32): pa.float32(),
    np.dtype(np.float64): pa.float64(),
    np.dtype("datetime64[ns]"): pa.timestamp("ns"),
}
_NAT = np.iinfo(np.int64).min


def _validity(valid: np.ndarray) -> tuple[pa.Buffer | None, int]:
    nulls = int(len(valid) - np.count_nonzero(valid))
    return (None, 0) if nulls == 0 else (pa.py_buffer(np.packbits(valid, bitorder="little")), nulls)


def _as_type(a: np.ndarray, type: pa.DataType) -> tuple[np.ndarray, pa.DataType | None]:
    """Integers as another integer type (every value fits: else pa.array's own check says why), days as date32."""
    if type == pa.date32() and a.dtype == np.int32:
        return a, type
    target = next((d for d, t in _PRIMITIVE.items() if t == type), None)
    if target is None or a.dtype.kind not in "iu" or target.kind not in "iu":
        return a, None
    if len(a) and (a.min() < np.iinfo(target).min or a.max() > np.iinfo(target).max):
        return a, None
    return a.astype(target), type


def array(
    values: Any, type: pa.DataType | None = None, *, mask: np.ndarray | None = None, nan_is_null: bool = False
) -> pa.Array:
    """``pa.array(values, type, mask=mask, from_pandas=nan_is_null)`` for a 1-d numpy array (or a sequence)."""
    a = np.asarray(values)
    natural = _PRIMITIVE.get(a.dtype) if a.ndim == 1 else None
    if a.dtype == np.bool_ and a.ndim == 1:
        natural = pa.bool_()
    if natural is not None and type is not None and type != natural:
        a, natural = _as_type(a, type)
    if natural is None or (type is not None and type != natural):
        return pa.array(a, type, mask=mask, from_pandas=nan_is_null or None)
    if natural == pa.timestamp("ns") and (a.view(np.int64) == _NAT).any():
        return pa.array(a, type, mask=mask, from_pandas=nan_is_null or None)  # NaT: pyarrow's rule for it
    valid = None if mask is None else ~np.asarray(mask, bool)
    if nan_is_null and a.dtype.kind == "f":
        not_nan = ~np.isnan(a)
        valid = not_nan if valid is None else valid & not_nan
    validity, nulls = _validity(valid) if valid is not None else (None, 0)
    if natural == pa.bool_():
        data = pa.py_buffer(np.packbits(a, bitorder="little"))
    else:
        data = pa.py_buffer(np.ascontiguousarray(a))
    return pa.Array.from_buffers(natural, len(a), [validity, data], null_count=nulls)


def strings(values: Sequence[str | None], type: pa.DataType | None = None) -> pa.Array:
    """``pa.array(values, type)`` for Python strings (None: null), as ``string`` or ``large_string``."""
    type = pa.string() if type is None else type
    if type not in (pa.string(), pa.large_string()):
        return pa.array(list(values), type)
    return _var_width([None if v is None else v.encode("utf-8") for v in values], type)


def binaries(values: Sequence[bytes | None], type: pa.DataType | None = None) -> pa.Array:
    """``pa.array(values, type)`` for Python bytes (None: null), as ``binary`` or ``large_binary``."""
    type = pa.binary() if type is None else type
    if type not in (pa.binary(), pa.large_binary()):
        return pa.array(list(values), type)
    return _var_width(values, type)


def _var_width(encoded: Sequence[bytes | None], type: pa.DataType) -> pa.Array:
    """A variable-width array of ``type`` (32- or 64-bit offsets by its name) from its values' bytes."""
    large = type in (pa.large_string(), pa.large_binary())
    offsets = np.zeros(len(encoded) + 1, np.int64 if large else np.int32)
    np.cumsum([0 if b is None else len(b) for b in encoded], out=offsets[1:])
    validity, nulls = _validity(np.array([b is not None for b in encoded], bool))
    buffers = [validity, pa.py_buffer(offsets), pa.py_buffer(b"".join(b for b in encoded if b is not None))]
    return pa.Array.from_buffers(type, len(encoded), buffers, null_count=nulls)


def table_from_rows(rows: list[dict[str, Any]]) -> pa.Table:
    """``pa.Table.from_pylist(rows)`` for rows whose every column holds only ``int`` (in int64) or only
    ``str``, built from buffers as ``from_pylist`` types them (int64, string, no nulls); anything else (None,
    floats, booleans, rows with other keys or key orders) goes to ``from_pylist``."""
    names = list(rows[0]) if rows else []
    if not rows or any(list(r) != names for r in rows):
        return pa.Table.from_pylist(rows)
    arrays: list[pa.Array] = []
    for name in names:
        values = [r[name] for r in rows]
        if all(type(v) is str for v in values):
            arrays.append(strings(values, pa.string()))
        elif all(type(v) is int and -(1 << 63) <= v < (1 << 63) for v in values):
            arrays.append(array(np.array(values, np.int64)))
        else:
            return pa.Table.from_pylist(rows)
    return pa.Table.from_arrays(arrays, names=names)


def to_numpy(arr: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """``arr.to_numpy()`` of a primitive array without nulls (a view of its buffer); others as pyarrow makes it."""
    if isinstance(arr, pa.ChunkedArray):
        if arr.num_chunks == 1:
            return to_numpy(arr.chunk(0))
        if arr.num_chunks == 0:
            return arr.to_numpy()
        return np.concatenate([to_numpy(c) for c in arr.chunks])
    dtype = next((d for d, t in _PRIMITIVE.items() if t == arr.type), None)
    if dtype is None or arr.null_count:
        return arr.to_numpy(zero_copy_only=False)
    return np.frombuffer(arr.buffers()[1], dtype, count=len(arr), offset=arr.offset * dtype.itemsize)


def list_values(column: pa.Array | pa.ChunkedArray) -> np.ndarray:
    """A list column's values end to end (``flatten()``'s, as numpy), read from the lists' own buffers where
    no list is null: ``flatten`` and ``combine_chunks`` import ``pyarrow.compute`` (a tenth of a second)."""
    chunks = column.chunks if isinstance(column, pa.ChunkedArray) else [column]
    value_type = column.type.value_type
    dtype = next((d for d, t in _PRIMITIVE.items() if t == value_type), None)
    parts = [np.zeros(0, dtype if dtype is not None else object)]
    for chunk in chunks:
        if chunk.null_count:
            flat = chunk.flatten()
        else:
            offsets = to_numpy(chunk.offsets)
            # ``values`` ignores a slice of the lists: the offsets say which values are these lists'.
            flat = chunk.values.slice(int(offsets[0]), int(offsets[-1] - offsets[0]))
        if len(flat):
            parts.append(to_numpy(flat))
    return np.concatenate(parts)
