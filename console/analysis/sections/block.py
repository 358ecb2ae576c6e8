"""A block of events through the section engine at once: exactly :meth:`SectionEngine.step` per event.

Most events change no state: an axle counted into or out of a section that
stays occupied (its count above zero before and after), a head damped or
freed beside such a section, anything at a section already disturbed
(latched).  Those do only bookkeeping: the count (a running sum per
section, which no state changes), the ledger row, the heads damped and the
holds they put on their sections, the sweep train seen entering a
preparatory section.  :func:`step_block` does that bookkeeping for every
run of such events with array operations and steps only the others (a
count reaching zero or below, a section clear, a lone pulse, a fault, a
reset) one by one through :meth:`SectionEngine.step`, so each of those
sees the state it would have seen (``tests/test_sections_block.py``).

Which events are quiet is decided once per block from the counts and the
sections disturbed when it begins; a section disturbed within the block
only makes its later events stepped one by one (still exact), and a reset
(the only way out of disturbed) splits the block.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from console.analysis.events.block import KIND_CODE, EventBlock
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.sections.state import EngineSection, LedgerEntry, SectionState, Transition

_AXLE, _DAMPED, _FREE, _RESET = (
    KIND_CODE[k] for k in (EventKind.AXLE, EventKind.HEAD_DAMPED, EventKind.HEAD_FREE, EventKind.RESET)
)


class SteppedEngine(Protocol):
    """What a block's run reads and changes of :class:`~console.analysis.sections.engine.SectionEngine`."""

    sections: dict[str, EngineSection]
    damped: set[str]  # heads with something over them now
    unheard: set[str]  # heads with no event yet: their sections hold
    now_ns: int  # the latest event time stepped
    ledger: list[LedgerEntry]

    def step(self, e: DetectionEvent) -> list[Transition]: ...
    def bound(self, head: str) -> list[tuple[EngineSection, int]]: ...


def step_block(engine: SteppedEngine, block: EventBlock) -> None:
    """Apply a block of events in order, as ``engine.step`` on each would."""
    lo = 0
    n = len(block)
    for r in [*np.flatnonzero(block.kind == _RESET).tolist(), n]:  # per operator reset: rare
        if lo < r:
            _segment(engine, block, lo, r)
        if r < n:
            engine.step(block.event(r))
        lo = r + 1


def _segment(engine: SteppedEngine, block: EventBlock, lo: int, hi: int) -> None:
    """Events lo … hi - 1, none of them a reset."""
    kind = block.kind[lo:hi]
    direction = block.direction[lo:hi].astype(np.int64)
    time_ns = block.time_ns[lo:hi]
    codes, head = np.unique(block.head[lo:hi], return_inverse=True)
    head = head.reshape(-1)
    names = [block.head_name(c) for c in codes.tolist()]
    sections = list(engine.sections.values())
    index = {id(s): i for i, s in enumerate(sections)}
    # Per head of the block, the sections it bounds (in the engine's order for it), as rows.
    inc_head: list[int] = []
    inc_sec: list[int] = []
    inc_sign: list[int] = []
    for u, name in enumerate(names):  # per head of the block
        for s, sign in engine.bound(name):
            inc_head.append(u)
            inc_sec.append(index[id(s)])
            inc_sign.append(sign)
    per_head = np.bincount(np.array(inc_head, np.int64), minlength=len(names))
    first_row = np.r_[0, np.cumsum(per_head)[:-1]] if len(names) else np.zeros(0, np.int64)
    sec_of, sign_of = np.array(inc_sec, np.int64), np.array(inc_sign, np.int64)

    # Every (event, section it touches) pair, in event order, then the head's section order.
    reps = per_head[head]
    ev = np.repeat(np.arange(len(kind)), reps)
    inc = np.repeat(first_row[head] - np.r_[0, np.cumsum(reps)[:-1]], reps) + np.arange(len(ev))
    sec = sec_of[inc]
    counted = (kind[ev] == _AXLE) & (direction[ev] != 0)
    delta = np.where(counted, sign_of[inc] * direction[ev], 0)
    start = np.array([s.count for s in sections], np.int64)
    by_sec = np.argsort(sec, kind="stable")
    after = np.empty(len(ev), np.int64)
    running = np.cumsum(delta[by_sec])
    first_of_sec = np.r_[True, sec[by_sec][1:] != sec[by_sec][:-1]] if len(ev) else np.zeros(0, bool)
    base = np.maximum.accumulate(np.where(first_of_sec, np.arange(len(ev)), 0)) if len(ev) else running
    before_run = (running - delta[by_sec])[base]
    after[by_sec] = start[sec[by_sec]] + running - before_run
    before = after - delta

    disturbed = np.array([s.state is SectionState.DISTURBED for s in sections], bool)
    pair_ok = disturbed[sec] | ((before > 0) & (after > 0))
    quiet_kind = ((kind == _AXLE) & (direction != 0)) | (kind == _DAMPED) | (kind == _FREE)
    bad_pairs = np.bincount(ev[~pair_ok], minlength=len(kind)) if len(ev) else np.zeros(len(kind), np.int64)
    # A head's first event, while it is not heard yet, lifts its sections' hold: stepped one by one.
    heard_now = np.zeros(len(kind), bool)
    if engine.unheard:  # until every head bounding a section is heard (the start of a log)
        first_of_head = np.unique(head, return_index=True)[1]
        heard_now[first_of_head] = [names[int(head[i])] in engine.unheard for i in first_of_head.tolist()]
    loud = np.flatnonzero(~quiet_kind | (bad_pairs > 0) | heard_now)

    ctx = _Context(engine, block, lo, sections, names, head, kind, time_ns, ev, sec, delta, after, counted)
    prev = 0
    for c in [*loud.tolist(), len(kind)]:  # per event that may change a state
        if prev < c:
            ctx.quiet(prev, c)
        if c < len(kind):
            engine.step(block.event(lo + c))
        prev = c + 1


class _Context:
    """One segment's arrays, and the bookkeeping of its quiet runs."""

    def __init__(
        self,
        engine: SteppedEngine,
        block: EventBlock,
        lo: int,
        sections: list[EngineSection],
        names: list[str],
        head: np.ndarray,
        kind: np.ndarray,
        time_ns: np.ndarray,
        ev: np.ndarray,
        sec: np.ndarray,
        delta: np.ndarray,
        after: np.ndarray,
        counted: np.ndarray,
    ) -> None:
        self.engine, self.block, self.lo = engine, block, lo
        self.sections, self.names = sections, names
        self.head, self.kind, self.time_ns = head, kind, time_ns
        self.ev, self.sec, self.delta, self.after, self.counted = ev, sec, delta, after, counted
        self.ids = [s.section.id for s in sections]

    def quiet(self, a: int, b: int) -> None:
        """Events a … b - 1, none of which changes a state: counts, ledger, damped heads, holds, sweeps."""
        engine = self.engine
        engine.now_ns = max(engine.now_ns, int(self.time_ns[a:b].max()))
        r0, r1 = np.searchsorted(self.ev, [a, b])
        ev, sec = self.ev[r0:r1], self.sec[r0:r1]
        counted = self.counted[r0:r1]
        if counted.any():
            rows = np.flatnonzero(counted)
            delta, after = self.delta[r0:r1][rows], self.after[r0:r1][rows]
            rsec, rev = sec[rows], ev[rows]
            ids, names = self.ids, self.names
            times, heads = self.time_ns[rev].tolist(), self.head[rev].tolist()
            engine.ledger += [
                LedgerEntry(t, ids[s], names[h], d, c)
                for t, s, h, d, c in zip(times, rsec.tolist(), heads, delta.tolist(), after.tolist(), strict=True)
            ]
            touched = np.unique(rsec)
            last = len(rsec) - 1 - np.unique(rsec[::-1], return_index=True)[1]
            n_in = np.bincount(rsec, weights=delta > 0, minlength=len(self.sections))
            for s_i, end in zip(touched.tolist(), last.tolist(), strict=True):  # per section counted
                s = self.sections[s_i]
                s.count = int(after[end])
                s.count_in += int(n_in[s_i])
                s.count_out += int(np.count_nonzero(rsec == s_i)) - int(n_in[s_i])
        kind = self.kind[ev]
        settles = counted | (kind == _FREE)
        for s_i in np.unique(sec[settles]).tolist():  # per section: a sweep train seen entering
            s = self.sections[s_i]
            if s.state is SectionState.PREPARATORY:
                s.swept_in = True
        self._damping(a, b, ev, sec, kind)

    def _damping(self, a: int, b: int, ev: np.ndarray, sec: np.ndarray, kind: np.ndarray) -> None:
        """HEAD_DAMPED / HEAD_FREE: the last of each head (and of each of its sections) wins."""
        k = self.kind[a:b]
        marks = np.flatnonzero((k == _DAMPED) | (k == _FREE))
        if not len(marks):
            return
        h = self.head[a:b][marks]
        last = len(h) - 1 - np.unique(h[::-1], return_index=True)[1]
        engine = self.engine
        for u, i in zip(np.unique(h).tolist(), last.tolist(), strict=True):  # per head damped or freed
            name = self.names[u]
            if k[marks[i]] == _DAMPED:
                engine.damped.add(name)
            else:
                engine.damped.discard(name)
        rows = np.flatnonzero((kind == _DAMPED) | (kind == _FREE))
        if not len(rows):
            return
        hs = self.head[ev[rows]]
        key = hs * len(self.sections) + sec[rows]
        last_row = rows[len(key) - 1 - np.unique(key[::-1], return_index=True)[1]]
        for r in last_row.tolist():  # per (section, head) damped or freed
            s = self.sections[int(sec[r])]
            mark = f"{self.names[int(self.head[ev[r]])]} damped"
            if kind[r] == _DAMPED:
                s.held_by.add(mark)
            else:
                s.held_by.discard(mark)
