"""``pa.Table.from_pylist`` for rows of plain integers and texts, without pyarrow's pandas check.

``pa.array`` of a Python list first asks whether the list is a pandas array, and that imports pandas (a
quarter of a CPU second), which a plain ingest otherwise never needs.  Rows whose every column holds only
``int`` (in int64) or only ``str`` are built from their buffers, as ``from_pylist`` types them (int64,
string, no nulls); anything else (None, floats, booleans, rows with other keys) goes to ``from_pylist``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pyarrow as pa

from console.archive import arrow_np


def table_from_rows(rows: list[dict[str, Any]]) -> pa.Table:
    """The same table as ``pa.Table.from_pylist(rows)``."""
    names = list(rows[0]) if rows else []
    if not rows or any(list(r) != names for r in rows):
        return pa.Table.from_pylist(rows)
    arrays: list[pa.Array] = []
    for name in names:
        values = [r[name] for r in rows]
        if all(type(v) is str for v in values):
            arrays.append(arrow_np.strings(values, pa.string()))
        elif all(type(v) is int and -(1 << 63) <= v < (1 << 63) for v in values):
            arrays.append(arrow_np.array(np.array(values, np.int64)))
        else:
            return pa.Table.from_pylist(rows)
    return pa.Table.from_arrays(arrays, names=names)
