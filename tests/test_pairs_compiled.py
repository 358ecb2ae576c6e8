"""The compiled pairing of wheel onsets (console/analysis/counting/compiled_pairs.c) and the numpy one give the
same pairs.

Both run over the same onsets sorted by head, then time: the positions of each pair's Sys1 and Sys2 onset, in
the same order, and each pair's stamp step must be equal.  The inputs are random: heads with sub-second stamps
(nanosecond, microsecond and millisecond steps, equal times, Sys2 onsets two Sys1 onsets reach for), heads with
whole-second stamps (runs of neighbours of both systems), heads mixing both, with and without each head's step
given up front (some heads beyond the given ones, a NaN step); and whole pairings through pair_axle_arrays.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from console.analysis.counting import wheels
from console.analysis.counting.wheels import SYS1, SYS2, PairingSettings, pair_axle_arrays
from parsers.units import NS
from tests.compiled_parts import needs_compiled

pytestmark = needs_compiled(wheels.compiled_pairs, "console.analysis.counting.compiled_pairs")

_STEPS_NS = (1, 1_000, 1_000_000, NS)


@st.composite
def onsets(draw: st.DrawFn) -> dict[str, np.ndarray]:
    """Onsets of a few heads, in read order: each head's times rise (with repeats), heads interleaved; now and
    then two of a head's onsets swapped (its times go back) or head keys far above the onsets' number."""
    n_heads = draw(st.integers(1, 5))
    offset = draw(st.sampled_from([0, 0, 0, 10**7]))  # keys too sparse for the counting sort
    heads, times, channels, subs = [], [], [], []
    for h in range(n_heads):
        step = draw(st.sampled_from(_STEPS_NS))
        n = draw(st.integers(0, 40))
        gaps = draw(st.lists(st.integers(0, 6), min_size=n, max_size=n))  # 0: an equal time
        t = draw(st.integers(-3, 3)) * NS + np.cumsum(np.array(gaps, np.int64)) * step * draw(st.integers(1, 90))
        channels += draw(st.lists(st.sampled_from([SYS1, SYS2]), min_size=n, max_size=n))
        whole = step == NS
        # A head with whole-second stamps carries no fraction; one sub-second head now and then has a stamp
        # without one (it pairs as a whole-second head then).
        sub = [not whole] * n
        if n and not whole and draw(st.booleans()) and draw(st.booleans()):
            sub[draw(st.integers(0, n - 1))] = False
        heads += [h * 3 + offset] * n
        times += t.tolist()
        subs += sub
    # Read order: by time, heads interleaved, each head's own order kept (a stable sort).
    by = np.argsort(np.array(times, np.int64), kind="stable")
    if len(by) > 1 and draw(st.integers(0, 5)) == 0:
        i, j = sorted(draw(st.lists(st.integers(0, len(by) - 1), min_size=2, max_size=2, unique=True)))
        by[[i, j]] = by[[j, i]]
    return {
        "head": np.array(heads, np.int64)[by],
        "channel": np.array(channels, np.int64)[by],
        "time_ns": np.array(times, np.int64)[by],
        "subsecond": np.array(subs, bool)[by],
    }


def _read_order(o: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
    return o["head"], o["time_ns"], o["channel"], o["subsecond"]


def _same(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> None:
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)


@settings(max_examples=400, deadline=None)
@given(
    o=onsets(),
    window_ms=st.sampled_from([0.0, 1.0, 20.0, 468.0, 5000.0]),
    given_steps=st.sampled_from([None, "all", "some", "nan"]),
)
def test_compiled_and_numpy_pairings_agree(o: dict[str, np.ndarray], window_ms: float, given_steps: str | None) -> None:
    gh, t, ch, sub = _read_order(o)
    fine_ns = int(window_ms * 1e6)
    coarse_ns = max(fine_ns, NS)
    head_step = None
    if given_steps is not None and len(gh):
        n = int(gh.max()) + 1 if given_steps != "some" else max(int(gh.max()) // 2, 1)
        head_step = np.where(np.arange(n) % 2 == 0, 1e-3, 1.0)
        if given_steps == "nan":
            head_step[0] = np.nan
    args = (gh, t, ch, sub, head_step, fine_ns, coarse_ns)
    _same(wheels._pair_positions_compiled(*args), wheels._pair_positions_numpy(*args))


def test_a_sys2_onset_claimed_twice_goes_to_the_nearer_sys1_onset_either_way() -> None:
    # Sys1 at 0 and 10 ms, Sys2 at 6 ms: both reach for it; the later Sys1 is nearer (4 ms against 6 ms).
    gh = np.zeros(3, np.int64)
    t = np.array([0, 6_000_000, 10_000_000], np.int64)
    ch = np.array([SYS1, SYS2, SYS1], np.int64)
    sub = np.ones(3, bool)
    for pairing in (wheels._pair_positions_compiled, wheels._pair_positions_numpy):
        order, pa, pb, _ = pairing(gh, t, ch, sub, None, 468_000_000, NS)
        assert order.tolist() == [0, 1, 2] and pa.tolist() == [2] and pb.tolist() == [1]


@settings(max_examples=100, deadline=None)
@given(o=onsets())
def test_whole_pairings_agree(o: dict[str, np.ndarray]) -> None:
    s = PairingSettings()
    before = wheels.pair_positions
    try:
        wheels.pair_positions = wheels._pair_positions_numpy
        numpy_axles, numpy_unpaired = pair_axle_arrays(o, s)
        wheels.pair_positions = wheels._pair_positions_compiled
        compiled_axles, compiled_unpaired = pair_axle_arrays(o, s)
    finally:
        wheels.pair_positions = before
    assert compiled_unpaired == numpy_unpaired
    assert compiled_axles.keys() == numpy_axles.keys()
    for c in numpy_axles:
        np.testing.assert_array_equal(compiled_axles[c], numpy_axles[c])
