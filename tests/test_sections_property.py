"""Fail-safe property: no section is ever reported clear while an axle is inside it.

Randomized trains run over the example layout.  Faults are injected into the
*wheel-sensor records* (not into the engine's events), and the whole chain
runs: overlap rule → detection events → section engine.  After every event
time the test compares each section's reported state with the true position
of every axle.

Injected faults: one system missing a wheel, a dead channel, a power loss at
a head (records lost), lone interference pulses, and operator resets (only
when the section is truly empty: an operator verifies before resetting, as
seed 003 requires).  Not injected, because no axle counter can see it: a
wheel both systems miss.  Vehicles have at least two axles, each within the
soft-timing isolation time of the next (seed 002's rule treats a lone pulse
as accidental by design).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from console.analysis.counting.bank import two_channel_events
from console.analysis.counting.wheels import CountingSettings
from console.analysis.events.detection import DetectionEvent, EventKind, sort_events
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState
from console.layout import load_layout

NS = 1_000_000_000
LAYOUT = load_layout("example")
HEAD_X = {h.id: h.chainage_m for h in LAYOUT.heads}
SPACING, ZONE = 0.13, 0.25


@dataclass
class Train:
    up: bool
    start_s: float
    speed: float
    axles: list[float]


@st.composite
def trains_st(draw: st.DrawFn) -> list[Train]:
    """Trains on one track that never share a spot: a follower in the same
    direction is no faster than its leader and starts after the leader has
    passed the first head; otherwise a train waits until the line is clear."""
    n = draw(st.integers(1, 5))
    line_m = max(HEAD_X.values()) - min(HEAD_X.values()) + 200
    out: list[Train] = []
    for _ in range(n):
        up = draw(st.booleans())
        speed = draw(st.floats(2.0, 25.0))
        gaps = draw(st.lists(st.floats(1.2, 12.0), min_size=1, max_size=7))
        axles = [0.0, *np.cumsum(gaps).tolist()]
        wait = draw(st.floats(1.0, 600.0))
        if not out:
            start = draw(st.floats(0, 300))
        else:
            prev = out[-1]
            if prev.up == up and speed <= prev.speed:
                start = prev.start_s + (prev.axles[-1] + 1.0) / prev.speed + wait
            else:
                start = prev.start_s + (line_m + prev.axles[-1]) / prev.speed + wait
        out.append(Train(up, start, speed, axles))
    return out


def crossing_ns(tr: Train, head: str, axle_m: float) -> int:
    """When an axle's wheel reaches a head (the later of its two onsets)."""
    origin = min(HEAD_X.values()) - 100 if tr.up else max(HEAD_X.values()) + 100
    dist = abs(HEAD_X[head] - origin) + axle_m
    return int((tr.start_s + dist / tr.speed + SPACING / tr.speed) * NS)


@st.composite
def scenarios(draw: st.DrawFn) -> tuple[list[Train], dict]:
    trains = draw(trains_st())
    faults = {
        # (train, axle, head) → the one system that misses that wheel there.
        "miss": draw(
            st.dictionaries(
                st.tuples(st.integers(0, 4), st.integers(0, 7), st.sampled_from(list(HEAD_X))),
                st.sampled_from([1, 2]),
                max_size=3,
            )
        ),
        "dead": draw(st.none() | st.tuples(st.sampled_from(list(HEAD_X)), st.sampled_from([1, 2]), st.floats(0, 8000))),
        "power": draw(st.none() | st.tuples(st.sampled_from(list(HEAD_X)), st.floats(0, 8000), st.floats(5, 600))),
        "pulses": draw(
            st.lists(st.tuples(st.sampled_from(list(HEAD_X)), st.sampled_from([1, 2]), st.floats(0, 9000)), max_size=3)
        ),
        "resets": draw(
            st.lists(st.tuples(st.sampled_from([s.id for s in LAYOUT.sections]), st.floats(0, 12000)), max_size=6)
        ),
    }
    return trains, faults


def _spans(trains: list[Train]) -> dict[str, list[tuple[int, int]]]:
    """Each axle's stay in each section: [past the entry head, past the exit head) in ns."""
    spans: dict[str, list[tuple[int, int]]] = {s.id: [] for s in LAYOUT.sections}
    for tr in trains:
        for a in tr.axles:
            for s in LAYOUT.sections:
                lo, hi = sorted(s.heads, key=HEAD_X.__getitem__)
                enter, leave = (lo, hi) if tr.up else (hi, lo)
                spans[s.id].append((crossing_ns(tr, enter, a), crossing_ns(tr, leave, a)))
    return spans


def _truth(trains: list[Train], t_ns: int, spans: dict[str, list[tuple[int, int]]] | None = None) -> dict[str, int]:
    """Axles truly inside each section at t (counted once past the bounding head); ``spans`` is
    ``_spans(trains)``, worked out once per scenario rather than at every event time."""
    spans = _spans(trains) if spans is None else spans
    return {sid: sum(1 for a, b in stays if a <= t_ns < b) for sid, stays in spans.items()}


def _events(trains: list[Train], faults: dict) -> list[DetectionEvent]:
    recs: dict[str, list[tuple[int, int, int]]] = {h: [] for h in HEAD_X}  # head → (channel, t, value)
    power = faults["power"]
    dead = faults["dead"]
    for ti, tr in enumerate(trains):
        for k, a in enumerate(tr.axles):
            for head in HEAD_X:
                t_late = crossing_ns(tr, head, a)
                t_early = t_late - int(SPACING / tr.speed * NS)
                zone = int(ZONE / tr.speed * NS)
                first, second = (1, 2) if tr.up else (2, 1)
                for ch, t_on in ((first, t_early), (second, t_late)):
                    if faults["miss"].get((ti, k, head)) == ch:
                        continue
                    if dead and dead[0] == head and dead[1] == ch and t_on >= dead[2] * NS:
                        continue
                    if power and power[0] == head and power[1] * NS <= t_on <= (power[1] + power[2]) * NS:
                        continue
                    recs[head] += [(ch, t_on, 1), (ch, t_on + zone, 0)]
    for head, ch, t in faults["pulses"]:
        if not (power and power[0] == head and power[1] <= t <= power[1] + power[2]):
            recs[head] += [(ch, int(t * NS), 1), (ch, int(t * NS) + NS // 10, 0)]
    events: list[DetectionEvent] = []
    for head, rows in recs.items():
        if rows:
            arr = _as_the_channel_reports(np.array(rows, dtype=np.int64))
            events += two_channel_events(head, arr[:, 0], arr[:, 1], arr[:, 2], settings=CountingSettings())
    if power:
        events.append(DetectionEvent(int(power[1] * NS), EventKind.POWER_LOSS, power[0]))
        events.append(DetectionEvent(int((power[1] + power[2]) * NS), EventKind.POWER_RESTORED, power[0]))
    if dead:
        events.append(DetectionEvent(int(dead[2] * NS), EventKind.CHANNEL_FAULT, dead[0], channel=dead[1]))
    return sort_events(events)


# Found by this search (2026-11-28): a pulse on WS3's Sys1 15 ms before the last axle's onset on Sys2 turned
# that axle's direction; B1 was shown clear with two axles inside until the counter took the reversed
# release order as doubt (tests/test_counting_release_order.py).
PULSE_OVER_A_WHEEL = (
    [
        Train(up=False, start_s=1.0, speed=25.0, axles=[0.0, 2.0, 4.0, 6.0, 13.0]),
        *(Train(up=False, start_s=2.56 + 2.5 * i, speed=2.0, axles=[0.0, 2.0]) for i in range(4)),
    ],
    {"miss": {}, "dead": None, "power": None, "pulses": [("WS3", 1, 67.5)], "resets": []},
)


def _as_the_channel_reports(rows: np.ndarray) -> np.ndarray:
    """(channel, t, value) dampings as a system's records show them: a channel's state, so dampings that
    overlap (a pulse over a wheel) are one damping from the first onset to the last release, not a release
    in the middle while the system is still damped."""
    out = []
    for ch in np.unique(rows[:, 0]):
        on = rows[(rows[:, 0] == ch) & (rows[:, 2] == 1), 1]
        off = rows[(rows[:, 0] == ch) & (rows[:, 2] == 0), 1]
        order = np.argsort(on, kind="stable")
        on, off = on[order], off[order]  # each damping's release is written right after its onset
        end = np.maximum.accumulate(off)
        new = np.r_[True, on[1:] > end[:-1]]  # begins after every earlier damping ended
        starts = np.flatnonzero(new)
        ends = np.r_[starts[1:], len(on)] - 1
        out += [(ch, t, 1) for t in on[starts]] + [(ch, t, 0) for t in end[ends]]
    return np.array(out, dtype=np.int64)


@settings(max_examples=300, deadline=None)
@given(scenario=scenarios(), initial=st.sampled_from([SectionState.CLEAR, SectionState.PREPARATORY]))
@example(scenario=PULSE_OVER_A_WHEEL, initial=SectionState.CLEAR)
def test_never_clear_with_an_axle_inside(scenario: tuple[list[Train], dict], initial: SectionState) -> None:
    _assert_never_clear_with_an_axle_inside(scenario, initial)


@st.composite
def pulses_over_wheels(draw: st.DrawFn) -> tuple[list[Train], dict]:
    """Scenarios whose interference pulses fall within 0.3 s of a wheel at a head: the rare case the
    uniformly placed pulses above reach only once in many runs.  One pulse per head, and none at a head that
    misses a wheel: pulses on both systems in turn over a wheel, or a pulse standing in for a missed damping,
    are a whole wheel the other way, which no counter can tell from one."""
    trains, faults = draw(scenarios())
    missing = {head for _, _, head in faults["miss"]}
    pulses = []
    heads = [h for h in HEAD_X if h not in missing]
    for head in draw(st.lists(st.sampled_from(heads), min_size=1, max_size=3, unique=True)):
        tr = trains[draw(st.integers(0, len(trains) - 1))]
        t_s = crossing_ns(tr, head, draw(st.sampled_from(tr.axles))) / NS + draw(st.floats(-0.3, 0.3))
        pulses.append((head, draw(st.sampled_from([1, 2])), t_s))
    return trains, {**faults, "pulses": pulses}


@settings(max_examples=500, deadline=None)
@given(scenario=pulses_over_wheels(), initial=st.sampled_from([SectionState.CLEAR, SectionState.PREPARATORY]))
def test_never_clear_with_an_axle_inside_when_pulses_fall_on_wheels(
    scenario: tuple[list[Train], dict], initial: SectionState
) -> None:
    _assert_never_clear_with_an_axle_inside(scenario, initial)


def _assert_never_clear_with_an_axle_inside(scenario: tuple[list[Train], dict], initial: SectionState) -> None:
    trains, faults = scenario
    events = _events(trains, faults)
    # Operator resets, only when the section is truly empty at that moment.
    for sid, t in faults["resets"]:
        t_ns = int(t * NS)
        if _truth(trains, t_ns)[sid] == 0:
            events.append(DetectionEvent(t_ns, EventKind.RESET, sid, source="operator"))
    events = sort_events(events)
    engine = SectionEngine(LAYOUT, initial=initial, start_ns=0)
    times = sorted({e.time_ns for e in events})
    spans = _spans(trains)
    i = 0
    for t in times:
        while i < len(events) and events[i].time_ns == t:
            engine.step(events[i])
            i += 1
        truth = _truth(trains, t, spans)
        for sid in truth:
            if engine.state(sid) is SectionState.CLEAR:
                assert truth[sid] == 0, f"{sid} shown clear at {t / NS:.3f} s with {truth[sid]} axles inside"


@settings(max_examples=100, deadline=None)
@given(trains=trains_st())
def test_without_faults_every_section_ends_clear(trains: list[Train]) -> None:
    """The other half of correctness: a fault-free run does not stay disturbed."""
    events = _events(trains, {"miss": {}, "dead": None, "power": None, "pulses": []})
    engine = SectionEngine(LAYOUT, initial=SectionState.CLEAR, start_ns=0)
    for e in events:
        engine.step(e)
    assert {sid: engine.state(sid) for sid in engine.sections} == {s.id: SectionState.CLEAR for s in LAYOUT.sections}
