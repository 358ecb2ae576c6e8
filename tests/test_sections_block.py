"""The section engine fed a block at a time is the engine stepped event by event.

:meth:`SectionEngine.step_block` does the bookkeeping of quiet events
(axles into sections that stay occupied, heads damped beside them,
anything at a disturbed section) with array operations and steps the
others one by one.  Over random event streams on the example layout (every
event kind, heads bounding two sections and heads bounding none, operator
resets, sections that start clear or preparatory), cut into blocks
anywhere, the engine's whole state must equal the one stepped event by
event: timeline, ledger, resets, each section's state, count, reason, holds
and sweep, and the heads damped, faulty and dark.
"""

from __future__ import annotations

import itertools
import os

from hypothesis import given, settings
from hypothesis import strategies as st

from console.analysis.events.block import EventBlock, StringPool
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState
from console.layout import load_layout

LAYOUT = load_layout("example")
HEADS = [h.id for h in LAYOUT.heads] + ["WS9"]  # WS9: in no section
SECTIONS = [s.id for s in LAYOUT.sections]
LONG = bool(os.environ.get("TRACKSIDE_LONG"))

# Mostly what a train makes (axles, heads damped and freed), the rest now and then.
KINDS = [EventKind.AXLE] * 8 + [EventKind.HEAD_DAMPED, EventKind.HEAD_FREE] * 3 + list(EventKind)


@st.composite
def streams(draw: st.DrawFn) -> list[DetectionEvent]:
    out: list[DetectionEvent] = []
    t = 0
    for _ in range(draw(st.integers(0, 120))):
        t += draw(st.sampled_from([0, 0, 1, 10, 1000]))
        kind = draw(st.sampled_from(KINDS))
        if kind is EventKind.RESET:
            out.append(DetectionEvent(t, kind, draw(st.sampled_from([*SECTIONS, "X"])), source="operator"))
            continue
        direction = draw(st.sampled_from([1, 1, -1, -1, 0])) if kind is EventKind.AXLE else 0
        channel = draw(st.sampled_from([None, 1, 2]))
        out.append(DetectionEvent(t, kind, draw(st.sampled_from(HEADS)), direction, channel, "diag", "d"))
    return out


def _state(engine: SectionEngine) -> object:
    secs = {
        sid: (s.state, s.count, s.count_in, s.count_out, s.reason, s.since_ns, sorted(s.held_by), s.swept_in)
        for sid, s in engine.sections.items()
    }
    faults = {h: sorted(c, key=str) for h, c in engine.faults.items()}
    damped, unheard = sorted(engine.damped), sorted(engine.unheard)
    heads = (damped, unheard, faults, engine.powerless)
    return (engine.transitions, engine.ledger, engine.resets, secs, heads, engine.now_ns)


@settings(max_examples=2000 if LONG else 200, deadline=None)
@given(
    events=streams(),
    initial=st.sampled_from([SectionState.PREPARATORY, SectionState.CLEAR]),
    data=st.data(),
)
def test_blocks_of_events_leave_the_engine_as_stepping_each_event_does(
    events: list[DetectionEvent], initial: SectionState, data: st.DataObject
) -> None:
    one = SectionEngine(LAYOUT, initial=initial)
    for e in events:
        one.step(e)
    blocks = SectionEngine(LAYOUT, initial=initial)
    names = list(HEADS)
    pool = StringPool()
    n = len(events)
    cuts = sorted({0, n, *data.draw(st.lists(st.integers(0, n), max_size=6), label="cuts")})
    for lo, hi in itertools.pairwise(cuts):
        # Heads as keys into the names (as the event stream gives them), resets by pooled name.
        part = events[lo:hi]
        block = EventBlock.from_events(part, names, pool)
        keys = [
            names.index(e.head) if e.kind is not EventKind.RESET else h for e, h in zip(part, block.head, strict=True)
        ]
        block.head[:] = keys
        blocks.step_block(block)
    assert _state(blocks) == _state(one)


def test_a_train_through_an_occupied_section_is_counted_in_bulk_without_a_state_change() -> None:
    # 1G already holds 2 axles: 6 more in at WS1, then 8 out at WS2; only the last one clears it.
    engine = SectionEngine(LAYOUT, initial=SectionState.CLEAR)
    start = [DetectionEvent(0, EventKind.AXLE, "WS1", 1), DetectionEvent(1, EventKind.AXLE, "WS1", 1)]
    for e in start:
        engine.step(e)
    train = [DetectionEvent(10 + i, EventKind.AXLE, "WS1", 1) for i in range(6)]
    train += [DetectionEvent(100 + i, EventKind.AXLE, "WS2", 1) for i in range(8)]
    before = len(engine.transitions)
    names = list(HEADS)
    block = EventBlock.from_events(train, names, StringPool())
    block.head[:] = [names.index(e.head) for e in train]
    engine.step_block(block)
    assert engine.count("1G") == 0 and engine.state("1G") is SectionState.CLEAR
    # WS2 also bounds B1 (sign +1): the train runs on into it.
    assert [(t.section, t.state) for t in engine.transitions[before:]] == [
        ("B1", SectionState.OCCUPIED),
        ("1G", SectionState.CLEAR),
    ]
    assert [x.count for x in engine.ledger if x.section == "1G"][-3:] == [2, 1, 0]
