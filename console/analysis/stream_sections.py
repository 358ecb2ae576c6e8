"""Detection events and section states from closed passages: a whole-log result in bounded memory.

The batch path (:func:`console.analysis.diag_events.diag_detection_events`
then :func:`console.analysis.sections.run_sections`) holds every wheel record
of the log, then every event.  Here the log is read in chunks through
:class:`~console.analysis.stream.PassageStream`; each batch of closed
passages hands its wheel records to one
:class:`~console.analysis.wheels.HeadCounter` per counting head (the same
object the batch path and the live view run), and the events go through a
heap into one :class:`~console.analysis.sections.SectionEngine`, released
below a *watermark* as the live engine (:mod:`console.live.diag`) does.
So the result is the batch result, event for event:

* order: the batch path sorts all events by time, stably, over a list built
  head by head (counting events, then power events), operator resets last.
  The heap key is exactly that: (time, head key, group, generation order);
* release: an event is handed to the engine only when nothing generated
  later can come before it.  Future records come at or after the
  watermark ``W`` (the earliest open run, or the log's clock less the order
  slack); a counter's unsettled pulses (point mode: an onset waiting for its
  partner) settle at ``onset + window``; a power loss is known only when the
  head's next record comes, at ``last record + power gap``.  Counters are
  advanced only to a time where no held pulse and waiting onset settle at
  the same instant, so equal-time events keep the batch's order;
* per-head facts the batch path takes from the whole log (no release
  records: point mode; any whole-second stamp) are guessed from the head's
  first closed passage and checked on every later one:
  :attr:`EventStream.guess_failed` tells the caller to read again with the
  facts it now knows (:attr:`EventStream.facts`).  Real boards do not change
  their stamps or their registers mid-log, so that second read is rare.

Three-element (majority) heads and several overlapping files are not
streamed: the caller reads those whole.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from console.analysis.diag_events import DiagEventSettings
from console.analysis.events import DetectionEvent, EventKind
from console.analysis.timefmt import NS
from console.analysis.wheels import HeadCounter
from console.layout import CountingHead, Layout

ALL_TIME = np.iinfo(np.int64).max
# Heap groups: a head's counting events come before its power events at equal times (batch order).
_COUNTING, _POWER = 0, 1
# Operator resets sort after every diagnostic event at the same time.
_RESET_HEAD = 1 << 62


@dataclass(frozen=True)
class HeadFacts:
    """What the batch path learns about a head from all its wheel records."""

    point_mode: bool  # no release record at all: onsets pair within a window
    whole_second: bool  # some wheel record is stamped to the whole second


@dataclass
class _Head:
    name: str
    spec: CountingHead | None  # None: not counted (warned about)
    counter: HeadCounter | None = None
    facts: HeadFacts | None = None  # the facts the counter runs with
    seen_release: bool = False
    seen_whole: bool = False
    last_activity_ns: int | None = None  # the last closed activity bucket's last record (power gap)


class EventStream:
    """Wheel records of closed passages in, detection events out in batch order.

    ``layout`` None counts every head of the log with default facts (as
    :func:`console.layout.layout_from_heads` gives them); ``facts`` fixes the
    per-head facts (a second read), else they are guessed.  ``on_event`` sees
    every event as it is generated (health reads the channel findings there),
    :meth:`release` returns them in order.
    """

    def __init__(
        self,
        layout: Layout | None,
        settings: DiagEventSettings,
        facts: dict[int, HeadFacts] | None = None,
        on_event: Callable[[DetectionEvent], None] | None = None,
    ) -> None:
        self.layout = layout
        self.settings = settings
        self.known_facts = facts
        self.on_event = on_event
        self.guess_failed = False
        self._heads: dict[int, _Head] = {}
        self._heap: list[tuple[int, int, int, int, DetectionEvent]] = []
        self._seq = 0
        self._power_ns = int(settings.power_gap_s * NS) if settings.power_gap_s is not None else None

    # -- heads -------------------------------------------------------------
    def _head(self, key: int, device_id: int, name: str) -> _Head:
        h = self._heads.get(key)
        if h is None:
            spec: CountingHead | None
            if self.layout is None:
                spec = CountingHead(id=name, chainage_m=0.0)
            elif not self.layout.has_head(name):
                spec = None
            else:
                spec = self.layout.head(name)
                if spec.device_id is not None and spec.device_id != device_id:
                    spec = None
            if spec is not None and spec.channels == 3:
                raise ValueError(f"head {name}: three-element heads are counted from the whole log")
            h = self._heads[key] = _Head(name, spec)
        return h

    def warnings(self, heads: Sequence[tuple[int, str]]) -> list[str]:
        """The batch path's warnings about log heads the layout does not count, in head order."""
        out: list[str] = []
        lay = self.layout
        if lay is None:
            return out
        for device_id, name in heads:
            if not lay.has_head(name):
                out.append(f"counting head {name} (device {device_id}) is in the log but not in the layout")
            elif (spec := lay.head(name)).device_id is not None and spec.device_id != device_id:
                out.append(f"counting head {name}: the log's device {device_id} is not the layout's {spec.device_id}")
        return out

    @property
    def facts(self) -> dict[int, HeadFacts]:
        """Per head key, the facts seen in the records read so far."""
        return {k: HeadFacts(not h.seen_release, h.seen_whole) for k, h in self._heads.items()}

    # -- input ---------------------------------------------------------------
    def _push(self, e: DetectionEvent, key: int, group: int) -> None:
        heapq.heappush(self._heap, (e.time_ns, key, group, self._seq, e))
        self._seq += 1
        if self.on_event is not None:
            self.on_event(e)

    def add_reset(self, e: DetectionEvent) -> None:
        """An operator reset (given up front, in the order given)."""
        heapq.heappush(self._heap, (e.time_ns, _RESET_HEAD, 0, self._seq, e))
        self._seq += 1

    def add(
        self,
        wheel: dict[str, np.ndarray] | None,
        activity: dict[str, np.ndarray] | None,
        heads: Sequence[tuple[int, str]],
    ) -> None:
        """One batch of closed passages: their wheel records (read order) and activity buckets."""
        if wheel is not None and len(wheel["head"]):
            self._count(wheel, heads)
        if self._power_ns is not None and activity is not None and len(activity["head"]):
            self._power(activity, heads)

    def _count(self, wheel: dict[str, np.ndarray], heads: Sequence[tuple[int, str]]) -> None:
        key_col = wheel["head"]
        order = np.lexsort((wheel["time_ns"], key_col))  # per head by time; ties keep read order
        hk = key_col[order]
        starts = np.flatnonzero(np.r_[True, hk[1:] != hk[:-1]])
        ends = np.r_[starts[1:], len(hk)]
        for key, a, b in zip(hk[starts].tolist(), starts.tolist(), ends.tolist(), strict=True):  # per head
            device_id, name = heads[key]
            h = self._head(key, device_id, name)
            if h.spec is None:
                continue
            rows = order[a:b]
            ch = wheel["channel"][rows]
            t = wheel["time_ns"][rows]
            v = wheel["value"][rows]
            h.seen_release |= bool((v == 0).any())
            h.seen_whole |= not bool(wheel["subsecond"][rows].all())
            if h.counter is None:
                known = self.known_facts.get(key) if self.known_facts is not None else None
                h.facts = known or HeadFacts(not h.seen_release, h.seen_whole)
                h.counter = HeadCounter(
                    name,
                    up_is_sys1_first=h.spec.up_is_first_channel_first,
                    settings=self.settings.counting,
                    point_mode=h.facts.point_mode,
                    whole_second=h.facts.whole_second,
                )
            assert h.facts is not None
            if (h.seen_release and h.facts.point_mode) or (h.seen_whole and not h.facts.whole_second):
                self.guess_failed = True
            hc = h.counter
            for c, tt, vv in zip(ch.tolist(), t.tolist(), v.tolist(), strict=True):  # per wheel record, as batch
                for e in hc.feed(int(c), int(tt), int(vv)):
                    self._push(e, key, _COUNTING)

    def _power(self, activity: dict[str, np.ndarray], heads: Sequence[tuple[int, str]]) -> None:
        assert self._power_ns is not None
        order = np.lexsort((activity["t_first_ns"], activity["head"]))
        hk = activity["head"][order]
        first = activity["t_first_ns"][order]
        last = activity["t_last_ns"][order]
        starts = np.flatnonzero(np.r_[True, hk[1:] != hk[:-1]])
        ends = np.r_[starts[1:], len(hk)]
        for key, a, b in zip(hk[starts].tolist(), starts.tolist(), ends.tolist(), strict=True):  # per head
            device_id, name = heads[key]
            h = self._head(key, device_id, name)
            if h.spec is None:
                continue
            f, la = first[a:b], last[a:b]
            # Gaps between consecutive buckets, the first one after the head's previous batch.
            if h.last_activity_ns is not None:
                prev_last, next_first = np.r_[np.int64(h.last_activity_ns), la[:-1]], f
            else:
                prev_last, next_first = la[:-1], f[1:]
            gap = next_first - prev_last
            for i in np.flatnonzero(gap > self._power_ns).tolist():  # per power loss: rare
                lost = int(prev_last[i]) + self._power_ns
                detail = f"no records for {gap[i] / NS:.0f} s"
                self._push(DetectionEvent(lost, EventKind.POWER_LOSS, name, 0, None, "diag", detail), key, _POWER)
                restored = DetectionEvent(int(next_first[i]), EventKind.POWER_RESTORED, name, 0, None, "diag")
                self._push(restored, key, _POWER)
            h.last_activity_ns = int(la[-1])

    # -- output --------------------------------------------------------------
    def release(self, watermark_ns: int) -> list[DetectionEvent]:
        """Events that nothing read later can precede, given that no record still to come is
        earlier than ``watermark_ns``; in the batch path's order."""
        bound = watermark_ns
        for key, h in self._heads.items():
            hc = h.counter
            if hc is not None:
                waiting = min(p[0] for p in hc.pending) + hc.tol if hc.pending else ALL_TIME
                t = min(watermark_ns, waiting)
                # A held pulse and a waiting onset settling at the same instant: the batch path
                # settles both in one call (waiting first); leave both for it.
                if any(p[0] + hc.iso == t for p in hc.holds):
                    t -= 1
                for e in hc.advance(t):
                    self._push(e, key, _COUNTING)
                bound = min(bound, waiting)
            if self._power_ns is not None and h.last_activity_ns is not None:
                bound = min(bound, h.last_activity_ns + self._power_ns)
        return self._pop_below(bound)

    def finish(self) -> list[DetectionEvent]:
        """End of the log: settle every counter; all events, in order."""
        for key, h in self._heads.items():
            if h.counter is not None:
                for e in h.counter.flush():
                    self._push(e, key, _COUNTING)
        return self._pop_below(ALL_TIME)

    def _pop_below(self, bound: int) -> list[DetectionEvent]:
        out = []
        heap = self._heap
        while heap and (heap[0][0] < bound or bound == ALL_TIME):
            out.append(heapq.heappop(heap)[4])
        return out

    @property
    def held(self) -> int:
        """Events waiting for the watermark."""
        return len(self._heap)
