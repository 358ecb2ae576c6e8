"""`Window`: what ``deque(maxlen=n)`` keeps, for any run of appends and clears (it replaced the deques of the
live crossing units and the integrity monitor, a dozen per train)."""

from __future__ import annotations

from collections import deque

import pytest
from hypothesis import given
from hypothesis import strategies as st

from console.analysis.window import Window

OPS = st.lists(st.one_of(st.integers(-5, 5), st.just("clear")), max_size=60)


@given(maxlen=st.integers(1, 6), ops=OPS)
def test_a_window_keeps_what_a_deque_of_that_maxlen_keeps(maxlen: int, ops: list[int | str]) -> None:
    w: Window[int] = Window(maxlen)
    d: deque[int] = deque(maxlen=maxlen)
    for op in ops:
        if op == "clear":
            w.clear()
            d.clear()
        else:
            assert isinstance(op, int)
            w.append(op)
            d.append(op)
        assert list(w) == list(d) and len(w) == len(d) and bool(w) == bool(d)
        if d:
            assert w[-1] == d[-1] and w[0] == d[0]
            assert all(op_ in w for op_ in d)
    assert w.maxlen == d.maxlen


def test_a_window_keeps_one_item_at_least() -> None:
    with pytest.raises(ValueError):
        Window(0)
