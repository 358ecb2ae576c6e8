"""The counters' and the sections' witness of train integrity.

Once two head fixes place a train's head its length (and every allowance)
past a counting head, the axles counted there in its direction since the
head was surely before it must be the consist's, and the section it left at
that head must not stay occupied behind it.  :class:`CountsWitness` keeps
what the counting heads said (axles, their own doubt, section changes) and
gives an :class:`Opinion` per check; :mod:`console.analysis.integrity.monitor`
weighs it with the GNSS witness (:func:`console.analysis.integrity.verdict.fuse`).

A check runs only once the counters have reported past the time the train
should have cleared the head (so a log read after its telemetry is never
judged incomplete; on a quiet line the check waits for the counters' next
word), and reads the section's state as it was at that time.
"""

from __future__ import annotations

import math
from bisect import bisect_left, insort
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.sections.state import SectionState, Transition
from console.layout import Layout
from parsers.units import NS

AXLES, SECTIONS = "axles", "sections"
# What a counting head reports that makes its count unfit as evidence either way.
COUNTER_DOUBT = {
    EventKind.SINGLE_CHANNEL: "a single system damped (possibly a missed axle)",
    EventKind.COUNT_ERROR: "a count error",
    EventKind.CHANNEL_FAULT: "a channel fault",
    EventKind.POWER_LOSS: "a power or contact loss",
    EventKind.INTERFERENCE: "an isolated pulse",
    EventKind.CLOCK_STEP: "its records going back in time",
}


@dataclass(frozen=True)
class Opinion:
    """What one witness says of a train now."""

    # ok | doubt | separation (a doubt that points to a parting) | parted | none | unfit (the witness
    # cannot tell: its evidence is kept, it weighs nothing)
    level: str
    witnesses: tuple[str, ...] = ()
    evidence: tuple[str, ...] = ()
    t_ns: int = 0  # when it was formed (fix time for GNSS, check time for counters)


NONE = Opinion("none")


@dataclass
class HeadCheck:
    """The counters' check of one train at one counting head."""

    head: str
    chainage_m: float
    since_ns: int  # fix time of the last head fix surely before the counting head: its axles come after
    due_fixes: int = 0  # head fixes so far placing the whole train past the counting head
    due_ns: int | None = None  # when the second of them arrived (console time)
    until_ns: int | None = None  # its fix time: axles after this are late
    done: bool = False


class CountsWitness:
    """What the counting heads and the section engine said, and the checks they answer."""

    def __init__(
        self, layout: Layout | None, pos_allow_m: float, slack_m: float, counter_lag_s: float, history_s: float
    ) -> None:
        self.layout = layout
        self.pos_allow_m = pos_allow_m
        self.slack_m = slack_m
        self.lag_ns = int(counter_lag_s * NS)
        self.history_ns = int(history_s * NS)
        # The counters' clock: the latest axle, counter event or section change seen.
        self.counters_ns: int | None = None
        # Per counting head: (time, direction) of counted axles, and (time, why) of the counter's doubt;
        # per section, its state changes (time, state): each oldest first.
        self.axles: dict[str, deque[tuple[int, int]]] = {}
        self.counter_doubt: dict[str, deque[tuple[int, str]]] = {}
        self.section_states: dict[str, deque[tuple[int, SectionState]]] = {}
        heads = layout.heads if layout is not None else ()
        self.heads_sorted = sorted((h.chainage_m, h.id) for h in heads)
        head_m = {h.id: h.chainage_m for h in heads}
        self.extent: dict[str, tuple[float, float]] = {}
        if layout is not None:
            for sec in layout.sections:
                ch = [head_m[h] for h in sec.heads]
                self.extent[sec.id] = (min(ch), max(ch))

    # -- what the heads said ----------------------------------------------
    def detection(self, e: DetectionEvent) -> None:
        self._clock(e.time_ns)
        if e.kind is EventKind.AXLE and e.direction:
            self._keep(self.axles, e.head, (e.time_ns, e.direction))
        elif e.kind in COUNTER_DOUBT:
            self._keep(self.counter_doubt, e.head, (e.time_ns, COUNTER_DOUBT[e.kind]))

    def passage(self, head: str, t_first_ns: int, t_last_ns: int, axles: int, direction: int) -> None:
        self._clock(t_last_ns)
        if direction and axles > 0:
            step = (t_last_ns - t_first_ns) // max(1, axles - 1)
            for k in range(axles):
                self._keep(self.axles, head, (t_first_ns + k * step, direction))

    def transition(self, tr: Transition) -> None:
        self._clock(tr.time_ns)
        self._keep(self.section_states, tr.section, (tr.time_ns, tr.state))

    def _clock(self, t_ns: int) -> None:
        self.counters_ns = t_ns if self.counters_ns is None else max(self.counters_ns, t_ns)

    def _keep(self, store: dict[str, deque[Any]], key: str, item: tuple[int, Any]) -> None:
        q = store.setdefault(key, deque())
        if q and item[0] < q[-1][0]:
            items = list(q)
            insort(items, item)
            q.clear()
            q.extend(items)
        else:
            q.append(item)
        horizon = item[0] - self.history_ns
        while q and q[0][0] < horizon:
            q.popleft()

    # -- checks ----------------------------------------------------------------
    def open_checks(
        self,
        checks: dict[str, HeadCheck],
        times: list[int],
        chainage: list[float],
        d: int,
        length_m: float | None,
        now: int,
    ) -> None:
        """After a head fix (the last of ``times``/``chainage``): open a check at each counting head
        the head has surely passed; count the head fixes that make the open ones due."""
        if not d or not self.heads_sorted:
            return
        allow = self.pos_allow_m
        new_m, t_fix_ns = chainage[-1], times[-1]
        lo, hi = sorted((chainage[0], new_m))
        i = bisect_left(self.heads_sorted, (lo, ""))
        for ch, hid in self.heads_sorted[i:]:
            if ch > hi:
                break
            if hid in checks or d * (new_m - ch) <= allow:
                continue
            # The last fix surely before it: the train's axles at that head all come after it.
            before = [t for t, x in zip(times, chainage, strict=True) if d * (ch - x) > allow]
            if before:
                checks[hid] = HeadCheck(hid, ch, before[-1])
        if length_m is None:
            return  # not before the train's length is known: the check would come due too soon
        past = length_m + allow + self.slack_m
        for c in checks.values():
            if c.done or c.due_ns is not None:
                continue
            if d * (new_m - c.chainage_m) >= past:
                c.due_fixes += 1
                if c.due_fixes >= 2:  # two fixes, so that one jump cannot make it due early
                    c.due_ns, c.until_ns = now, t_fix_ns
            else:
                c.due_fixes = 0

    def ready(self, c: HeadCheck, now: int) -> bool:
        """Due, its delay allowance run out, and the counters have reported past the train's clearance."""
        if c.done or c.due_ns is None or c.until_ns is None or now < c.due_ns + self.lag_ns:
            return False
        return self.counters_ns is not None and self.counters_ns >= c.until_ns + self.lag_ns

    def judge(
        self,
        c: HeadCheck,
        d: int,
        axles: int | None,
        length_m: float | None,
        others_in: Callable[[str, float, float, int], bool],
    ) -> Opinion | None:
        """The counts at ``c.head`` and the section behind it against a train of ``axles`` axles
        (None: unknown, the section alone).  ``others_in(section, lo, hi, t)``: another followed
        train is in that section then (its occupancy is not this train's)."""
        assert c.until_ns is not None
        lag = self.lag_ns
        t0, t1 = c.since_ns - lag, c.until_ns
        counted = sum(1 for t, dd in self.axles.get(c.head, ()) if t0 <= t <= t1 and dd == d)
        doubts = sorted({why for t, why in self.counter_doubt.get(c.head, ()) if t0 <= t <= t1 + lag})
        n = axles
        sec = self.section_behind(c.head, d)
        at = c.until_ns + lag
        sec_state = self.state_at(sec, at) if sec is not None else None
        others = sec is not None and others_in(sec, *self.extent.get(sec, (math.inf, -math.inf)), at)
        occupied = sec_state is SectionState.OCCUPIED and not others
        disturbed = sec_state is SectionState.DISTURBED
        where = f"the head {length_m or 0:.0f} m + allowances past {c.head}"
        if doubts or disturbed:
            unfit = [f"{c.head} reported {', '.join(doubts)}"] if doubts else []
            unfit += [f"section {sec} disturbed"] if disturbed else []
            what = f"{counted} of {n} axles at {c.head}" if n else f"{counted} axles at {c.head}"
            # No witness here, not a doubt about the train: the counters cannot tell either way.
            return Opinion("unfit", (AXLES,), (f"{what}, counts unfit: " + "; ".join(unfit),), c.until_ns)
        if n is None:
            if occupied:
                left = f"section {sec} still occupied behind the train ({where})"
                return Opinion("separation", (SECTIONS,), (left,), c.until_ns)
            return None
        if counted == n:
            if occupied:
                return None  # something else is in that section: not this train's business
            return Opinion("ok", (AXLES,), (f"{n} of {n} axles counted at {c.head}",), c.until_ns)
        if counted > n:
            return Opinion(
                "doubt", (AXLES,), (f"{counted} axles at {c.head}, more than the consist's {n}",), c.until_ns
            )
        short = f"{c.head} counted {counted} of {n} axles ({where})"
        if occupied:
            why = (short, f"section {sec} still occupied behind the train")
            return Opinion("parted", (AXLES, SECTIONS), why, c.until_ns)
        if sec is not None and sec_state is SectionState.CLEAR:
            return Opinion("doubt", (AXLES,), (f"{short}, yet section {sec} behind is clear",), c.until_ns)
        return Opinion("separation", (AXLES,), (short,), c.until_ns)

    def section_behind(self, head: str, d: int) -> str | None:
        """The section a train running in direction ``d`` leaves at ``head``."""
        if self.layout is None:
            return None
        for sec, sign in self.layout.sections_of(head):
            if sign * d < 0:
                return sec.id
        return None

    def state_at(self, section: str, t_ns: int) -> SectionState | None:
        """The section's state at ``t_ns`` (its last change at or before then)."""
        hist = self.section_states.get(section)
        if not hist:
            return None
        k = bisect_left(hist, (t_ns + 1,)) - 1
        return hist[k][1] if k >= 0 else None
