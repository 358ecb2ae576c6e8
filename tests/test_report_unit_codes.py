"""The report's GNSS unit grouping from categorical codes equals the pandas grouping it replaced.

``sorted_codes`` stands for ``pd.factorize(column.astype(str), sort=True)`` and ``first_last_ns`` for a
``groupby(code).min()/max()`` of the times; both are compared with those over random columns (categorical
with unused categories, plain strings, missing values, NaT times).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import given
from hypothesis import strategies as st

from console.sinks.report.unit_codes import NAT_NS, first_last_ns, sorted_codes

_values = st.lists(st.sampled_from(["b", "a", "B", "d10", "d9", "ä", "", "z"]), max_size=40)


def _reference(column: pd.Series) -> tuple[np.ndarray, list[str]]:
    code, names = pd.factorize(column.astype(str), sort=True)
    return np.asarray(code, np.int64), [str(n) for n in names]


@given(_values, st.lists(st.sampled_from(["q", "b", "zz"]), max_size=3), st.booleans())
def test_sorted_codes_as_factorize(values: list[str], unused: list[str], categorical: bool) -> None:
    column = pd.Series(values, dtype=object)
    if categorical:
        cats = list(dict.fromkeys([*values[::-1], *unused]))  # not sorted, some unused
        column = pd.Series(pd.Categorical(values, categories=cats))
    code, names = sorted_codes(column)
    ref_code, ref_names = _reference(column)
    assert code.tolist() == ref_code.tolist()
    assert list(names) == ref_names


@given(_values)
def test_sorted_codes_with_a_missing_value_as_factorize(values: list[str]) -> None:
    column = pd.Series(pd.Categorical([*values, None]))
    code, names = sorted_codes(column)
    ref_code, ref_names = _reference(column)
    assert code.tolist() == ref_code.tolist() and list(names) == ref_names


@given(st.lists(st.tuples(st.integers(0, 6), st.one_of(st.none(), st.integers(-(10**12), 10**12))), max_size=50))
def test_first_last_as_groupby(rows: list[tuple[int, int | None]]) -> None:
    n = 7
    code = np.array([c for c, _ in rows], np.int64)
    times_ns = np.array([NAT_NS if t is None else t for _, t in rows], np.int64)
    first, last = first_last_ns(code, times_ns, n)
    times = pd.Series(times_ns.view("datetime64[ns]"))
    by = times.groupby(code, sort=True)
    ref_first = np.full(n, NAT_NS, np.int64)
    ref_last = ref_first.copy()
    if len(rows):
        t0, t1 = by.min(), by.max()
        ref_first[t0.index.to_numpy()] = t0.to_numpy("datetime64[ns]").view(np.int64)
        ref_last[t1.index.to_numpy()] = t1.to_numpy("datetime64[ns]").view(np.int64)
    assert first.tolist() == ref_first.tolist()
    assert last.tolist() == ref_last.tolist()
