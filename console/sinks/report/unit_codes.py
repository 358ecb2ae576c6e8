"""The GNSS unit table's grouping, from the fix table's categorical codes: no Python string per fix.

:func:`sorted_codes` gives what ``pd.factorize(column.astype(str), sort=True)`` gives (a code per row
into the distinct values, sorted), but for a categorical column of strings it reads the codes the
column already has: on a file of a million devices, ``astype(str)`` made an array of a million
references and ``factorize`` hashed every string again (together ~65 MB at the report's peak).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

NAT_NS = int(np.iinfo(np.int64).min)


def sorted_codes(column: pd.Series) -> tuple[np.ndarray, pd.Index]:
    """(code per row, the distinct values as strings, sorted) as ``pd.factorize(column.astype(str), sort=True)``."""
    import pandas as pd  # deferred, with the report's other uses of pandas (see console.sinks.report.model)

    dtype = column.dtype
    if isinstance(dtype, pd.CategoricalDtype) and dtype.categories.inferred_type in ("string", "empty"):
        raw = column.cat.codes.to_numpy()
        if not len(raw) or raw.min() >= 0:  # a missing value would read "nan" as a string: the general path
            categories = np.asarray(dtype.categories, dtype=object)
            used = np.flatnonzero(np.bincount(raw.astype(np.int64), minlength=len(categories)))
            ranked = used[np.argsort(categories[used], kind="stable")]
            rank = np.zeros(len(categories), np.int64)
            rank[ranked] = np.arange(len(ranked))
            return rank[raw], pd.Index(categories[ranked], dtype=object)
    code, names = pd.factorize(column.astype(str), sort=True)
    return np.asarray(code, np.int64), pd.Index(names, dtype=object)


def sorted_name_codes(codes: np.ndarray, names: Sequence[str]) -> tuple[np.ndarray, Sequence[str]]:
    """:func:`sorted_codes` for a column held as codes into its distinct ``names`` (the GNSS fix columns):
    (code per row into the names used, the names used in string order).

    Names in a :class:`~parsers.gnss.fix_table.NameTable` are sorted from their UTF-8 bytes and come
    back as a table over the same flat strings: no Python string per name (a pandas categorical of a
    million device names held ~60 MB of them from the read to the report's end).
    """
    from parsers.gnss.fix_table import NameTable

    codes = np.asarray(codes)
    if not len(codes):
        return np.zeros(0, np.int64), []
    used = np.flatnonzero(np.bincount(codes, minlength=len(names)))
    if isinstance(names, NameTable):
        ranked = names.string_order(used)
        table: Sequence[str] = names.reordered(ranked)
    else:
        values = np.asarray(list(names), dtype=object)
        ranked = used[np.argsort(values[used], kind="stable")]
        table = [str(v) for v in values[ranked]]
    rank = np.zeros(len(names), np.int64)
    rank[ranked] = np.arange(len(ranked))
    return rank[codes], table


def first_last_ns(code: np.ndarray, times_ns: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per group (``code`` in ``range(n)``), the first and last known time (int64 ns; NaT when none).

    Reduced in place (``minimum.at``/``maximum.at``): a sort by group and time held five copies of the
    columns at once (~70 MB at a million devices)."""
    first = np.full(n, NAT_NS, np.int64)
    last = first.copy()
    known = times_ns != NAT_NS
    if not known.any():
        return first, last
    c, t = (code, times_ns) if known.all() else (code[known], times_ns[known])
    never = np.iinfo(np.int64).max  # above any time (they end in 2262)
    lowest = np.full(n, never, np.int64)
    np.minimum.at(lowest, c, t)
    np.maximum.at(last, c, t)  # NaT is int64's least: a group without a known time keeps it
    first[lowest != never] = lowest[lowest != never]
    return first, last


def sorted_positions(
    names: pd.Index | Sequence[object] | Sequence[str], key: Callable[[object], str], chunk: int = 65_536
) -> np.ndarray:
    """``np.argsort(np.array([key(x) for x in names], dtype=object), kind="stable")``, with the keys held
    as one array of UTF-8 bytes (whose order is the code points' order) made a chunk of names at a
    time, instead of a Python string per name (a million device names: ~70 MB of keys at the peak).
    The keys go straight into the one array (not chunks joined at the end, which held them twice)."""
    keys_all: np.ndarray | None = None
    for start in range(0, len(names), chunk):
        keys = [key(x) for x in names[start : start + chunk]]
        # numpy compares bytes with trailing NULs as padding: a key ending in one is sorted as strings.
        if any(k.endswith("\x00") for k in keys):
            return _sorted_as_strings(names, key)
        part = np.array([k.encode("utf-8", "surrogatepass") for k in keys], dtype=bytes)
        if keys_all is None:
            keys_all = np.empty(len(names), part.dtype)
        elif part.dtype.itemsize > keys_all.dtype.itemsize:
            keys_all = keys_all.astype(part.dtype)  # a longer key: those so far padded to its width
        keys_all[start : start + len(part)] = part
    if keys_all is None:
        return np.zeros(0, np.int64)
    return np.argsort(keys_all, kind="stable")


def _sorted_as_strings(names: pd.Index | Sequence[object], key: Callable[[object], str]) -> np.ndarray:
    return np.argsort(np.array([key(x) for x in names], dtype=object), kind="stable")
