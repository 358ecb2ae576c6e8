"""The vectorized counter gives exactly the scalar HeadCounter's events, for any split of the records.

:class:`console.analysis.counting.bank.CounterBank` applies seed 003's overlap
rule to blocks of records of many heads with array operations;
:class:`console.analysis.counting.wheels.HeadCounter` (the live engine's and the
simulator's counter) is the oracle, fed the same records one at a time.
Random record sequences per head: wheels (both systems overlapping, either
order, sometimes one system missing), lone pulses, repeated onsets,
releases missing (point mode) or ignored, whole-second stamps with ties,
stray channels, several heads interleaved; fed in blocks cut anywhere (down
to one record), with time let pass between blocks as the event stream
does.  Per head, the events must be the same, in the same order, field for
field (detail text included).

CI runs a few hundred examples; ``TRACKSIDE_LONG=1`` runs many more.
"""

from __future__ import annotations

import copy
import itertools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.analysis.counting.bank import CounterBank
from console.analysis.counting.holds import NONE, pass_time, pass_time_slices
from console.analysis.counting.wheels import CountingSettings, HeadCounter
from console.analysis.diag_events import DiagEventSettings, diag_detection_events
from console.analysis.events.block import COLUMNS, EventBlock
from console.analysis.events.detection import DetectionEvent, EventKind, sort_events
from console.analysis.passages.diag_analysis import DiagAnalysis
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.stream import ORDER_SLACK_S
from console.layout import Layout, load_layout
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_diagnostic
from tests.reads import whole_job

NS = 1_000_000_000
MS = 1_000_000
LONG = bool(os.environ.get("TRACKSIDE_LONG"))
CASE = settings(max_examples=3000 if LONG else 300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
GAPS_NS = [0, 0, 1, MS, 20 * MS, 200 * MS, 470 * MS, 900 * MS, NS, 2 * NS, 4 * NS, 30 * NS, 61 * NS, 300 * NS]


@dataclass(frozen=True)
class Head:
    up_is_sys1_first: bool
    point_mode: bool
    whole_second: bool


@st.composite
def head_records(draw: st.DrawFn, whole_second: bool, releases: bool) -> list[tuple[int, int, int]]:
    """(channel, time_ns, value) of one head, in time order."""
    out: list[tuple[int, int, int]] = []
    t = draw(st.integers(0, 3)) * NS
    for _ in range(draw(st.integers(0, 12))):
        t += draw(st.sampled_from(GAPS_NS))
        what = draw(st.sampled_from(["wheel", "wheel", "wheel", "pulse", "record"]))
        if what == "wheel":  # two systems a coil spacing apart, overlapping; sometimes one misses
            first = draw(st.sampled_from([1, 2]))
            delay = draw(st.sampled_from([0, 1, 5 * MS, 30 * MS, 300 * MS]))
            length = draw(st.sampled_from([10 * MS, 40 * MS, 600 * MS, 70 * NS]))
            missing = draw(st.sampled_from([None, None, None, 1, 2]))
            other = 3 - first
            rows = [(first, t, 1), (other, t + delay, 1), (first, t + length, 0), (other, t + delay + length, 0)]
            if draw(st.booleans()):  # a repeated onset
                rows.insert(1, (first, t + delay // 2, 1))
            out += [r for r in rows if r[0] != missing]
        elif what == "pulse":  # one system alone
            c = draw(st.sampled_from([1, 2]))
            out += [(c, t, 1), (c, t + draw(st.sampled_from([0, 50 * MS, 2 * NS])), 0)]
        else:
            out.append((draw(st.sampled_from([1, 2, 2, 3])), t, draw(st.sampled_from([0, 1, 1, 7]))))
    if not releases:
        out = [r for r in out if r[2] == 1]
    if whole_second:
        out = [(c, tt - tt % NS, v) for c, tt, v in out]
    # Per head in time order; equal times keep the order they were made in (the read order).
    return sorted(out, key=lambda r: r[1])


@st.composite
def logs(draw: st.DrawFn) -> tuple[list[Head], list[tuple[int, int, int, int]], CountingSettings]:
    heads = [
        Head(draw(st.booleans()), draw(st.booleans()), draw(st.booleans())) for _ in range(draw(st.integers(1, 4)))
    ]
    records: list[tuple[int, int, int, int]] = []
    for k, hd in enumerate(heads):
        rows = draw(head_records(hd.whole_second, releases=not hd.point_mode or draw(st.booleans())))
        records += [(k, c, t, v) for c, t, v in rows]
    # The read order: heads interleaved by time; a head's own records keep their order.
    records.sort(key=lambda r: r[2])
    s = CountingSettings(
        pair_window_s=draw(st.sampled_from([0.1, 0.13 / (1 / 3.6), 2.0])),
        isolation_s=draw(st.sampled_from([0.5, 5.0, 60.0])),
    )
    return heads, records, s


def _bank(heads: list[Head], s: CountingSettings) -> CounterBank:
    bank = CounterBank(s, names=[f"WS{k}" for k in range(len(heads))])
    bank.configure(
        np.arange(len(heads)),
        np.array([h.up_is_sys1_first for h in heads]),
        np.array([h.point_mode for h in heads]),
        np.array([h.whole_second for h in heads]),
    )
    return bank


def _by_head(events: list[DetectionEvent], out: dict[str, list[DetectionEvent]]) -> None:
    for e in events:
        out.setdefault(e.head, []).append(e)


@CASE
@given(log=logs(), data=st.data())
def test_bank_gives_the_head_counters_events_for_any_split_of_the_records(
    log: tuple[list[Head], list[tuple[int, int, int, int]], CountingSettings], data: st.DataObject
) -> None:
    heads, records, s = log
    n = len(records)
    cuts = data.draw(st.lists(st.integers(0, n), max_size=n + 1), label="cuts")
    bounds = sorted({0, n, *cuts})
    counters = [
        HeadCounter(
            f"WS{k}",
            up_is_sys1_first=h.up_is_sys1_first,
            settings=s,
            point_mode=h.point_mode,
            whole_second=h.whole_second,
        )
        for k, h in enumerate(heads)
    ]
    bank = _bank(heads, s)
    expected: dict[str, list[DetectionEvent]] = {}
    got: dict[str, list[DetectionEvent]] = {}
    for lo, hi in itertools.pairwise(bounds):
        block = records[lo:hi]
        for k, c, t, v in block:
            _by_head(counters[k].feed(c, t, v), expected)
        rows = sorted(range(len(block)), key=lambda i: block[i][0])  # by head, read order kept
        a = np.array([block[i] for i in rows], np.int64).reshape(-1, 4)
        _by_head(bank.feed(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).events(), got)
        if hi < n and data.draw(st.booleans(), label="advance"):
            # Time passes up to (at most) the next record, as the event stream's watermark does.
            until = records[hi][2] - data.draw(st.sampled_from([0, 1, NS, 100 * NS]), label="short of it")
            for hc in counters:
                _by_head(hc.advance(until), expected)
            _by_head(bank.advance({k: until for k in range(len(heads))}).events(), got)
    for hc in counters:
        _by_head(hc.flush(), expected)
    _by_head(bank.flush().events(), got)
    assert got == expected


@CASE
@given(log=logs(), data=st.data())
def test_settling_what_time_alone_settles_keeps_the_batch_order_and_nothing_comes_earlier_later(
    log: tuple[list[Head], list[tuple[int, int, int, int]], CountingSettings], data: st.DataObject
) -> None:
    # The event stream's release: between blocks, settle_before(the next record's time or earlier).
    # Per head, the events sorted by time (stably) are those of the records fed one by one with
    # nothing in between (the batch path), and nothing made afterwards is earlier than that time
    # (or than the bank's floor: a hold that falls due before its pulse ends).
    heads, records, s = log
    n = len(records)
    bounds = sorted({0, n, *data.draw(st.lists(st.integers(0, n), max_size=n + 1), label="cuts")})
    counters = [
        HeadCounter(
            f"WS{k}",
            up_is_sys1_first=h.up_is_sys1_first,
            settings=s,
            point_mode=h.point_mode,
            whole_second=h.whole_second,
        )
        for k, h in enumerate(heads)
    ]
    bank = _bank(heads, s)
    expected: dict[str, list[DetectionEvent]] = {}
    got: dict[str, list[DetectionEvent]] = {}
    settled = -(2**63)  # the latest time settled before

    def take(events: list[DetectionEvent]) -> None:
        assert all(e.time_ns >= settled for e in events)
        _by_head(events, got)

    for lo, hi in itertools.pairwise(bounds):
        block = records[lo:hi]
        for k, c, t, v in block:
            _by_head(counters[k].feed(c, t, v), expected)
        rows = sorted(range(len(block)), key=lambda i: block[i][0])
        a = np.array([block[i] for i in rows], np.int64).reshape(-1, 4)
        take(bank.feed(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).events())
        if hi < n and data.draw(st.booleans(), label="settle"):
            until = records[hi][2] - data.draw(st.sampled_from([0, 1, NS, 100 * NS]), label="short of it")
            passed = bank.settle_before(until).events()
            assert all(e.time_ns < until for e in passed)
            take(passed)
            settled = max(settled, min(until, bank.floor_ns()))
    for hc in counters:
        _by_head(hc.flush(), expected)
    take(bank.flush().events())
    assert {h: sorted(v, key=lambda e: e.time_ns) for h, v in got.items()} == {
        h: sorted(v, key=lambda e: e.time_ns) for h, v in expected.items()
    }


def test_a_block_of_plain_wheels_makes_no_lone_pulse_and_no_rare_state() -> None:
    # Two heads, ten wheels each, both systems overlapping: axles only, nothing held or waiting.
    rows = []
    for k in range(2):
        for w in range(10):
            t = w * 2 * NS
            rows += [(k, 1, t, 1), (k, 2, t + 5 * MS, 1), (k, 1, t + 40 * MS, 0), (k, 2, t + 45 * MS, 0)]
    a = np.array(rows, np.int64)
    bank = _bank([Head(True, False, False), Head(False, False, False)], CountingSettings())
    events = bank.feed(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).events()
    axles = [e for e in events if e.kind is EventKind.AXLE]
    assert [e.direction for e in axles] == [1] * 10 + [-1] * 10
    assert len(events) == 20 * 3  # head damped, axle, head free per wheel
    assert not bank.pending and not bank.holds
    assert bank.flush().events() == []


# --- the batch path: every head at once equals the loop over heads it replaced -------------


def _per_head_reference(analysis: DiagAnalysis, layout: Layout, s: DiagEventSettings) -> list[DetectionEvent]:
    """The batch path before the bank: a HeadCounter per two-channel head, a record at a time."""
    events: list[DetectionEvent] = []
    wr = analysis.wheel_records
    for key, (device_id, name) in enumerate(analysis.heads):
        if not layout.has_head(name) or layout.head(name).device_id not in (None, device_id):
            continue
        head = layout.head(name)
        rows = wr[wr["head"] == key] if len(wr) else wr
        if len(rows):
            order = np.argsort(rows["time_ns"].to_numpy(np.int64), kind="stable")
            ch, t, v = (rows[c].to_numpy(np.int64)[order] for c in ("channel", "time_ns", "value"))
            hc = HeadCounter(
                name,
                up_is_sys1_first=head.up_is_first_channel_first,
                settings=s.counting,
                point_mode=not bool((v == 0).any()),
                whole_second=not bool(rows["subsecond"].all()),
            )
            own = [e for c, tt, vv in zip(ch.tolist(), t.tolist(), v.tolist(), strict=True) for e in hc.feed(c, tt, vv)]
            events += sorted(own + hc.flush(), key=lambda e: e.time_ns)
        if s.power_gap_s is not None and len(analysis.activity):
            act = analysis.activity[analysis.activity["head"] == key].sort_values("t_first_ns", kind="stable")
            first, last = act["t_first_ns"].to_numpy(), act["t_last_ns"].to_numpy()
            gap = first[1:] - last[:-1]
            gap_ns = int(s.power_gap_s * NS)
            detail = f"no records for {s.power_gap_s:.0f} s"  # what is known when the loss is told
            for i in np.flatnonzero(gap > gap_ns).tolist():
                lost = int(last[i]) + gap_ns
                events.append(DetectionEvent(lost, EventKind.POWER_LOSS, name, 0, None, "diag", detail))
                events.append(DetectionEvent(int(first[i + 1]), EventKind.POWER_RESTORED, name, 0, None, "diag"))
            # Silent at the end, while the log ran on past the gap and the order slack: lost, never back.
            if len(last) and int(analysis.activity["t_last_ns"].max()) - int(ORDER_SLACK_S * NS) > last[-1] + gap_ns:
                events.append(
                    DetectionEvent(int(last[-1]) + gap_ns, EventKind.POWER_LOSS, name, 0, None, "diag", detail)
                )
    return sort_events(events)


@pytest.fixture(scope="module")
def faulty_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Layout]:
    faults = (
        Fault("missed_detections", "WS3", 150.0, 500.0, channel=2, probability=0.3),
        Fault("isolated_pulse", "WS2", 250.0),
        Fault("power_loss", "WS5", 350.0, 420.0),
        Fault("damped_head", "WS4", 780.0, 820.0),
    )
    sim = StationSim(load_layout("example"), SimConfig(seed=5, trains_per_hour=30, faults=faults))
    sim.run(900)
    path = tmp_path_factory.mktemp("faulty") / "sim.log"
    heads = [h.id for h in sim.layout.heads]
    write_diagnostic(sim, path, resolution={h: ("us", "ms", "s")[i % 3] for i, h in enumerate(heads)})
    return path, sim.layout


@pytest.mark.parametrize("power_gap", [None, 5.0])
@pytest.mark.parametrize("isolation", [5.0, 60.0])
def test_the_batch_path_gives_the_per_head_loops_events(
    faulty_log: tuple[Path, Layout], power_gap: float | None, isolation: float
) -> None:
    path, layout = faulty_log
    s = DiagEventSettings(counting=CountingSettings(isolation_s=isolation), power_gap_s=power_gap)
    job = whole_job([path], SpeedSettings(), keep_releases=True)
    events, _ = diag_detection_events(job.analysis, layout, s)
    assert events == _per_head_reference(job.analysis, layout, s)
    assert {e.kind for e in events} >= {EventKind.AXLE, EventKind.SINGLE_CHANNEL, EventKind.INTERFERENCE}


def _columns(blocks: list[EventBlock]) -> dict[str, list[int]]:
    return {c: [int(x) for b in blocks for x in b.column(c)] for c in COLUMNS}


@CASE
@given(log=logs(), data=st.data())
def test_time_passing_a_slice_of_heads_at_a_time_gives_the_events_of_all_at_once(
    log: tuple[list[Head], list[tuple[int, int, int, int]], CountingSettings], data: st.DataObject
) -> None:
    # The log's end settles a million heads' waiting onsets and holds a slice of heads at a time (for
    # memory): the blocks joined are the events of all heads at once, column for column and in order, and
    # the rows left waiting or held are the same, whatever the slice's size.
    heads, records, s = log
    bank = _bank(heads, s)
    n = len(records)
    cut = data.draw(st.integers(0, n), label="fed before time passes")
    for block in (records[:cut], records[cut:]):
        rows = sorted(range(len(block)), key=lambda i: block[i][0])  # by head, read order kept
        a = np.array([block[i] for i in rows], np.int64).reshape(-1, 4)
        bank.feed(a[:, 0], a[:, 1], a[:, 2], a[:, 3])
        # Time passes to some time per head (NONE: not this head), short of its records' end or past it.
        late = data.draw(st.lists(st.sampled_from([NONE, 0, NS, 30 * NS, 100 * NS, 10_000 * NS]), min_size=4))
        times = np.array([late[k % len(late)] for k in range(len(heads))], np.int64)
        strict = data.draw(st.booleans(), label="strict")
        size = data.draw(st.integers(1, 4), label="slice rows")
        whole, sliced = copy.deepcopy(bank), copy.deepcopy(bank)
        expected = [pass_time(whole, lambda h, times=times: times[h], strict)]
        got = list(pass_time_slices(sliced, lambda h, times=times: times[h], strict, size))
        assert _columns(got) == _columns(expected)
        for table in ("pending", "holds"):
            left, want = getattr(sliced, table).cols, getattr(whole, table).cols
            assert {c: v.tolist() for c, v in left.items()} == {c: v.tolist() for c, v in want.items()}
        assert sliced.hold_ids == whole.hold_ids
        bank = sliced
    size = data.draw(st.integers(1, 4), label="slice rows at the end")
    whole = copy.deepcopy(bank)
    assert _columns(list(bank.flush_blocks(size))) == _columns([whole.flush()])
    assert not len(bank.pending) and not len(bank.holds)
