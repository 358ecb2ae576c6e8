"""The GNSS unit table's grouping, from the fix table's categorical codes: no Python string per fix.

:func:`sorted_codes` gives what ``pd.factorize(column.astype(str), sort=True)`` gives (a code per row
into the distinct values, sorted), but for a categorical column of strings it reads the codes the
column already has: on a file of a million devices, ``astype(str)`` made an array of a million
references and ``factorize`` hashed every string again (together ~65 MB at the report's peak).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

NAT_NS = int(np.iinfo(np.int64).min)


def sorted_codes(column: pd.Series) -> tuple[np.ndarray, pd.Index]:
    """(code per row, the distinct values as strings, sorted) as ``pd.factorize(column.astype(str), sort=True)``."""
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


def first_last_ns(code: np.ndarray, times_ns: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Per group (``code`` in ``range(n)``), the first and last known time (int64 ns; NaT when none)."""
    first = np.full(n, NAT_NS, np.int64)
    last = first.copy()
    known = times_ns != NAT_NS
    if not known.any():
        return first, last
    c, t = code[known], times_ns[known]
    order = np.lexsort((t, c))  # by group, then time: each group's first and last are its run's ends
    c, t = c[order], t[order]
    starts = np.flatnonzero(np.r_[True, c[1:] != c[:-1]])
    ends = np.r_[starts[1:] - 1, len(c) - 1]
    first[c[starts]] = t[starts]
    last[c[ends]] = t[ends]
    return first, last
