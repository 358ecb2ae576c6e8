"""The report's GNSS unit grouping from categorical codes equals the pandas grouping it replaced.

``sorted_codes`` stands for ``pd.factorize(column.astype(str), sort=True)`` and ``first_last_ns`` for a
``groupby(code).min()/max()`` of the times; both are compared with those over random columns (categorical
with unused categories, plain strings, missing values, NaT times).
"""

from __future__ import annotations

import random

import numpy as np
import pandas as pd
import pytest
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


def _natural_key(x: object) -> str:
    from console.inputs.recognise import NUMBER_PARTS
    from console.sinks.report.gnss_units import _padded_number

    return NUMBER_PARTS.sub(_padded_number, str(x).casefold())


@pytest.mark.parametrize("with_nul", [False, True])
def test_sorted_positions_as_string_keys(with_nul: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    # Digits (padded to keys with NULs inside), case, casefold's ß, accents, a lone surrogate, non-ASCII
    # digits, empty names; with_nul adds names ending in NUL (the string path).
    from console.sinks.report import unit_codes

    alphabet = ["a", "B", "b", "0", "1", "9", "00", "12", "-", " ", "ß", "é", "Ω", "\udc80", "x", "Z", "٣", "²"]
    if with_nul:
        alphabet.append("\x00")
    else:

        def no_strings(*_: object) -> np.ndarray:
            raise AssertionError("bytes keys expected")

        monkeypatch.setattr(unit_codes, "_sorted_as_strings", no_strings)
    rng = random.Random(int(with_nul))
    for _ in range(30):
        names = ["".join(rng.choice(alphabet) for _ in range(rng.randint(0, 6))) for _ in range(rng.randint(0, 2000))]
        want = np.argsort(np.array([_natural_key(x) for x in names], dtype=object), kind="stable")
        got = unit_codes.sorted_positions(pd.Index(names, dtype=object), _natural_key, chunk=rng.choice([1, 7, 500]))
        assert (want == got).all()
