"""Seed 003's two-channel overlap rule over blocks of wheel records of many heads at once.

:class:`~console.analysis.counting.wheels.HeadCounter` states the rule for one head,
a record at a time; the live engine and the simulator run it so.  A
:class:`CounterBank` gives exactly its events (same order, same fields:
``tests/test_counting_bank.py``) for a block of records of many heads,
with array operations, and keeps each head's state in flat arrays between
blocks, so any split of the records gives the same events.

Why the sequential rule is array work (a head's records in time order):

* a system's damping state after a record is that record's value: an onset
  counts where its system was free (else it repeats one), a release where
  it was damped;
* an onset makes an axle iff the other system is damped by a damping not
  yet part of an axle.  That damping began at the head's previous onset
  unless an onset of this system came in between (which took it), and it
  is free iff that previous onset made no axle itself.  So with ``A`` =
  "the other system is damped and the previous onset was the other's",
  ``axle[k] = A[k] and not axle[k - 1]``: in a run of such onsets every
  other one is an axle, from the first;
* a damping is a lone pulse iff no axle was made at the head between its
  onset and its release.

Point mode (no release records: onsets pair within the window) keeps a
queue of waiting onsets of one system; the next onset of the other system
takes the oldest, and a waiting onset expires a window after it came.
Between two onsets more than a window apart everything has expired, so
runs of onsets closer than that (clusters) are independent.  A cluster is
paired first in queue order as if nothing expired; when every such pair
is within the window that is the rule's answer, and only a cluster where
it is not (a lone pulse amid close onsets) is paired a record at a time.

Lone pulses, the holds they start and what is carried from one block to
the next (onsets still waiting, holds) are settled for all heads at once
too, as flat tables (:mod:`console.analysis.counting.holds`): no loop per
record, per head or per pulse.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

import numpy as np

from console.analysis.counting.holds import (
    EXPIRED,
    FREE,
    NONE,
    OWN,
    Collector,
    Rows,
    first_record,
    pass_time,
    pass_time_slices,
    settle,
)
from console.analysis.counting.point_mode import group_starts, pair_point_onsets
from console.analysis.counting.wheels import REVERSED_RELEASE, SYS1, SYS2, CountingSettings
from console.analysis.events.block import KIND_CODE, NO_CHANNEL, Detail, EventBlock, StringPool
from console.analysis.events.detection import DetectionEvent, EventKind
from parsers.units import ALL_TIME, NS

_AXLE, _DAMPED, _FREE_KIND, _SINGLE = (
    KIND_CODE[k] for k in (EventKind.AXLE, EventKind.HEAD_DAMPED, EventKind.HEAD_FREE, EventKind.SINGLE_CHANNEL)
)


def _last(mask: np.ndarray, hstart: np.ndarray, strict: bool) -> np.ndarray:
    """Per position, the last position of ``mask`` at (or, ``strict``, before) it within its head; -1: none."""
    n = len(mask)
    last = np.maximum.accumulate(np.where(mask, np.arange(n), -1)) if n else np.zeros(0, np.int64)
    if strict:
        last = np.r_[-1, last[:-1]] if n else last
    return np.where(last >= hstart, last, -1)


class CounterBank:
    """The overlap rule for many heads: per-head state as flat arrays, records fed in blocks.

    Heads are int keys (into ``names``, which the caller extends).  Give each
    head its facts with :meth:`configure` before its first records; then
    :meth:`feed` blocks of records sorted by (head, time), ties in read
    order, :meth:`advance` to let time pass, :meth:`flush` at the end.  Each
    returns an :class:`EventBlock` in the order the heads' ``HeadCounter``\\ s
    would make the events, head by head.
    """

    def __init__(
        self,
        settings: CountingSettings | None = None,
        *,
        names: Sequence[str] = (),
        pool: StringPool | None = None,
        source: str = "diag",
    ) -> None:
        self.settings = s = settings or CountingSettings()
        self.iso = int(s.isolation_s * NS)
        self._window_ns = int(s.pair_window_s * NS)
        self.names = names
        self.pool = pool if pool is not None else StringPool()
        self.source = self.pool.code(source)
        self.texts = (
            self.pool.code("one system damped"),
            self.pool.code("isolated pulse: held"),
            self.pool.code(f"nothing else within {s.isolation_s:g} s: accidental"),
        )
        self.up_first = np.zeros(0, bool)
        self.point_mode = np.zeros(0, bool)
        self.whole_second = np.zeros(0, bool)
        self.tol = np.zeros(0, np.int64)
        self.open_t = np.zeros((0, 2), np.int64)  # per system: the current damping's onset (NONE: free)
        self.paired = np.zeros((0, 2), bool)  # that damping is part of an axle
        self.before = np.zeros((0, 2), np.int64)  # the head's previous onset when that damping began
        self.last_onset = np.zeros(0, np.int64)
        # Rare state, a row each: point mode's onsets waiting for a partner (all of one system per
        # head, in queue order), and isolated pulses held (in the order they began).
        self.pending = Rows(("head", "t_on", "channel", "before"))
        self.holds = Rows(("head", "t_on", "channel", "hold"), order="hold")
        self.hold_ids = 0

    # -- heads -------------------------------------------------------------
    def _grow(self, n: int) -> None:
        have = len(self.tol)
        if n <= have:
            return
        # By a quarter, not double: with a million heads these columns are some 50 MB at their size, and
        # doubling would hold up to as much again unused.
        n = max(n, have + have // 4)
        extra = n - have
        self.up_first = np.r_[self.up_first, np.ones(extra, bool)]
        self.point_mode = np.r_[self.point_mode, np.zeros(extra, bool)]
        self.whole_second = np.r_[self.whole_second, np.zeros(extra, bool)]
        self.tol = np.r_[self.tol, np.full(extra, self._window_ns, np.int64)]
        self.open_t = np.r_[self.open_t, np.full((extra, 2), NONE, np.int64)]
        self.paired = np.r_[self.paired, np.zeros((extra, 2), bool)]
        self.before = np.r_[self.before, np.full((extra, 2), NONE, np.int64)]
        self.last_onset = np.r_[self.last_onset, np.full(extra, NONE, np.int64)]

    def configure(
        self, keys: np.ndarray, up_is_sys1_first: np.ndarray, point_mode: np.ndarray, whole_second: np.ndarray
    ) -> None:
        """The facts of heads ``keys`` (before their first records): direction, point mode, stamps."""
        keys = np.asarray(keys, np.int64)
        if not len(keys):
            return
        self._grow(int(keys.max()) + 1)
        self.up_first[keys] = up_is_sys1_first
        self.point_mode[keys] = point_mode
        self.whole_second[keys] = whole_second
        # Whole-second stamps of one wheel's two onsets may differ by a second.
        self.tol[keys] = np.where(whole_second, max(self._window_ns, NS), self._window_ns)

    # -- records -------------------------------------------------------------
    def feed(self, head: np.ndarray, channel: np.ndarray, time_ns: np.ndarray, value: np.ndarray) -> EventBlock:
        """A block of wheel records sorted by (head, time), ties in read order; their events."""
        keep = (channel == SYS1) | (channel == SYS2)  # other channels are not this rule's
        h = np.asarray(head, np.int64)[keep]
        ch = np.asarray(channel)[keep].astype(np.int64)
        t = np.asarray(time_ns, np.int64)[keep]
        on = np.asarray(value)[keep] == 1
        out = Collector()
        if len(h):
            self._grow(int(h.max()) + 1)
            pm = self.point_mode[h]
            for mode, rows in ((False, np.flatnonzero(~pm)), (True, np.flatnonzero(pm))):
                if len(rows):
                    self._block(out, rows, h[rows], ch[rows], t[rows], on[rows], mode)
        return out.block(self)

    def _block(
        self, out: Collector, idx: np.ndarray, h: np.ndarray, ch: np.ndarray, t: np.ndarray, on: np.ndarray, point: bool
    ) -> None:
        """Records of heads of one mode (whole heads, in order); ``idx``: their positions in the block."""
        starts = group_starts(h)
        size = np.diff(np.r_[starts, len(h)])
        hstart = np.repeat(starts, size)
        if point:
            lones, onsets = self._point(out, idx, h, ch, t, on, starts, hstart)
        else:
            lones, onsets = self._overlap(out, idx, h, ch - 1, t, on, starts, hstart)
        settle(self, out, idx, h, t, onsets, starts, lones)

    def _overlap(
        self,
        out: Collector,
        idx: np.ndarray,
        h: np.ndarray,
        ci: np.ndarray,
        t: np.ndarray,
        on: np.ndarray,
        starts: np.ndarray,
        hstart: np.ndarray,
    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        m = len(h)
        carried_open = self.open_t[h] != NONE
        was = []  # per system: damped before each record
        for c in (0, 1):
            lc = _last(ci == c, hstart, strict=True)
            was.append(np.where(lc >= 0, on[np.maximum(lc, 0)], carried_open[:, c]))
        same_open = np.where(ci == 0, was[0], was[1])
        other_open = np.where(ci == 0, was[1], was[0])
        onset = on & ~same_open
        release = ~on & same_open

        op = np.flatnonzero(onset)
        oh, oc, ot = h[op], ci[op], t[op]
        first = np.r_[True, oh[1:] != oh[:-1]] if len(op) else np.zeros(0, bool)
        prev_t = np.r_[NONE, ot[:-1]] if len(op) else ot
        prev_t[first] = self.last_onset[oh[first]]
        prev_c = np.r_[-1, oc[:-1]] if len(op) else oc
        other = 1 - oc
        a = other_open[op] & np.where(first, ~self.paired[oh, other], prev_c != oc)
        k = np.arange(len(op))
        run_start = a & (first | ~np.r_[False, a[:-1]]) if len(op) else a
        offset = k - np.maximum.accumulate(np.where(run_start, k, 0)) if len(op) else k
        axle = a & (offset % 2 == 0)

        ax = np.flatnonzero(axle)
        axh, axc = oh[ax], oc[ax]
        partner = np.where(first[ax], self.open_t[axh, 1 - axc], prev_t[ax])
        t2 = ot[ax]
        same = (partner == t2) & ~self.whole_second[axh]
        order = np.where(axc == 1, 1, -1)  # this onset is Sys2's: the other, first, is Sys1
        direction = np.where(same, 0, np.where(self.up_first[axh], order, -order))
        detail = np.where(axc == 1, Detail.AXLE_SYS1_FIRST, Detail.AXLE_SYS2_FIRST)
        out.add(idx[op[ax]], OWN, 0, np.maximum(partner, t2), _AXLE, axh, direction, NO_CHANNEL, detail, partner)
        dm = op[~other_open[op]]
        out.add(idx[dm], OWN, 0, t[dm], _DAMPED, h[dm], 0, NO_CHANNEL, Detail.NONE, 0)

        onset_before = np.full(m, NONE, np.int64)
        onset_before[op] = prev_t
        axles_before = np.zeros(m + 1, np.int64)  # axles made at records before each position
        axles_before[op[axle] + 1] = 1
        axles_before = np.cumsum(axles_before)
        last_on = [_last(onset & (ci == c), hstart, strict=False) for c in (0, 1)]

        rp = np.flatnonzero(release)
        rc = ci[rp]
        rh = h[rp]
        s = np.where(rc == 0, last_on[0][rp], last_on[1][rp])  # the damping's onset (-1: before the block)
        inb = s >= 0
        s0 = np.maximum(s, 0)
        paired = np.where(
            inb,
            axles_before[rp + 1] - axles_before[s0] > 0,
            self.paired[rh, rc] | (axles_before[rp + 1] - axles_before[hstart[rp]] > 0),
        )
        # An axle's system damped second, freed while the first is still damped: its direction is in doubt
        # (HeadCounter.feed).  The other system's damping began at its last onset, or before the block.
        oc_r = 1 - rc
        so = np.where(oc_r == 0, last_on[0][rp], last_on[1][rp])
        other_on = np.where(so >= 0, t[np.maximum(so, 0)], self.open_t[rh, oc_r])
        this_on = np.where(inb, t[s0], self.open_t[rh, rc])
        rev = np.flatnonzero(paired & other_open[rp] & (other_on < this_on))
        if len(rev):
            text = self.pool.code(REVERSED_RELEASE)
            out.add(idx[rp[rev]], OWN, 0, t[rp[rev]], _SINGLE, rh[rev], 0, rc[rev] + 1, Detail.TEXT, text)
        lone_at = np.flatnonzero(~paired)
        lr, lh, lc = rp[lone_at], rh[lone_at], rc[lone_at]
        lones = {
            "record": lr,
            "sub": np.full(len(lr), OWN, np.int64),
            "tie": np.zeros(len(lr), np.int64),
            "t_on": np.where(inb[lone_at], t[s0[lone_at]], self.open_t[lh, lc]),
            "channel": lc + 1,
            "now": t[lr],
            "before": np.where(inb[lone_at], onset_before[s0[lone_at]], self.before[lh, lc]),
        }
        fr = rp[~other_open[rp]]
        out.add(idx[fr], FREE, 0, t[fr], _FREE_KIND, h[fr], 0, NO_CHANNEL, Detail.NONE, 0)

        # The state each head leaves the block in.
        ends = np.r_[starts[1:], m] - 1
        hh = h[starts]
        for c in (0, 1):
            lr_c = _last(ci == c, hstart, strict=False)[ends]
            open_end = np.where(lr_c >= 0, on[np.maximum(lr_c, 0)], carried_open[starts, c])
            so = last_on[c][ends]
            sin = so >= 0
            so0 = np.maximum(so, 0)
            paired_end = np.where(
                sin,
                axles_before[ends + 1] - axles_before[so0] > 0,
                self.paired[hh, c] | (axles_before[ends + 1] - axles_before[starts] > 0),
            )
            new_open = np.where(open_end, np.where(sin, t[so0], self.open_t[hh, c]), NONE)
            new_before = np.where(open_end, np.where(sin, onset_before[so0], self.before[hh, c]), NONE)
            self.open_t[hh, c] = new_open
            self.before[hh, c] = new_before
            self.paired[hh, c] = open_end & paired_end
        lo = _last(onset, hstart, strict=False)[ends]
        self.last_onset[hh] = np.where(lo >= 0, t[np.maximum(lo, 0)], self.last_onset[hh])
        return lones, op

    def _point(
        self,
        out: Collector,
        idx: np.ndarray,
        h: np.ndarray,
        ch: np.ndarray,
        t: np.ndarray,
        on: np.ndarray,
        starts: np.ndarray,
        hstart: np.ndarray,
    ) -> tuple[dict[str, np.ndarray], np.ndarray]:
        m = len(h)
        op = np.flatnonzero(on)
        oh = h[op]
        first = np.r_[True, oh[1:] != oh[:-1]] if len(op) else np.zeros(0, bool)
        before = np.r_[NONE, t[op][:-1]] if len(op) else np.zeros(0, np.int64)
        before[first] = self.last_onset[oh[first]]
        # Onsets still waiting from earlier blocks come first, in their queue order.
        waiting = self.pending.take(np.isin(self.pending.heads(), h[starts]))
        vh = waiting["head"]
        rows_h = np.r_[vh, oh]
        real = np.r_[np.zeros(len(vh), bool), np.ones(len(op), bool)]
        order = np.lexsort((np.r_[np.arange(len(vh)), op], real, rows_h))
        rows = {
            "head": rows_h[order],
            "time_ns": np.r_[waiting["t_on"], t[op]][order],
            "channel": np.r_[waiting["channel"], ch[op]][order],
            "before": np.r_[waiting["before"], before][order],
            "record": np.r_[np.full(len(vh), -1, np.int64), op][order],
        }
        pairs_a, pairs_b, unmatched = pair_point_onsets(rows, self.tol[rows["head"]])

        ra, rb = pairs_a, pairs_b
        rh = rows["head"][rb]
        t1, t2 = rows["time_ns"][ra], rows["time_ns"][rb]
        c1 = rows["channel"][ra]
        same = (t1 == t2) & ~self.whole_second[rh]
        order_12 = np.where(c1 == SYS1, 1, -1)
        direction = np.where(same, 0, np.where(self.up_first[rh], order_12, -order_12))
        detail = np.where(c1 == SYS1, Detail.AXLE_SYS1_FIRST, Detail.AXLE_SYS2_FIRST)
        out.add(idx[rows["record"][rb]], OWN, 0, np.maximum(t1, t2), _AXLE, rh, direction, NO_CHANNEL, detail, t1)

        # A waiting onset expires at the first record of its head more than a window after it.
        u = unmatched
        uk, ut = rows["head"][u], rows["time_ns"][u]
        expires = ut + self.tol[uk]
        at = first_record(h, t, uk, expires, after=True)
        now = at < np.r_[starts[1:], m][np.searchsorted(h[starts], uk)]
        lones = {
            "record": at[now],
            "sub": np.full(int(now.sum()), EXPIRED, np.int64),
            "tie": u[now],
            "t_on": ut[now],
            "channel": rows["channel"][u][now],
            "now": expires[now],
            "before": rows["before"][u][now],
        }
        later = ~now
        self.pending.add(
            {
                "head": uk[later],
                "t_on": ut[later],
                "channel": rows["channel"][u][later],
                "before": rows["before"][u][later],
            }
        )
        if len(op):
            last = np.r_[np.flatnonzero(oh[1:] != oh[:-1]), len(op) - 1]
            self.last_onset[oh[last]] = t[op[last]]
        return lones, op

    # -- time ----------------------------------------------------------------
    def advance(self, until: Mapping[int, int]) -> EventBlock:
        """HeadCounter.advance at these heads (key → time): expire waiting onsets, confirm quiet holds."""
        keys = np.fromiter(until, np.int64, len(until))
        times = np.fromiter(until.values(), np.int64, len(until))
        order = np.argsort(keys)
        keys, times = keys[order], times[order]

        def at(heads: np.ndarray) -> np.ndarray:
            i = np.minimum(np.searchsorted(keys, heads), max(len(keys) - 1, 0))
            return (
                np.where((len(keys) > 0) & (keys[i] == heads), times[i], NONE)
                if len(keys)
                else np.full(len(heads), NONE)
            )

        return pass_time(self, at, strict=False)

    def settle_before(self, t: int) -> EventBlock:
        """Events that time alone makes before ``t``, when no record still to come is earlier than ``t``.

        Onsets that expire and holds that fall due before ``t``; whatever falls
        at ``t`` itself waits, to be made with the records at ``t`` in
        HeadCounter's order.  After this only what :meth:`floor_ns` says can
        make an event earlier than ``t``.
        """
        return pass_time(self, lambda heads: np.full(len(heads), t, np.int64), strict=True)

    def floor_ns(self) -> int:
        """After :meth:`settle_before`: the earliest time an event made later may still carry (ALL_TIME:
        none earlier than the records to come).

        A pulse ends as a lone one when it is released (or its window closes),
        but its hold, when nothing came before it, falls due ``isolation_s``
        after it began, which may be earlier: a damping of one system open for
        longer than that, or (``isolation_s`` shorter than the window) an onset
        still waiting for its partner.  The batch path sorts that confirmation
        before what came in between, so nothing after it may be released yet.
        """
        iso = self.iso
        # Only the held systems' times are looked at (a few), not temporaries over every head's.
        held = np.flatnonzero(((self.open_t != NONE) & ~self.paired).ravel())
        open_t, before = self.open_t.ravel()[held], self.before.ravel()[held]
        quiet = (before == NONE) | (open_t - np.where(before == NONE, 0, before) > iso)
        p = self.pending.cols
        p_quiet = (p["before"] == NONE) | (p["t_on"] - np.where(p["before"] == NONE, 0, p["before"]) > iso)
        starts = np.r_[open_t[quiet], p["t_on"][p_quiet]]
        return int(starts.min()) + iso if len(starts) else int(ALL_TIME)

    def _end(self, heads: np.ndarray) -> np.ndarray:
        last = self.last_onset[heads]
        return np.where(last != NONE, last + self.iso + self.tol[heads] + 1, NONE)

    def flush(self) -> EventBlock:
        """End of input: settle everything still open, at each head's last onset plus the windows."""
        return pass_time(self, self._end, strict=False)

    def flush_blocks(self, rows: int) -> Iterator[EventBlock]:
        """:meth:`flush` a slice of whole heads at a time (about ``rows`` onsets waiting or pulses held
        each): its events over the blocks, in the same order."""
        return pass_time_slices(self, self._end, strict=False, size=rows)


def two_channel_events(
    head: str,
    channel: np.ndarray,
    time_ns: np.ndarray,
    value: np.ndarray,
    *,
    up_is_sys1_first: bool = True,
    settings: CountingSettings | None = None,
    source: str = "diag",
    whole_second: bool = False,
) -> list[DetectionEvent]:
    """Batch: one head's records through the overlap rule (the events of
    :class:`~console.analysis.counting.wheels.HeadCounter`, made by :class:`CounterBank` without a loop per record),
    in time order.

    Records come in the log's order; equal times keep it (a stable sort).
    """
    order = np.argsort(time_ns, kind="stable")
    bank = CounterBank(settings, names=[head], source=source)
    point_mode = not bool((np.asarray(value) == 0).any())
    bank.configure(
        np.zeros(1, np.int64), np.array([up_is_sys1_first]), np.array([point_mode]), np.array([whole_second])
    )
    fed = bank.feed(np.zeros(len(order), np.int64), channel[order], time_ns[order], value[order])
    events = fed.events() + bank.flush().events()
    return sorted(events, key=lambda e: e.time_ns)
