"""The stream's per-chunk order (by head, then time) is lexsort's, whichever way it is found."""

from __future__ import annotations

import numpy as np
import pytest

from console.analysis.head_table import by_head_then_time


@pytest.mark.parametrize("heads", [1, 80, 70_000])  # 70 000: keys beyond 16 bits, lexsort only
def test_same_order_as_lexsort(heads: int) -> None:
    rng = np.random.default_rng(heads)
    for trial in range(200):
        n = int(rng.integers(0, 500))
        h = rng.integers(0, heads, n).astype(np.intp)
        t = rng.integers(0, 40, n).astype(np.int64)  # ties in time, within a head and across heads
        if trial % 2:
            t = np.sort(t)  # each head's records in time order: the radix path
        order, hs, ts = by_head_then_time(h, t)
        expected = np.lexsort((t, h))
        assert order.tolist() == expected.tolist()
        assert hs.tolist() == h[expected].tolist() and ts.tolist() == t[expected].tolist()
