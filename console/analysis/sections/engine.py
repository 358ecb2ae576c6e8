"""Section states from detection events: the axle counter's safety logic.

States:

* ``clear`` — counts balance (in = out) and nothing is in doubt;
* ``occupied`` — axles counted in and not yet out; or a bounding head
  damped right now (as a real counting head reports occupation the moment
  it is damped, before the axle is confirmed); or held by a suspected
  interference pulse (seed 002's soft timing) until it is confirmed
  accidental;
* ``disturbed`` — the count cannot be trusted: count underflow (more out
  than in), a power or communication loss at a bounding head, a channel
  fault, an axle of unknown direction, a single-system damping next to
  other activity (a possibly missed axle), or the channels disagreeing.
  Disturbed is latched: only an accepted reset leaves it;
* ``preparatory`` — after an accepted reset (or at the start of a log,
  when the state is unknown), until a sweep train has run in and out with
  balanced counts (seed 003: "reset only after it is confirmed really
  clear").

Fail-safe: the engine never moves to ``clear`` except from a balanced count
with no doubt active, and nothing moves a disturbed section except a reset
whose preconditions hold: no bounding head damped, no channel fault, no
power loss at a bounding head.  A refused reset is recorded with why.

The engine is a pure state machine: :meth:`SectionEngine.step` takes one
event and returns what changed; the same code runs over a parsed log, in the
simulator and behind the live view.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from console.analysis.events.detection import UNKNOWN, DetectionEvent, EventKind, sort_events
from console.analysis.sections.block import step_block
from console.analysis.sections.state import EngineSection, LedgerEntry, ResetRecord, SectionState, Transition
from console.layout import Layout

if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.events.block import EventBlock


_UNHEARD = "no record of "


def unheard_mark(head: str) -> str:
    """A section's hold while ``head``, one of its bounds, has not been heard (no event of it yet)."""
    return f"{_UNHEARD}{head} yet"


class SectionEngine:
    """The section state machine over a layout.  Feed it events with :meth:`step`."""

    def __init__(self, layout: Layout, *, initial: SectionState = SectionState.PREPARATORY, start_ns: int = 0) -> None:
        if initial not in (SectionState.CLEAR, SectionState.PREPARATORY):
            raise ValueError("a section starts clear (a known empty line) or preparatory (unknown)")
        self.layout = layout
        reason = "start: line known empty" if initial is SectionState.CLEAR else "start: state unknown until a sweep"
        self.sections = {s.id: EngineSection(s, initial, reason=reason, since_ns=start_ns) for s in layout.sections}
        # Heads not heard yet (no event of theirs): a section they bound holds, never clear on the count of its
        # other heads alone (a head absent from the log, or its records not counted, counts no axle in or out).
        self.unheard: set[str] = {h for s in layout.sections for h in s.heads}
        # The latest event time stepped: doubt told late (a clock step read after records stamped later than
        # it, as a followed file gives it) is stamped then, so the timeline never goes back in time.
        self.now_ns = start_ns
        for s in self.sections.values():
            s.held_by.update(unheard_mark(h) for h in s.section.heads)
        self.damped: set[str] = set()  # heads with something over them now
        self.faults: dict[str, set[int | None]] = {}  # head → faulty channels (None: whole head)
        self.powerless: set[str] = set()
        self.transitions: list[Transition] = [Transition(start_ns, s.id, initial, 0, reason) for s in layout.sections]
        self.ledger: list[LedgerEntry] = []
        self.resets: list[ResetRecord] = []
        self._bound: dict[str, list[tuple[EngineSection, int]]] = {}  # head → the sections it bounds, with signs

    # -- queries --------------------------------------------------------
    def state(self, section_id: str) -> SectionState:
        return self.sections[section_id].state

    def count(self, section_id: str) -> int:
        return self.sections[section_id].count

    def reset_refusal(self, section_id: str) -> str | None:
        """Why a reset of this section would be refused now, or None."""
        sec = self.sections[section_id].section
        damped = [h for h in sec.heads if h in self.damped]
        if damped:
            return f"head {', '.join(damped)} is damped (something is over it)"
        faulty = [h for h in sec.heads if self.faults.get(h)]
        if faulty:
            return f"channel fault at {', '.join(faulty)}"
        dark = [h for h in sec.heads if h in self.powerless]
        if dark:
            return f"no power or contact at {', '.join(dark)}"
        return None

    # -- the state machine ----------------------------------------------
    def _set(self, s: EngineSection, state: SectionState, t: int, reason: str, note: bool = False) -> Transition | None:
        """Change state.  Counts go to the ledger; the timeline keeps state changes, and
        (``note``) a new reason for the same state, such as a hold beginning."""
        if state is s.state and (not note or reason == s.reason):
            return None
        s.state, s.reason, s.since_ns = state, reason, t
        tr = Transition(t, s.section.id, state, s.count, reason)
        self.transitions.append(tr)
        return tr

    def _disturb(self, s: EngineSection, t: int, reason: str) -> Transition | None:
        if s.state is SectionState.DISTURBED:
            return None  # latched: keep the first reason
        return self._set(s, SectionState.DISTURBED, t, reason)

    def _settle(self, s: EngineSection, t: int, reason: str) -> Transition | None:
        """After a count change or a lifted hold: the state the count allows."""
        if s.state is SectionState.DISTURBED:
            return None
        if s.count < 0:
            return self._disturb(s, t, f"count underflow ({s.count}): more axles out than in")
        if s.state is SectionState.PREPARATORY:
            if s.count > 0:
                s.swept_in = True
                return None
            if s.swept_in and not s.held_by:
                s.swept_in = False
                return self._set(s, SectionState.CLEAR, t, "sweep train in and out: counts balance")
            waiting = sorted(h for h in s.held_by if h.startswith(_UNHEARD))
            if s.swept_in and waiting:  # a sweep that would have cleared it but for a head not heard: said
                why = f"sweep train in and out, held: {', '.join(waiting)}"
                return self._set(s, SectionState.PREPARATORY, t, why, note=True)
            return None
        if s.count > 0:
            return self._set(s, SectionState.OCCUPIED, t, reason)
        if s.held_by:
            what = sorted(s.held_by)
            unheard = any(h.startswith(_UNHEARD) for h in what)
            why = (
                f"held: {', '.join(what)}"
                if unheard or any("damped" in h for h in what)
                else f"held: isolated pulse at {', '.join(what)}"
            )
            # Counts balanced, and only a head not heard yet keeps it from clear: said in the timeline.
            return self._set(s, SectionState.OCCUPIED, t, why, note=unheard)
        return self._set(s, SectionState.CLEAR, t, "counts balance")

    def step(self, e: DetectionEvent) -> list[Transition]:
        """Apply one event; returns the state changes it caused."""
        out: list[Transition | None] = []
        t = e.time_ns
        if e.kind is EventKind.CLOCK_STEP and t < self.now_ns:
            t = self.now_ns  # read after later records (a followed file): doubt from when it was read
        self.now_ns = max(self.now_ns, t)
        if e.kind is EventKind.RESET:
            out.append(self._reset(e))
            return [x for x in out if x is not None]
        secs = self.bound(e.head)
        if e.head in self.unheard:
            self.unheard.discard(e.head)
            for s, _ in secs:
                s.held_by.discard(unheard_mark(e.head))
        k = e.kind
        if k is EventKind.AXLE:
            for s, sign in secs:
                if e.direction == UNKNOWN:
                    out.append(self._disturb(s, t, f"axle of unknown direction at {e.head}"))
                    continue
                delta = sign * e.direction
                s.count += delta
                if delta > 0:
                    s.count_in += 1
                else:
                    s.count_out += 1
                self.ledger.append(LedgerEntry(t, s.section.id, e.head, delta, s.count))
                out.append(self._settle(s, t, f"axles counted in: {s.count}"))
        elif k is EventKind.SINGLE_CHANNEL:
            for s, _ in secs:
                what = f"Sys{e.channel}" if e.channel else "one system"
                out.append(self._disturb(s, t, f"{what} only at {e.head}: possibly a missed axle"))
        elif k is EventKind.COUNT_ERROR:
            for s, _ in secs:
                out.append(self._disturb(s, t, f"count error at {e.head}: {e.detail or 'channels disagree'}"))
        elif k is EventKind.CHANNEL_FAULT:
            self.faults.setdefault(e.head, set()).add(e.channel)
            for s, _ in secs:
                ch = "whole head" if e.channel is None else f"channel {e.channel}"
                out.append(self._disturb(s, t, f"{ch} faulty at {e.head}"))
        elif k is EventKind.CHANNEL_OK:
            self.faults.get(e.head, set()).discard(e.channel)
        elif k is EventKind.POWER_LOSS:
            self.powerless.add(e.head)
            for s, _ in secs:
                out.append(
                    self._disturb(s, t, f"power or contact lost at {e.head}" + (f": {e.detail}" if e.detail else ""))
                )
        elif k is EventKind.CLOCK_STEP:
            for s, _ in secs:
                out.append(
                    self._disturb(s, t, f"records of {e.head} went back in time: counts after it may be out of order")
                )
        elif k is EventKind.POWER_RESTORED:
            self.powerless.discard(e.head)  # the sections stay disturbed until a reset
        elif k is EventKind.HEAD_DAMPED:
            # As a real counting head does: occupied the moment it is damped,
            # before the axle is (or is not) confirmed.
            self.damped.add(e.head)
            for s, _ in secs:
                s.held_by.add(f"{e.head} damped")
                if s.state is SectionState.CLEAR:
                    out.append(self._set(s, SectionState.OCCUPIED, t, f"head {e.head} damped"))
        elif k is EventKind.HEAD_FREE:
            self.damped.discard(e.head)
            for s, _ in secs:
                s.held_by.discard(f"{e.head} damped")
                out.append(self._settle(s, t, f"axles counted in: {s.count}"))
        elif k is EventKind.INTERFERENCE:
            for s, _ in secs:
                s.held_by.add(e.head)
                if s.state in (SectionState.CLEAR, SectionState.OCCUPIED):
                    why = f"held: isolated pulse at {e.head}"
                    out.append(self._set(s, SectionState.OCCUPIED, t, why, note=s.count == 0))
        elif k is EventKind.ACCIDENTAL:
            for s, _ in secs:
                s.held_by.discard(e.head)
                out.append(self._settle(s, t, f"axles counted in: {s.count}"))
        return [x for x in out if x is not None]

    def bound(self, head: str) -> list[tuple[EngineSection, int]]:
        """The sections ``head`` bounds, with their signs (looked up once per head: the layout is fixed)."""
        secs = self._bound.get(head)
        if secs is None:
            bound = self.layout.sections_of(head) if self.layout.has_head(head) else []
            secs = self._bound[head] = [(self.sections[sec.id], sign) for sec, sign in bound]
        return secs

    def step_block(self, block: EventBlock) -> None:
        """Apply a block of events in order: :meth:`step` on each, the quiet ones as array bookkeeping
        (:func:`console.analysis.sections.block.step_block`)."""
        step_block(self, block)

    def _reset(self, e: DetectionEvent) -> Transition | None:
        sid = e.head
        if sid not in self.sections:
            self.resets.append(ResetRecord(e.time_ns, sid, False, f"no section {sid!r} in the layout"))
            return None
        why = self.reset_refusal(sid)
        if why is not None:
            self.resets.append(ResetRecord(e.time_ns, sid, False, why))
            return None
        s = self.sections[sid]
        s.count, s.swept_in = 0, False
        s.held_by = {h for h in s.held_by if h.endswith("damped") or h.startswith(_UNHEARD)}
        self.resets.append(ResetRecord(e.time_ns, sid, True, "preconditions hold: waiting for a sweep train"))
        return self._set(s, SectionState.PREPARATORY, e.time_ns, "reset accepted: waiting for a sweep train")

    def take_history(self) -> tuple[list[Transition], list[LedgerEntry], list[ResetRecord]]:
        """The state changes, ledger rows and reset records made since the last call, moved out of the engine."""
        out = (self.transitions, self.ledger, self.resets)
        self.transitions, self.ledger, self.resets = [], [], []
        return out

    def run(self, events: Iterable[DetectionEvent]) -> SectionsResult:
        for e in sort_events(events):
            self.step(e)
        return self.result()

    def result(
        self,
        transitions: list[Transition] | None = None,
        ledger: list[LedgerEntry] | None = None,
        resets: list[ResetRecord] | None = None,
    ) -> SectionsResult:
        """The run so far; the history given (drained out of the engine as it ran) or the engine's own."""
        import pandas as pd

        trs = self.transitions if transitions is None else transitions
        led = self.ledger if ledger is None else ledger
        rst = self.resets if resets is None else resets
        return SectionsResult(
            timeline=pd.DataFrame(
                [(t.time_ns, t.section, str(t.state), t.count, t.reason) for t in trs],
                columns=["time_ns", "section", "state", "count", "reason"],
            ),
            ledger=pd.DataFrame(
                [(x.time_ns, x.section, x.head, x.delta, x.count) for x in led],
                columns=["time_ns", "section", "head", "delta", "count"],
            ),
            resets=pd.DataFrame(
                [(r.time_ns, r.section, r.accepted, r.reason) for r in rst],
                columns=["time_ns", "section", "accepted", "reason"],
            ),
            final=self.final_states(),
        )

    def final_states(self) -> dict[str, tuple[str, int, int, int, str]]:
        """Each section's state now: section → (state, count, counted in, counted out, reason)."""
        return {sid: (str(s.state), s.count, s.count_in, s.count_out, s.reason) for sid, s in self.sections.items()}


@dataclass
class SectionsResult:
    timeline: pd.DataFrame  # every state change: time_ns, section, state, count, reason
    ledger: pd.DataFrame  # every axle counted: time_ns, section, head, delta, count
    resets: pd.DataFrame  # every reset request: accepted or refused, and why
    final: dict[str, tuple[str, int, int, int, str]]  # section → (state, count, in, out, reason)
    # The ledger summary when the ledger itself was not kept (a streamed run: console.stream_jobs).
    summary: pd.DataFrame | None = None

    def ledger_summary(self) -> pd.DataFrame:
        """Per section and head: axles counted in and out, first and last (section, head order)."""
        import pandas as pd

        cols = ["section", "head", "count_in", "count_out", "first_ns", "last_ns"]
        if self.summary is not None:
            return self.summary
        led = self.ledger
        if led.empty:
            return pd.DataFrame(columns=cols)
        delta = led["delta"]
        keyed = pd.DataFrame(
            {
                "section": led["section"].astype(str),
                "head": led["head"].astype(str),
                "count_in": (delta > 0).astype("int64"),
                "count_out": (delta < 0).astype("int64"),
                "time_ns": led["time_ns"].astype("int64"),
            }
        )
        g = keyed.groupby(["section", "head"], sort=True)
        out = g[["count_in", "count_out"]].sum()
        out["first_ns"] = g["time_ns"].min()
        out["last_ns"] = g["time_ns"].max()
        return out.reset_index()[cols]


def ledger_summary_frame(totals: dict[tuple[str, str], list[int]]) -> pd.DataFrame:
    """:meth:`SectionsResult.ledger_summary` from running totals: (section, head) → [in, out, first, last]."""
    import pandas as pd

    cols = ["section", "head", "count_in", "count_out", "first_ns", "last_ns"]
    rows = [(s, h, *v) for (s, h), v in sorted(totals.items())]
    frame = pd.DataFrame(rows, columns=cols)
    return frame.astype({c: "int64" for c in cols[2:]})


def run_sections(
    layout: Layout, events: Iterable[DetectionEvent], *, initial: SectionState = SectionState.PREPARATORY
) -> SectionsResult:
    """Run the section engine over a whole event stream (batch)."""
    ev = sort_events(events)
    return SectionEngine(layout, initial=initial, start_ns=ev[0].time_ns if ev else 0).run(ev)
