"""Level-crossing warning with a head unit and an end-of-train (EOT) device.

Seed 004: the crossing unit warns when the head will reach the crossing
within the warning time, T = d_head / v_head ≤ 70 s, and stops when the EOT
is within d_off of the crossing and its distance starts to increase.

**Why not literally.**  With fixes every 10 s at 55 km/h the tail moves
150 m between fixes and may never be seen within d_off (30 m) of the
crossing: the warning would never end.  With metres of GNSS noise, a
distance that "increases" between two fixes while the tail is still
approaching would end it too early.  And an unsigned distance cannot tell
"30 m before" from "30 m after".

**The rule used here.**  Positions are *along-track chainages* (the fix
projected onto the layout's polyline), signed in the train's direction of
travel.

* **On** (per train, at each fix and whenever the unit's clock wakes: every
  tick, and the instant a warning falls due, :meth:`CrossingController.next_onset_ns`):
  the earliest the head can reach the road's near edge
  (:mod:`console.analysis.crossing.arrival`) is within the warning time (plus
  a small margin), or the head is within the guard
  distance whatever the speed (a slow or stopped train near the crossing), or
  already at or past it while the tail is not.  The earliest arrival is
  anchored at a fix: where the head was at most, how fast it ran at most,
  accelerating at the line's acceleration to the line speed from then on.  It
  stays valid however late the next fix comes, so no allowance for the report
  period or the latency is needed; a unit that falls silent ends up warning.
* **Estimate** (:mod:`console.analysis.crossing.estimate`): per device, a
  Kalman filter on chainage, speed and acceleration gives the estimate and
  its σ; the bound is estimate + k·σ.  Until the filter is settled (its first
  fixes, fixes set aside lately), the model-free bounds below count too, the
  earlier wins.
* **Release** (per train, :mod:`console.analysis.crossing.release`): a warning that came on early
  goes off, before the head arrives, when a settled estimate of a fresh head unit proves the head
  cannot arrive within the warning time for a while yet: a train proven standing 2 km out does not
  hold the road closed.
* **Model-free bounds** (:mod:`console.analysis.crossing.evidence`): the
  device's reported speed, or, when the export has none, an upper bound
  estimated from successive fixes; a single fix without speed is the worst
  case (the most a train can run), never a standstill.  Position jumps are set aside
  and counted; they do not refresh the device.
* **Off** (per train, :mod:`console.analysis.crossing.tail`): on positive evidence only: two
  consecutive accepted EOT fixes past the crossing by ``d_off`` in the direction of travel
  (:mod:`console.analysis.crossing.direction`), consistent and moving away: one wild fix,
  plausible-looking or not, cannot open the road.  The same evidence, latched, puts the tail past
  (no more warnings for the train).
* **Fail-safe.**  Nothing ever ends a warning by timeout; a release needs a
  fresh, settled head estimate.  A stale EOT
  (no fix for ``stale_after_s``) raises an alarm and keeps the warning on.
  A lost head unit falls back to the EOT position plus the train length.
  A train with no EOT keeps the warning on (alarm).  Direction unknown:
  treated as approaching.
* **A parted train** (:meth:`CrossingController.train_parted`, from the
  integrity monitor, :mod:`console.analysis.integrity.monitor`): its warning is
  held until the rear part is accounted for, that is, by the off rule's own
  evidence, two EOT fixes past the crossing (the EOT rides on the rear
  part); the EOT position plus the train length no longer places its head.

A fixed-time **baseline** (off at head arrival + train length / speed +
margin) is computed beside it in the timeline, to show what the EOT saves
and where the baseline would have opened the road too early.

The controller is a pure state machine: :meth:`CrossingController.step` for
each received fix, :meth:`CrossingController.tick` for the passing of time
(:mod:`console.analysis.crossing.clock` runs its clock).  It keeps the order of
things (which rule runs when, and for which trains) and says what happens
(events); a train's state is a :class:`~console.analysis.crossing.track.Track`,
the bounds it acts on are worked out in :mod:`console.analysis.crossing.bounds`,
and the values it takes and gives are in :mod:`console.analysis.crossing.values`.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable

from console.analysis.crossing.arrival import ArrivalBound, Motion
from console.analysis.crossing.bounds import EOT_WITNESS, acting_bound, onset_of, source_bound, speed_basis_text
from console.analysis.crossing.direction import update_direction
from console.analysis.crossing.evidence import REPORTED
from console.analysis.crossing.release import check_release
from console.analysis.crossing.tail import check_off, cleared, note_tail, tail_past
from console.analysis.crossing.track import Track, feed_device_filter, feed_train_filter, fresh, new_track
from console.analysis.crossing.values import EOT, HEAD, TRAIN, ControllerSettings, CrossingEvent, Fix, TrainSpec
from console.layout import LevelCrossing
from parsers.units import NS

# A train to evaluate at the next tick or fix whatever the time (its state changed outside a step).
_AT_ONCE = -(2**63)


class CrossingController:
    """The warning logic of one level crossing, for any number of trains."""

    def __init__(
        self, crossing: LevelCrossing, trains: Iterable[TrainSpec], settings: ControllerSettings | None = None
    ) -> None:
        self.crossing = crossing
        self.s = settings or ControllerSettings()
        s = self.s
        self.motion = Motion(crossing.chainage_m, s.crossing_half_width_m, s.accel_mps2, s.line_speed_mps, s.noise_m)
        # The agenda: a fix or a tick evaluates only the trains it can change, not every train followed.
        # Between a train's fixes its state is fixed, and what a tick finds for it (a warning due by
        # extrapolation, an alarm for a unit gone stale) changes only at the instants next_onset_ns
        # names: a unit going stale, its bound coming due.  Until the first of them (its due_ns)
        # evaluating it finds nothing and changes nothing, so it is left out; at that instant (or the
        # first tick or fix after it) it is evaluated exactly as before, in the order trains were
        # first followed.  (Its alarms are dropped only when a unit is fresh again, which takes a fix
        # of its own; a unit going stale is one of its instants.)  Nothing is skipped that could warn:
        # a train's due instant is never later than its warning's, and a fix, a parting or the clock
        # going back evaluates it again.
        self._seq = 0
        self._due: list[tuple[int, int, str]] = []  # (due_ns, seq, train), stale entries skipped
        self._late: list[tuple[int, int, str]] = []  # (−late_ns, seq, train): next_change_ns's maximum
        self._last_fix_ns: int | None = None  # the latest fix time of any device followed
        self._t_eval_ns: int | None = None  # the latest instant any train was evaluated at
        self.tracks = {t.train: self._new_track(t) for t in trains}
        self.events: list[CrossingEvent] = []
        # Fixes set aside as position jumps, per (train, role): their fix times.
        self.set_aside: dict[tuple[str, str], list[int]] = {}

    def _new_track(self, spec: TrainSpec) -> Track:
        self._seq += 1
        return new_track(spec, self.s, self._seq)

    @property
    def position_jumps(self) -> int:
        """Fixes set aside as position jumps, all trains and devices."""
        return sum(len(v) for v in self.set_aside.values())

    def add_train(self, spec: TrainSpec) -> None:
        """Start following a train (a live unit learns of trains as they are registered)."""
        if spec.train not in self.tracks:
            self.tracks[spec.train] = self._new_track(spec)

    def forget_train(self, train: str) -> bool:
        """Stop following a train that has left the line, unless its warning is still on
        (then it stays, and so do its warning and alarms).  Returns whether it was forgotten."""
        tr = self.tracks.get(train)
        if tr is None or tr.warned:
            return False
        del self.tracks[train]  # its agenda entries go stale with it
        last = [r.t_fix_ns for t in self.tracks.values() for r in (t.head, t.eot) if r is not None]
        self._last_fix_ns = max(last) if last else None
        return True

    @property
    def warning_on(self) -> bool:
        return any(t.warned for t in self.tracks.values())

    # -- the state machine -------------------------------------------------
    def _emit(self, t_ns: int, tr: Track, kind: str, reason: str) -> CrossingEvent:
        ev = CrossingEvent(t_ns, self.crossing.code, tr.spec.train, kind, reason)
        self.events.append(ev)
        return ev

    def _off(self, t_ns: int, tr: Track, reason: str | None) -> list[CrossingEvent]:
        """The event of a warning a rule ended (``reason``; None: it did not)."""
        return [] if reason is None else [self._emit(t_ns, tr, "off", reason)]

    def _approach(self, tr: Track, t_ns: int) -> tuple[float, float, str, ArrivalBound] | None:
        """The head's distance from the road (m, the nearest it may be; < 0 once past), its earliest
        arrival from now (s), the bound's basis and the bound; None without one or once the tail is past."""
        if tail_past(tr, self.crossing, self.s):
            return None
        got = acting_bound(tr, self.s, self.motion, t_ns)
        if got is None:
            return None
        b, basis = got
        return b.ahead_m, max(0.0, (b.t_arrival_ns - t_ns) / NS), basis, b

    def arrival_bound(self, train: str, t_ns: int) -> tuple[ArrivalBound, str] | None:
        """The bound on a train's arrival the unit acts on at ``t_ns``, and its basis (head,
        eot+length, stale …); None: no fix of the train yet, or its tail is past the crossing."""
        tr = self.tracks.get(train)
        if tr is None or tail_past(tr, self.crossing, self.s):
            return None
        return acting_bound(tr, self.s, self.motion, t_ns)

    def arrival_s(self, t_ns: int) -> float | None:
        """Earliest arrival of the nearest head still approaching, as this unit estimates it (s)."""
        etas = [a[1] for tr in self.tracks.values() if (a := self._approach(tr, t_ns)) is not None and a[0] > 0]
        return min(etas) if etas else None

    def barriers_down(self, t_ns: int) -> bool:
        """The barriers follow the lights after ``barrier_delay_s`` and rise with them."""
        on_since = [t.t_on for t in self.tracks.values() if t.warned and t.t_on is not None]
        return bool(on_since) and t_ns - min(on_since) >= self.s.barrier_delay_s * NS

    @property
    def alarm(self) -> bool:
        return any(t.alarms for t in self.tracks.values())

    @property
    def horizon_s(self) -> float:
        """A warning comes on when the earliest arrival is this near (s).  No tick is added: the unit's
        clock wakes at the instant a warning comes due (:meth:`next_onset_ns`), not only every tick."""
        return self.crossing.warning_time_s + self.s.onset_margin_s

    def next_onset_ns(self, now_ns: int) -> int | None:
        """The first instant after ``now_ns`` at which the passing of time alone may change what the
        unit does: a warning coming due by extrapolation, or a unit going stale (its bound may then be
        another's, and an alarm is due).  Every driver wakes the unit's clock then, as well as every
        tick, so a warning comes on at the instant it is due, never a tick before (nor after).
        None: nothing is pending.  A train evaluated at or before ``now_ns`` and not due by then wakes
        at its due instant; the others (due, not yet evaluated) are worked out."""
        if self._t_eval_ns is not None and now_ns < self._t_eval_ns:
            wakes = [w for tr in self.tracks.values() if (w := self._wake_ns(tr, now_ns)) is not None]
            return min(wakes) if wakes else None
        due = self._pop_due(now_ns)
        wakes = [w for tr in due if (w := self._wake_ns(tr, now_ns)) is not None]
        while self._due and not self._entry_ok(self._due[0]):
            heapq.heappop(self._due)
        if self._due:
            wakes.append(self._due[0][0])  # the first train not due by now
        for tr in due:  # put back: asking does not evaluate
            assert tr.due_ns is not None
            heapq.heappush(self._due, (tr.due_ns, tr.seq, tr.spec.train))
        return min(wakes) if wakes else None

    def _wake_ns(self, tr: Track, now_ns: int) -> int | None:
        """The first instant after ``now_ns`` at which time alone may change what the unit does for
        ``tr``: a device going stale, or (no warning on) its bound coming due."""
        stale_ns = int(self.s.stale_after_s * NS)
        wake = [r.t_fix_ns + stale_ns for r in (tr.head, tr.eot) if r is not None]  # the instants they go stale
        if not tr.warned and (a := self._approach(tr, now_ns)) is not None:
            wake.append(a[3].t_arrival_ns - int(self.horizon_s * NS))
        later = [t for t in wake if t > now_ns]
        return min(later) if later else None

    def _late_ns(self, tr: Track) -> int | None:
        """``tr``'s share of :meth:`next_change_ns`: the latest instant one of its bounds comes due, while
        no warning is on for it and its tail is not past (None: none)."""
        if tr.warned or tail_past(tr, self.crossing, self.s):
            return None
        horizon_ns = int(self.horizon_s * NS)
        due = [
            b.t_arrival_ns - horizon_ns
            for role in (HEAD, EOT, TRAIN)
            if (b := source_bound(tr, self.s, self.motion, role))
        ]
        return max(due) if due else None

    def _entry_ok(self, entry: tuple[int, int, str]) -> bool:
        tr = self.tracks.get(entry[2])
        return tr is not None and tr.seq == entry[1] and tr.due_ns == entry[0]

    def _arm(self, tr: Track, t_ns: int) -> None:
        """``tr`` was just evaluated at ``t_ns``: its next due instant and its share of next_change_ns."""
        tr.due_ns = self._wake_ns(tr, t_ns)
        if tr.due_ns is not None:
            heapq.heappush(self._due, (tr.due_ns, tr.seq, tr.spec.train))
        late = self._late_ns(tr)
        if late != tr.late_ns:
            tr.late_ns = late
            if late is not None:
                heapq.heappush(self._late, (-late, tr.seq, tr.spec.train))
        self._t_eval_ns = t_ns if self._t_eval_ns is None else max(self._t_eval_ns, t_ns)

    def _at_once(self, tr: Track) -> None:
        """``tr``'s state changed outside an evaluation: evaluated at the next tick or fix."""
        tr.due_ns = _AT_ONCE
        heapq.heappush(self._due, (_AT_ONCE, tr.seq, tr.spec.train))

    def _pop_due(self, t_ns: int) -> list[Track]:
        """The trains due at or before ``t_ns``, taken off the agenda, in the order they were followed."""
        due: dict[int, Track] = {}
        while self._due and self._due[0][0] <= t_ns:
            entry = heapq.heappop(self._due)
            if self._entry_ok(entry):
                due[entry[1]] = self.tracks[entry[2]]
        return [due[k] for k in sorted(due)]

    def _evaluate(self, t_ns: int, skip: Track | None = None) -> list[CrossingEvent]:
        """What time alone does at ``t_ns`` to every train but ``skip``: warnings due, stale-unit alarms.
        Only the trains due are evaluated; all of them when the clock went back (a fix out of time
        order: a unit fresh again at that instant must be seen so)."""
        out: list[CrossingEvent] = []
        if self._t_eval_ns is not None and t_ns < self._t_eval_ns:
            todo = list(self.tracks.values())
            self._t_eval_ns = t_ns
        else:
            todo = self._pop_due(t_ns)
        for tr in todo:
            if tr is skip:
                continue
            out += self._check_on(tr, t_ns) + self._alarms(tr, t_ns)
            self._arm(tr, t_ns)
        return out

    def _check_on(self, tr: Track, t_ns: int) -> list[CrossingEvent]:
        if tr.warned:
            return []
        approach = self._approach(tr, t_ns)
        if approach is None:
            return []
        ahead, eta, basis, b = approach
        horizon_s = self.horizon_s
        reason = ""
        if ahead <= 0:
            reason = "head at or past the crossing"
        elif ahead <= self.s.guard_distance_m:
            reason = f"within the guard distance ({ahead:.0f} m)"
        elif t_ns >= b.t_arrival_ns - int(horizon_s * NS):  # in ns: the instant next_onset_ns wakes at is due
            extra = horizon_s - self.crossing.warning_time_s
            reason = f"ETA {eta:.0f} s ≤ {self.crossing.warning_time_s:g} s + {extra:.0f} s"
            how = speed_basis_text(tr) if not b.settled else "estimated from the fixes"
            if b.settled and (tr.head if basis.endswith("head") else tr.eot) is not None:
                last = tr.head if basis.endswith("head") else tr.eot
                how = "reported" if last is not None and last.speed_basis == REPORTED else how
            reason += f" (speed ≤ {b.speed_hi_mps:.1f} m/s, {how}; {b.ahead_m:.0f} m out)"
        if not reason:
            return []
        if basis == EOT_WITNESS:
            reason += " (EOT + train length: nearer than the head unit's own fixes)"
        elif basis != "head":
            reason += " (head unit lost: EOT + train length)" if basis == "eot+length" else f" ({basis}: no fresh unit)"
        tr.warned, tr.t_on, tr.reason_on, tr.t_off, tr.reason_off = True, t_ns, reason, None, ""
        tr.onset = onset_of(tr, self.s, t_ns, b, basis)
        tr.onsets.append(tr.onset)
        return [self._emit(t_ns, tr, "on", reason)]

    def _alarms(self, tr: Track, t_ns: int) -> list[CrossingEvent]:
        out = []
        if tr.warned and not fresh(tr.eot, t_ns, self.s) and "eot" not in tr.alarms:
            tr.alarms.add("eot")
            what = "no EOT fix yet" if tr.eot is None else f"EOT stale for {(t_ns - tr.eot.t_fix_ns) / NS:.0f} s"
            out.append(self._emit(t_ns, tr, "alarm", f"{what}: warning held on"))
        if (
            not fresh(tr.head, t_ns, self.s)
            and fresh(tr.eot, t_ns, self.s)
            and "head" not in tr.alarms
            and tr.head is not None
            and not cleared(tr, self.crossing, self.s)
        ):
            tr.alarms.add("head")
            fallback = (
                "the train parted: its head is not placed" if tr.parted_ns else "using EOT position + train length"
            )
            out.append(self._emit(t_ns, tr, "alarm", f"head unit stale: {fallback}"))
        if fresh(tr.eot, t_ns, self.s):
            tr.alarms.discard("eot")
        if fresh(tr.head, t_ns, self.s):
            tr.alarms.discard("head")
        return out

    def step(self, fix: Fix) -> list[CrossingEvent]:
        """Process one received fix."""
        tr = self.tracks.get(fix.train)
        if tr is not None:
            self._at_once(tr)  # a fix set aside is doubt, kept in its state: evaluated at once
        if tr is None or not fix.valid or math.isnan(fix.chainage_m) or fix.role not in (HEAD, EOT):
            return self.tick(fix.t_ns)
        prev = tr.head if fix.role == HEAD else tr.eot
        if prev is not None and fix.t_fix_ns <= prev.t_fix_ns:
            return self.tick(fix.t_ns)  # late or repeated packet: older than what we know
        ev = tr.head_ev if fix.role == HEAD else tr.eot_ev
        jumped_before = ev.rejected_since_last
        prev_kept = tr.kf_ok[fix.role]
        rep = ev.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps)
        aside = self.set_aside.setdefault((fix.train, fix.role), [])
        if rep is None:
            aside.append(fix.t_fix_ns)  # a position jump: the device is not refreshed by it
            tr.doubt_ns[fix.role] = fix.t_fix_ns
            return self.tick(fix.t_ns)
        if rep.restarted and aside:
            aside.pop()  # the fix set aside before this one started the new track with it
        # A restarted track keeps the fixes before it among the recent ones: the most
        # advanced of them still bounds the head (earlier warning, never later).
        tr.recent[fix.role].append(rep)
        if fix.role == HEAD:
            tr.head = rep
        else:
            tr.eot = rep
        self._last_fix_ns = rep.t_fix_ns if self._last_fix_ns is None else max(self._last_fix_ns, rep.t_fix_ns)
        feed_device_filter(tr, fix, rep, ev)
        update_direction(tr, fix)
        feed_train_filter(tr, self.s, fix, rep)
        tr.bounds.clear()  # recomputed as they are asked for
        # A jump set aside since the previous fix is doubt: that pair is no evidence for off;
        # nor is a fix the filter set aside, or one after such a fix.
        kept = prev_kept and tr.kf_ok[fix.role]
        prev_eot = prev if fix.role == EOT and not jumped_before and kept else None
        past = note_tail(tr, self.crossing, self.s, fix, prev_eot, rep)
        out = self._off(fix.t_ns, tr, check_off(tr, self.crossing, self.s, past, fix))
        out += self._off(fix.t_ns, tr, check_release(tr, self.s, self.motion, self.horizon_s, fix))
        out += self._check_on(tr, fix.t_ns)
        out += self._alarms(tr, fix.t_ns)
        # The clock going back evaluates every train but this one; else the others due by now.
        back = self._t_eval_ns is not None and fix.t_ns < self._t_eval_ns
        self._arm(tr, fix.t_ns)
        if back:
            self._t_eval_ns = fix.t_ns + 1  # any earlier instant: _evaluate takes every train
        return out + self._evaluate(fix.t_ns, skip=tr)

    def train_parted(self, train: str, t_ns: int, evidence: str) -> list[CrossingEvent]:
        """The integrity monitor saw ``train`` parted.  A warning on for it is held until the rear
        part is accounted for: the off rule's two EOT fixes past the crossing (the EOT rides on the
        rear part).  An alarm says so, once."""
        tr = self.tracks.get(train)
        if tr is None or tr.parted_ns is not None:
            return []
        tr.parted_ns = t_ns
        self._at_once(tr)  # its bound is another now
        if cleared(tr, self.crossing, self.s):
            return []  # its rear part is past this crossing already
        what = "warning held until the rear part is accounted for" if tr.warned else "its rear part is short of here"
        tr.alarms.add("parted")
        return [self._emit(t_ns, tr, "alarm", f"train parted ({evidence}): {what}")]

    def next_change_ns(self) -> int | None:
        """After this time (until the next fix) no tick changes anything (None: no fix yet).

        Ticks matter until every device's last fix has gone stale (alarms) and until every
        train not warned has had its warning due (the earliest arrival, less the horizon):
        after that no estimate can warn by extrapolation alone, a head-unit alarm needs a fresh
        EOT, and a stale-EOT alarm fires at the first tick."""
        if self._last_fix_ns is None:
            return None
        t = self._last_fix_ns + int(self.s.stale_after_s * NS)
        # Each train's share is kept up to date as it is evaluated (it changes only then).
        while self._late:
            neg, seq, train = self._late[0]
            tr = self.tracks.get(train)
            if tr is not None and tr.seq == seq and tr.late_ns == -neg:
                return max(t, -neg)
            heapq.heappop(self._late)
        return t

    def settled_ns(self) -> int | None:
        """When ticks stop mattering (:meth:`next_change_ns`); kept for callers that ask it so."""
        return self.next_change_ns()

    def tick(self, t_ns: int) -> list[CrossingEvent]:
        """The passing of time: activation by extrapolation, stale-device alarms."""
        return self._evaluate(t_ns)
