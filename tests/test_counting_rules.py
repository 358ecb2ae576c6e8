"""The counting rules, each from its seed's own description."""

from __future__ import annotations

import numpy as np

from console.analysis.counting.bank import two_channel_events
from console.analysis.counting.edge_rule import SIGNAL_A, SIGNAL_B, confirmed_axles, edge_rule_events
from console.analysis.counting.majority import majority_events
from console.analysis.counting.wheels import CountingSettings
from console.analysis.events.detection import DOWN, UP, EventKind

MS = 1_000_000
S = 1_000_000_000


def _kinds(events: list) -> list[str]:
    return [str(e.kind) for e in sorted(events, key=lambda e: e.time_ns)]


def _two(rows: list[tuple[int, int, int]], **kw: object):  # (channel, t_ms, value)
    a = np.array(rows, dtype=np.int64)
    return two_channel_events("WS1", a[:, 0], a[:, 1] * MS, a[:, 2], **kw)  # type: ignore[arg-type]


# --- seed 003: two channels, overlap rule ---------------------------------------


def test_overlapping_dampings_are_one_axle_with_direction() -> None:
    # Sys1 damped 0–50 ms, Sys2 26–76 ms: they overlap, Sys1 first → up.
    ev = _two([(1, 0, 1), (2, 26, 1), (1, 50, 0), (2, 76, 0)])
    axles = [e for e in ev if e.kind is EventKind.AXLE]
    assert len(axles) == 1 and axles[0].direction == UP
    assert _kinds(ev) == ["head_damped", "axle", "head_free"]


def test_sys2_first_is_down_and_the_layout_can_swap_it() -> None:
    rows = [(2, 0, 1), (1, 20, 1), (2, 45, 0), (1, 65, 0)]
    assert [e.direction for e in _two(rows) if e.kind is EventKind.AXLE] == [DOWN]
    assert [e.direction for e in _two(rows, up_is_sys1_first=False) if e.kind is EventKind.AXLE] == [UP]


def test_dampings_that_do_not_overlap_are_not_an_axle() -> None:
    # Sys1 0–50 ms and Sys2 80–130 ms: no overlap, so no axle (seed 003: "overlap").
    ev = _two([(1, 0, 1), (1, 50, 0), (2, 80, 1), (2, 130, 0)])
    assert not [e for e in ev if e.kind is EventKind.AXLE]


def test_single_system_damping_alone_is_accidental_after_the_quiet_time() -> None:
    # A trolley's metal damps Sys1 only, nothing else for minutes (seed 002 soft timing).
    ev = _two([(1, 0, 1), (1, 180, 0)])
    # Known to be alone when it ends (180 ms): held then, released 60 s after it began.
    assert _kinds(ev) == ["head_damped", "interference", "head_free", "accidental"]
    assert next(e for e in ev if e.kind is EventKind.INTERFERENCE).time_ns == 180 * MS
    acc = next(e for e in ev if e.kind is EventKind.ACCIDENTAL)
    assert acc.time_ns == 60 * S  # held for the isolation time, then released


def test_single_system_damping_amid_a_train_is_doubt() -> None:
    # A wheel Sys2 missed, between two good axles a second away: a possibly missed axle.
    rows = [(1, 0, 1), (2, 20, 1), (1, 45, 0), (2, 65, 0)]
    rows += [(1, 1000, 1), (1, 1045, 0)]
    rows += [(1, 2000, 1), (2, 2020, 1), (1, 2045, 0), (2, 2065, 0)]
    ev = _two(rows)
    assert [str(e.kind) for e in ev if e.kind not in (EventKind.HEAD_DAMPED, EventKind.HEAD_FREE)].count("axle") == 2
    single = [e for e in ev if e.kind is EventKind.SINGLE_CHANNEL]
    assert len(single) == 1 and single[0].channel == 1


def test_isolated_pulse_followed_by_a_train_becomes_doubt() -> None:
    # Quiet before, but 20 s later wheels come: it may have been that train's missed wheel.
    rows = [(1, 0, 1), (1, 40, 0), (1, 20_000, 1), (2, 20_020, 1), (1, 20_045, 0), (2, 20_065, 0)]
    ev = _two(rows)
    kinds = [e.kind for e in ev]
    assert EventKind.INTERFERENCE in kinds and EventKind.ACCIDENTAL not in kinds
    single = [e for e in ev if e.kind is EventKind.SINGLE_CHANNEL]
    assert single and single[0].time_ns == 20_000 * MS


def test_whole_second_onsets_pair_within_the_window() -> None:
    # No release records (the paper's export): onsets pair if within 0.47 s.
    ev = _two([(1, 0, 1), (2, 0, 1)], settings=CountingSettings())
    (axle,) = [e for e in ev if e.kind is EventKind.AXLE]
    assert axle.direction == 0  # same timestamp: order unknown


# --- seed 000: A (clear) / B (occupied) edge rule -------------------------------


def _edges(rows: list[tuple[int, int, int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a = np.array(rows, dtype=np.int64)
    return a[:, 0], a[:, 1], a[:, 2] * MS


def test_rising_b_then_rising_a_confirms_an_axle() -> None:
    sig, lev, t = _edges([(SIGNAL_A, 0, 0), (SIGNAL_B, 1, 10), (SIGNAL_B, 0, 30), (SIGNAL_A, 1, 40)])
    ok, unsure = confirmed_axles(sig, lev, t)
    assert ok.tolist() == [40 * MS] and unsure.tolist() == []


def test_a_dropping_without_b_is_uncertain_not_an_axle() -> None:
    # Metal that is not a wheel: A falls (not full in-phase) but B never rises.
    sig, lev, t = _edges([(SIGNAL_A, 0, 0), (SIGNAL_A, 1, 50)])
    ok, unsure = confirmed_axles(sig, lev, t)
    assert ok.tolist() == [] and unsure.tolist() == [0]


def test_a_pair_of_edge_sensors_gives_direction() -> None:
    one = [(SIGNAL_A, 0, 0), (SIGNAL_B, 1, 5), (SIGNAL_B, 0, 25), (SIGNAL_A, 1, 30)]
    two = [(s, lv, t + 20) for s, lv, t in one]  # sensor 2 sees it 20 ms later
    rows = [(1, *r) for r in one] + [(2, *r) for r in two]
    a = np.array(rows, dtype=np.int64)
    ev = edge_rule_events("E1", a[:, 0], a[:, 1], a[:, 2], a[:, 3] * MS)
    (axle,) = [e for e in ev if e.kind is EventKind.AXLE]
    assert axle.direction == UP


# --- seed 002: three elements, majority -----------------------------------------


def _wheels(pattern: list[tuple[int, ...]], gap_ms: int = 500, step_ms: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Each tuple: the elements that fire for one wheel, in order."""
    el, t = [], []
    for w, elements in enumerate(pattern):
        for k, e in enumerate(elements):
            el.append(e)
            t.append((w * gap_ms + k * step_ms) * MS)
    return np.array(el), np.array(t, dtype=np.int64)


def test_unanimous_wheels_count_without_error() -> None:
    el, t = _wheels([(1, 2, 3)] * 4)
    ev = majority_events("S", el, t)
    assert [e.kind for e in ev] == [EventKind.AXLE] * 4
    assert all(e.direction == UP for e in ev)


def test_two_of_three_counts_with_err() -> None:
    el, t = _wheels([(1, 3)])
    ev = majority_events("S", el, t)
    assert [e.kind for e in ev] == [EventKind.AXLE, EventKind.COUNT_ERROR]
    assert ev[1].channel == 2


def test_dead_element_is_faulty_after_three_interrupts() -> None:
    # S2 never answers: after CINT = 3 its MARKS2 is still 0 (and C2 is 0) → faulty.
    el, t = _wheels([(1, 3)] * 4)
    ev = majority_events("S", el, t)
    faults = [e for e in ev if e.kind is EventKind.CHANNEL_FAULT]
    assert len(faults) == 1 and faults[0].channel == 2
    axles_before = [e for e in ev if e.kind is EventKind.AXLE and e.time_ns <= faults[0].time_ns]
    assert len(axles_before) == 3


def test_s3_to_s1_is_down() -> None:
    el, t = _wheels([(3, 2, 1)] * 2)
    assert {e.direction for e in majority_events("S", el, t) if e.kind is EventKind.AXLE} == {DOWN}


def test_one_element_alone_is_accidental_when_isolated() -> None:
    el, t = _wheels([(2,)])
    assert [e.kind for e in majority_events("S", el, t)] == [EventKind.INTERFERENCE, EventKind.ACCIDENTAL]
