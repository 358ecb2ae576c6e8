"""Detection events and section states from closed passages: a whole-log result in bounded memory.

The batch path (:func:`console.analysis.diag_events.diag_detection_events`
then :func:`console.analysis.sections.engine.run_sections`) holds every wheel record
of the log, then every event.  Here the log is read in chunks through
:class:`~console.analysis.passages.stream.PassageStream`; each batch of closed
passages hands its wheel records, all heads at once, to one
:class:`~console.analysis.counting.bank.CounterBank` (the overlap rule with
array operations, event for event what a
:class:`~console.analysis.counting.wheels.HeadCounter` per head gives; the batch path
uses the same bank), and the events are held as columns and handed to one
:class:`~console.analysis.sections.engine.SectionEngine` below a *watermark*, as
the live engine (:mod:`console.live.diag`) does.  So the result is the
batch result, event for event:

* order: the batch path sorts all events by time, stably, over a list built
  head by head (counting events, then power events), operator resets last.
  The events released are sorted (``np.lexsort``) by exactly that:
  (time, head key, group, generation order);
* release: an event is handed to the engine only when nothing generated
  later can come before it.  Future records come at or after the
  watermark ``W`` (the earliest open run, or the log's clock less the order
  slack).  What time alone settles before ``W`` (a point-mode onset that
  waited a window for its partner in vain, a held pulse that stayed quiet)
  is settled then (:meth:`CounterBank.settle_before`); what falls at ``W``
  itself waits to be made with the records at ``W``, so equal-time events
  keep the batch's order.  A lone pulse's hold may fall due before it is
  known to be lone (a damping of one system longer than ``isolation_s``):
  nothing from that time on is released while such a pulse is open
  (:meth:`CounterBank.floor_ns`).  A power loss (at ``last record + power
  gap``) is known when the head's next record comes, or once the watermark
  is past it with nothing of the head's open: the head is silent while the
  log runs on, and a console following it must say so before it is heard
  again (the batch path gives the same loss, from the whole log);
* per-head facts the batch path takes from the whole log (no release
  records: point mode; any whole-second stamp) are guessed from the head's
  first closed passage and checked on every later one:
  :attr:`EventStream.guess_failed` tells the caller to read again with the
  facts it now knows (:attr:`EventStream.facts`).  Real boards do not change
  their stamps or their registers mid-log, so that second read is rare.

Per head the stream holds a few numbers in flat arrays (and the bank its
state), not an object: a log of a million heads costs arrays of a million.

Three-element (majority) heads and several overlapping files are not
streamed: the caller reads those whole.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from console.analysis.counting.bank import CounterBank
from console.analysis.counting.holds import NONE
from console.analysis.diag_events import (
    DiagEventSettings,
    absent_head_warnings,
    head_event_columns,
    power_gap_columns,
    shared_head_warnings,
    silent_heads,
    silent_loss_columns,
)
from console.analysis.events.block import KIND_CODE, EventBlock, StringPool
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.events.queue import EventQueue
from console.analysis.head_table import HeadNames
from console.layout import CountingHead, Layout
from parsers.units import ALL_TIME, NS

__all__ = ["EventStream", "HeadFacts"]

# Held groups: a head's counting events come before its power events at equal times (batch order).
_COUNTING, _POWER = 0, 1
# Operator resets sort after every diagnostic event at the same time.
_RESET_HEAD = 1 << 62
# Per head: not seen yet, counted, not counted (the layout does not know it: warned about).
_UNSEEN, _COUNTED, _IGNORED = 0, 1, 2


@dataclass(frozen=True)
class HeadFacts:
    """What the batch path learns about a head from all its wheel records."""

    point_mode: bool  # no release record at all: onsets pair within a window
    whole_second: bool  # some wheel record is stamped to the whole second


def _head_slices(records: dict[str, np.ndarray], size: int) -> Iterator[dict[str, np.ndarray]]:
    """Records (read order) in slices of whole heads by head key, each of about ``size`` records or one
    head's; within a head, read order kept."""
    n = len(records["head"])
    if n <= size:
        yield records
        return
    order = np.argsort(records["head"], kind="stable")
    key = np.asarray(records["head"])[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])  # each head's first position
    cuts = np.unique(starts[np.minimum(np.searchsorted(starts, np.arange(0, n, size)), len(starts) - 1)])
    for lo, hi in zip(cuts, np.r_[cuts[1:], n], strict=True):
        part = order[lo:hi]
        yield {c: v[part] for c, v in records.items()}


class EventStream:
    """Wheel records of closed passages in, detection events out in batch order.

    ``layout`` None counts every head of the log with default facts (as
    :func:`console.layout.layout_from_heads` gives them); ``facts`` fixes the
    per-head facts (a second read), else they are guessed.  ``on_event`` sees
    the events as they are generated (health reads the channel findings
    there), only those of ``event_kinds`` when given (the others are then
    never made as objects); :meth:`release` returns them in order
    (:meth:`release_block`: as columns).
    """

    def __init__(
        self,
        layout: Layout | None,
        settings: DiagEventSettings,
        facts: dict[int, HeadFacts] | None = None,
        on_event: Callable[[DetectionEvent], None] | None = None,
        event_kinds: Collection[EventKind] | None = None,
    ) -> None:
        self.layout = layout
        self.settings = settings
        self.known_facts = facts
        self.on_event = on_event
        self.event_kinds = frozenset(event_kinds) if event_kinds is not None else None
        self.guess_failed = False
        self.pool = StringPool()
        self.names: list[str] | HeadNames = HeadNames()  # head key → name (a list in a state pickled before)
        self.bank = CounterBank(settings.counting, names=self.names, pool=self.pool)
        self._state = np.zeros(0, np.int8)
        self._configured = np.zeros(0, bool)
        self._seen_release = np.zeros(0, bool)
        self._seen_whole = np.zeros(0, bool)
        self._last_activity = np.zeros(0, np.int64)  # the last closed activity bucket's last record
        self._queue = EventQueue(self.names, self.pool.strings)
        # Wheel records of heads whose facts are not settled yet (no passage of theirs closed), in read order.
        self._held: list[dict[str, np.ndarray]] = []
        self._last_heads: Sequence[tuple[int, str]] = []
        self._power_ns = int(settings.power_gap_s * NS) if settings.power_gap_s is not None else None

    # Held records counted, and the bank's waiting rows settled at the end, about this many (whole heads)
    # at a time.
    slice_records = 1 << 16

    # Per head: its loss told while silent, its restoration not yet (a class default: a state pickled
    # before there was one still loads).
    _lost = np.zeros(0, bool)

    # -- heads -------------------------------------------------------------
    def _heads(self, keys: np.ndarray, heads: Sequence[tuple[int, str]]) -> None:
        """Resolve the heads first seen among ``keys``: counted or not, and how (once per head)."""
        if isinstance(self.names, HeadNames):
            self.names.follow(heads)
        elif len(self.names) < len(heads):
            self.names.extend(name for _, name in heads[len(self.names) :])
        n = len(heads)
        if len(self._state) < n:
            grow = n - len(self._state)
            self._state = np.r_[self._state, np.zeros(grow, np.int8)]
            self._configured = np.r_[self._configured, np.zeros(grow, bool)]
            self._seen_release = np.r_[self._seen_release, np.zeros(grow, bool)]
            self._seen_whole = np.r_[self._seen_whole, np.zeros(grow, bool)]
            self._last_activity = np.r_[self._last_activity, np.full(grow, NONE, np.int64)]
        new = np.unique(keys[self._state[keys] == _UNSEEN])
        if not len(new):
            return
        up = np.ones(len(new), bool)
        if self.layout is None:  # every head counted, as layout_from_heads gives them
            self._state[new] = _COUNTED
        else:
            for i, key in enumerate(new.tolist()):  # per head, once
                spec = self._spec(*heads[key])
                self._state[key] = _IGNORED if spec is None else _COUNTED
                up[i] = spec is None or spec.up_is_first_channel_first
        counted = new[self._state[new] == _COUNTED]
        no = np.zeros(len(counted), bool)  # facts are set with the head's first wheel records
        self.bank.configure(counted, up[self._state[new] == _COUNTED], no, no)

    def _spec(self, device_id: int, name: str) -> CountingHead | None:
        lay = self.layout
        if lay is None:
            return CountingHead(id=name, chainage_m=0.0)
        spec = lay.counted_head(name, device_id)
        if spec is None:
            return None
        if spec.channels == 3:
            raise ValueError(f"head {name}: three-element heads are counted from the whole log")
        return spec

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
        return out + shared_head_warnings(lay, heads) + absent_head_warnings(lay, heads)

    @property
    def facts(self) -> dict[int, HeadFacts]:
        """Per head key, the facts seen in the records read so far."""
        seen = np.flatnonzero(self._state != _UNSEEN)
        rel, whole = self._seen_release[seen].tolist(), self._seen_whole[seen].tolist()
        return {k: HeadFacts(not r, w) for k, r, w in zip(seen.tolist(), rel, whole, strict=True)}

    # -- input ---------------------------------------------------------------
    def _push(self, block: EventBlock, group: int) -> None:
        if not len(block):
            return
        self._queue.push(block, block.head, group)
        if self.on_event is not None:
            shown = block.of_kinds(self.event_kinds) if self.event_kinds is not None else block
            for e in shown.events():
                self.on_event(e)

    def add_clock_steps(self, head: np.ndarray, time_ns: np.ndarray, heads: Sequence[tuple[int, str]]) -> None:
        """Heads whose records went back in time (``ClockSteps.feed``), each at its first record after the step:
        queued before any event of the records after it, and released in time order with them."""
        key_col = np.asarray(head, np.int64)
        self._heads(key_col, heads)
        mine = self._state[key_col] == _COUNTED
        n = int(mine.sum())
        if not n:
            return  # heads the layout does not count
        cols = head_event_columns(EventKind.CLOCK_STEP, key_col[mine], np.asarray(time_ns, np.int64)[mine])
        cols["source"] = np.full(n, self.bank.source)
        self._push(EventBlock.from_columns(cols, self.names, self.pool.strings), _POWER)

    def add_reset(self, e: DetectionEvent) -> None:
        """An operator reset (given up front, in the order given)."""
        block = EventBlock.from_events([e], self.names, self.pool)
        self._queue.push(block, np.full(1, _RESET_HEAD, np.int64), 0)

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

    def add_records(self, wheel: dict[str, np.ndarray], heads: Sequence[tuple[int, str]]) -> None:
        """Wheel records as they are read (any heads, read order): counted at once for heads whose facts
        are settled, held for the others until :meth:`settle` (their first passage has closed)."""
        if not len(wheel["head"]):
            return
        self._last_heads = heads
        key_col = np.asarray(wheel["head"], np.int64)
        self._heads(key_col, heads)
        ready = self._configured[key_col] | (self._state[key_col] != _COUNTED)
        if self.known_facts is not None:
            ready |= np.isin(key_col, np.fromiter(self.known_facts, np.int64, len(self.known_facts)))
        if ready.all():  # the usual case once every head's facts are settled: no copy of the columns
            self._count(wheel, heads)
            return
        self._held.append({c: np.asarray(v)[~ready] for c, v in wheel.items()})
        if ready.any():
            self._count({c: np.asarray(v)[ready] for c, v in wheel.items()}, heads)

    def settle(self, keys: np.ndarray, heads: Sequence[tuple[int, str]]) -> None:
        """Heads whose first passage has closed: their facts are guessed from what was held, and it is counted."""
        if not self._held:
            return
        keys = np.unique(np.asarray(keys, np.int64))
        held = {c: np.concatenate([h[c] for h in self._held]) for c in self._held[0]}
        now = np.isin(held["head"], keys)
        if not now.any():
            return
        rest = {c: v[~now] for c, v in held.items()}
        self._held = [rest] if len(rest["head"]) else []
        ready = {c: v[now] for c, v in held.items()}
        del held, rest, now
        # Counted a slice of whole heads at a time: a head's events do not depend on other heads', and the
        # queue orders them by (time, head, group, generation order), so the events are the same as counted
        # at once; but counting's temporaries (a few dozen arrays a record) stay a slice's, where a log of a
        # million heads settles half a million held records at its end.
        for part in _head_slices(ready, self.slice_records):
            self._count(part, heads)

    def held_from_ns(self) -> int:
        """The earliest wheel record held (int64 max: none): no event of its head is made before it."""
        if not self._held:
            return int(ALL_TIME)
        return int(min(int(h["time_ns"].min()) for h in self._held if len(h["time_ns"])))

    def _count(self, wheel: dict[str, np.ndarray], heads: Sequence[tuple[int, str]]) -> None:
        key_col = np.asarray(wheel["head"], np.int64)
        self._heads(key_col, heads)
        order = np.lexsort((wheel["time_ns"], key_col))  # per head by time; ties keep read order
        order = order[self._state[key_col[order]] == _COUNTED]
        if not len(order):
            return
        hk = key_col[order]
        v = wheel["value"][order]
        starts = np.flatnonzero(np.r_[True, hk[1:] != hk[:-1]])
        keys = hk[starts]
        self._seen_release[keys] |= np.logical_or.reduceat(v == 0, starts)
        self._seen_whole[keys] |= ~np.logical_and.reduceat(np.asarray(wheel["subsecond"], bool)[order], starts)
        new = keys[~self._configured[keys]]
        if len(new):
            point = ~self._seen_release[new]
            whole = self._seen_whole[new].copy()
            if self.known_facts is not None:
                for i, key in enumerate(new.tolist()):  # per head, once
                    known = self.known_facts.get(key)
                    if known is not None:
                        point[i], whole[i] = known.point_mode, known.whole_second
            self.bank.configure(new, self.bank.up_first[new], point, whole)
            self._configured[new] = True
        bank = self.bank
        wrong = (self._seen_release[keys] & bank.point_mode[keys]) | (self._seen_whole[keys] & ~bank.whole_second[keys])
        if bool(wrong.any()):
            self.guess_failed = True
        self._push(bank.feed(hk, wheel["channel"][order], wheel["time_ns"][order], v), _COUNTING)

    def _power(self, activity: dict[str, np.ndarray], heads: Sequence[tuple[int, str]]) -> None:
        assert self._power_ns is not None
        key_col = np.asarray(activity["head"], np.int64)
        self._heads(key_col, heads)
        order = np.lexsort((activity["t_first_ns"], key_col))
        order = order[self._state[key_col[order]] == _COUNTED]
        if not len(order):
            return
        hk = key_col[order]
        first = np.asarray(activity["t_first_ns"], np.int64)[order]
        last = np.asarray(activity["t_last_ns"], np.int64)[order]
        head_start = np.r_[True, hk[1:] != hk[:-1]]
        # Gaps between consecutive buckets, the first one after the head's previous batch.
        cols = power_gap_columns(hk, first, last, self._last_activity[hk], self._power_ns)
        lost = self._lost_flags()
        if lost[hk].any():
            # A loss already told while the head was silent: only its restoration is new.
            told = (cols["kind"] == KIND_CODE[EventKind.POWER_LOSS]) & lost[cols["head"]]
            told &= cols["time_ns"] == self._last_activity[cols["head"]] + self._power_ns
            cols = {c: v[~told] for c, v in cols.items()}
            lost[hk] = False
        cols["source"] = np.full(len(cols["time_ns"]), self.bank.source)
        self._push(EventBlock.from_columns(cols, self.names, self.pool.strings), _POWER)
        ends = np.r_[np.flatnonzero(head_start)[1:], len(hk)] - 1
        self._last_activity[hk[ends]] = last[ends]

    def _lost_flags(self) -> np.ndarray:
        if len(self._lost) < len(self._state):
            self._lost = np.r_[self._lost, np.zeros(len(self._state) - len(self._lost), bool)]
        return self._lost

    def _tell_silent(self, watermark_ns: int, open_first: np.ndarray) -> None:
        """Power losses of heads silent (nothing of theirs open) for more than the power gap before
        ``watermark_ns``: told now, each at its last record plus the gap."""
        assert self._power_ns is not None
        lost = self._lost_flags()
        n = len(self._state)
        is_open = np.zeros(n, bool)
        m = min(n, len(open_first))
        is_open[:m] = open_first[:m] != NONE
        silent = silent_heads(self._last_activity[:n], watermark_ns, self._power_ns)
        keys = np.flatnonzero(silent & ~is_open & ~lost & (self._state == _COUNTED))
        if not len(keys):
            return
        cols = silent_loss_columns(keys, self._last_activity[keys], self._power_ns)
        cols["source"] = np.full(len(keys), self.bank.source)
        self._push(EventBlock.from_columns(cols, self.names, self.pool.strings), _POWER)
        lost[keys] = True

    def _power_bound(self, open_first: np.ndarray | None) -> int:
        """No event at or after this may be released yet: a power event of some head could still come
        before it (a loss at its last record plus the gap; a told loss's restoration at its open run)."""
        assert self._power_ns is not None
        n = len(self._state)
        known = self._last_activity[:n] != NONE
        lost = self._lost_flags()[:n]
        bound = int(ALL_TIME)
        waiting = known & ~lost
        if waiting.any():
            bound = int(self._last_activity[:n][waiting].min()) + self._power_ns
        if open_first is not None and lost.any():
            firsts = np.full(n, NONE, np.int64)
            m = min(n, len(open_first))
            firsts[:m] = open_first[:m]
            back = lost & (firsts != NONE)
            if back.any():
                bound = min(bound, int(firsts[back].min()))
        return bound

    # -- output --------------------------------------------------------------
    def release_block(self, watermark_ns: int, open_first: np.ndarray | None = None) -> EventBlock:
        """Events that nothing read later can precede, given that no record still to come is
        earlier than ``watermark_ns``; in the batch path's order, as columns.

        ``open_first``: per head key, the first record of its open run (NONE: none open), as the passage
        stream holds it; with it, a power gap tells a silent head's loss as soon as it is known."""
        if self._power_ns is not None and open_first is not None:
            self._tell_silent(watermark_ns, open_first)
        watermark_ns = min(watermark_ns, self.held_from_ns())
        self._push(self.bank.settle_before(watermark_ns), _COUNTING)
        bound = min(watermark_ns, self.bank.floor_ns())
        if self._power_ns is not None:
            bound = min(bound, self._power_bound(open_first))
        return self._queue.pop_below(bound)

    def release(self, watermark_ns: int) -> list[DetectionEvent]:
        """:meth:`release_block` as event objects."""
        return self.release_block(watermark_ns).events()

    def finish_block(self, watermark_ns: int | None = None) -> EventBlock:
        """End of the log: settle every counter; all events, in order, as columns.

        ``watermark_ns``: the log's latest record time less the order slack; with a power gap, heads
        silent for longer than it before that have lost power (as the batch path finds in the whole log)."""
        if self._held:
            held = np.concatenate([h["head"] for h in self._held])
            self.settle(held, self._last_heads)
        for block in self.bank.flush_blocks(self.slice_records):
            self._push(block, _COUNTING)
        if self._power_ns is not None and watermark_ns is not None:
            self._tell_silent(watermark_ns, np.zeros(0, np.int64))
        return self._queue.pop_below(int(ALL_TIME))

    def finish(self) -> list[DetectionEvent]:
        """:meth:`finish_block` as event objects."""
        return self.finish_block().events()

    @property
    def held(self) -> int:
        """Events waiting for the watermark."""
        return len(self._queue)
