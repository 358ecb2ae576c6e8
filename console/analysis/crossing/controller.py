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
* **Release** (per train, at a fix while the head unit is fresh, before the head arrives): a warning
  that came on early (a first fix without speed counts as the fastest train;
  a train then stops out of reach) goes off when a settled estimate of a
  fresh head unit proves the head cannot arrive within the warning time for a
  while yet (``release_hold_s`` at least, and until the next fix is due: it
  does not come on again before a new fix could renew the bound, no flicker), with no
  jump set aside lately and no head-unit alarm: a train proven standing 2 km
  out does not hold the road closed.  It comes on again by the same rule as any warning: from a
  standstill the head cannot arrive sooner than √(2d/a).
* **Model-free bounds** (:mod:`console.analysis.crossing.evidence`): the
  device's reported speed, or, when the export has none, an upper bound
  estimated from successive fixes; a single fix without speed is the worst
  case (the most a train can run), never a standstill.  Position jumps are set aside
  and counted; they do not refresh the device.
* **Off** (per train): on positive evidence only: two consecutive accepted
  EOT fixes past the crossing by ``d_off`` in the direction of travel, the
  second consistent with the first (it moved forward, by no more than the
  train could have run), with no fix set aside as a jump between them and
  the device's track not just restarted: one wild fix, plausible-looking or
  not, cannot open the road.  This is the paper's "d ≤ d_off, then
  increasing" in signed form: past the crossing by the margin and moving
  away, which a standing EOT is not unless it was seen short of the
  crossing first (it crossed): read in a wrong direction, a standing EOT
  before the crossing is "past" it.  The same evidence, latched, is what
  puts the tail past (no more warnings for the train); one EOT fix never
  is.  A train with its EOT end leading (backing, pushed: the EOT ahead of
  the head unit) has its rear a train's length behind the EOT: past by
  ``d_off`` plus the length.
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
each received fix, :meth:`CrossingController.tick` for the passing of time.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from console.analysis.crossing.arrival import ArrivalBound, Motion, device_bound
from console.analysis.crossing.estimate import FilterLimits, MotionFilter
from console.analysis.crossing.evidence import ESTIMATED, REPORTED, DeviceEvidence, EvidenceLimits, Report
from console.analysis.crossing.values import (
    EOT,
    HEAD,
    JUMPS,
    NO_SPEED,
    SPARSE,
    STALE,
    TRAIN,
    ControllerSettings,
    CrossingEvent,
    Fix,
    Onset,
    TrainSpec,
)
from console.analysis.window import Window
from console.layout import LevelCrossing
from parsers.units import NS

RECENT_FIXES = 3  # the model-free bound takes each of this many last fixes on its own
# The basis of a bound from the EOT and the length, nearer than the fresh head unit's own while
# the train's filter (head and EOT together) is not settled.
EOT_WITNESS = "eot+length (head unsettled)"


@dataclass
class _Track:
    spec: TrainSpec
    head_ev: DeviceEvidence
    eot_ev: DeviceEvidence
    kf: dict[str, MotionFilter]
    head: Report | None = None
    eot: Report | None = None
    recent: dict[str, Window[Report]] = field(
        default_factory=lambda: {HEAD: Window(RECENT_FIXES), EOT: Window(RECENT_FIXES)}
    )
    bounds: dict[str, ArrivalBound | None] = field(default_factory=dict)  # per source, since the last fix
    kf_ok: dict[str, bool] = field(default_factory=lambda: {HEAD: False, EOT: False})  # last fix taken by the filter
    doubt_ns: dict[str, int | None] = field(default_factory=lambda: {HEAD: None, EOT: None})  # last jump / set aside
    eot_kept: Report | None = None  # the last EOT fix the filter took (which unit leads is judged on it)
    direction: int = 0
    direction_set_ns: int = 0  # fix time of the last change of direction
    # The last direction known (±1; 0: never known): one the witnesses left unknown is not reversed by
    # less than reverses a known one.
    known_direction: int = 0
    # The direction the tail was last proven past the crossing in (0: not proven), by the off rule's own
    # evidence (:meth:`CrossingController._tail_past_evidence`); an EOT fix the filter took short of it ends it.
    tail_past_dir: int = 0
    # The direction in which an EOT fix the filter took was last short of the crossing (0: none): a tail seen
    # on the near side and then past has crossed, standing there or not.
    eot_short_dir: int = 0
    warned: bool = False
    t_on: int | None = None
    reason_on: str = ""
    t_off: int | None = None
    reason_off: str = ""
    onset: Onset | None = None  # the last warning's
    onsets: list[Onset] = field(default_factory=list)  # every warning's, in order (a timeline row per pass)
    releases: list[tuple[int, int, str]] = field(default_factory=list)  # (on, off, why) of released warnings
    alarms: set[str] = field(default_factory=set)
    episodes: list[tuple[int, int | None, str, str]] = field(default_factory=list)
    parted_ns: int | None = None  # when the integrity monitor saw the train parted
    # The unit's agenda (see CrossingController): the order the train was first followed in, the
    # first instant after its last evaluation at which time alone may change what the unit does for
    # it (None: nothing pending), and its share of next_change_ns (None: none).
    seq: int = 0
    due_ns: int | None = None
    late_ns: int | None = None


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

    def _new_track(self, spec: TrainSpec) -> _Track:
        s = self.s
        lim = EvidenceLimits(
            s.noise_m,
            s.accel_mps2,
            s.jump_accel_mps2,
            s.max_speed_mps,
            s.speed_window_s,
            speed_error_mps=s.k_sigma * s.speed_sigma_mps,  # the same bound on a reported speed as the filter's
        )
        flim = FilterLimits(
            s.noise_m / 3.0,
            s.speed_sigma_mps,
            s.jerk_psd,
            s.max_speed_mps,
            k_sigma=s.k_sigma,
            settle_fixes=s.settle_fixes,
            adaptive_noise=s.adaptive_noise,
        )
        kf = {HEAD: MotionFilter(flim), EOT: MotionFilter(flim), TRAIN: MotionFilter(flim)}
        self._seq += 1
        return _Track(spec, DeviceEvidence(lim), DeviceEvidence(lim), kf, seq=self._seq)

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

    # -- estimates -------------------------------------------------------
    def _fresh(self, r: Report | None, t_ns: int) -> bool:
        """Heard from within the stale time: stale from ``stale_after_s`` after its fix on."""
        return r is not None and (t_ns - r.t_fix_ns) < int(self.s.stale_after_s * NS)

    def _speed(self, tr: _Track, t_ns: int) -> float:
        """The fastest the train may be running at ``t_ns`` (m/s) by the model-free bounds: reported
        speeds where the devices give them, else the tightest bound the positions prove; unknown is
        the worst case.  Per device the largest of its last few fixes' bounds, each moved on to
        ``t_ns`` (it may have accelerated since): one fix that jumped back and seemed to prove a
        slow train cannot lower it."""
        s = self.s
        per_device = []
        for role, r in ((HEAD, tr.head), (EOT, tr.eot)):
            if r is None or not (self._fresh(r, t_ns) or not any(self._fresh(q, t_ns) for q in (tr.head, tr.eot))):
                continue
            hi = max(q.speed_hi_mps + s.accel_mps2 * max(0.0, (t_ns - q.t_fix_ns) / NS) for q in tr.recent[role])
            per_device.append((r.speed_basis == REPORTED, hi))
        reported = [hi for rep, hi in per_device if rep]
        if reported:
            return max(reported)
        # Head and EOT ride one train: each bound holds for both, the smaller is the better.
        best = min((hi for _rep, hi in per_device), default=s.max_speed_mps)
        return min(best, self._witness_speed(tr))

    def _witness_speed(self, tr: _Track) -> float:
        """The EOT as a second witness of the head: a head fix and an EOT fix taken at different
        times are two positions of the head (the EOT one a length behind it, the length known to
        ``3 · length_sigma_m``), so they bound the speed as two fixes of one device do, before
        either device has a second fix.  Direction unknown: the head could be a length either way.
        Holds at either fix's time (it may have braked since the first or accelerated since)."""
        h, e, s = tr.head, tr.eot, self.s
        if h is None or e is None or h.t_fix_ns == e.t_fix_ns:
            return math.inf
        if not (tr.kf_ok[HEAD] and tr.kf_ok[EOT]):
            # A fix its device's filter set aside is a jump: one position of it proves no slow train
            # (the speed bounds from the device's own fixes keep the most of its last few instead).
            return math.inf
        dt = abs(h.t_fix_ns - e.t_fix_ns) / NS
        d, length = tr.direction, tr.spec.length_m
        gap = abs(h.chainage_m - e.chainage_m - d * length) if d else abs(h.chainage_m - e.chainage_m) + length
        run_m = gap + s.noise_m * 2 + 3 * s.length_sigma_m
        return run_m / dt + max(s.accel_mps2, s.jump_accel_mps2) * dt / 2

    def _speed_basis(self, tr: _Track) -> str:
        bases = {r.speed_basis for r in (tr.head, tr.eot) if r is not None}
        for b, text in ((REPORTED, "reported"), (ESTIMATED, "estimated from the fixes")):
            if b in bases:
                return text
        return "unknown: the most a train runs"

    def _device_bound(self, tr: _Track, role: str) -> ArrivalBound | None:
        """The head's earliest arrival from one source's evidence (head, EOT + length, the train's
        filter); computed once after each fix of the train (the direction and the other device's
        speed bound take part), then kept."""
        if role in tr.bounds:
            return tr.bounds[role]
        last = tr.eot if role == EOT else tr.head
        b = None
        if last is not None:
            est = tr.kf[role].estimate
            # The cap holds at the time the bound is anchored: the train's filter may stand on a
            # later fix (of the EOT) than the head's last, and the train may have accelerated since.
            cap = self._speed(tr, last.t_fix_ns if est is None else max(last.t_fix_ns, est.t_ns))
            extra = tr.spec.length_m if role == EOT else 0.0
            b = device_bound(self.motion, est, tr.recent[EOT if role == EOT else HEAD], tr.direction, extra, cap)
        tr.bounds[role] = b
        return b

    def _bound(self, tr: _Track, t_ns: int) -> tuple[ArrivalBound, str] | None:
        """The bound that counts now: the head unit's while it is fresh (the EOT's plus the train's
        length where it is nearer and the train's filter is not settled), else the EOT's plus the
        train's length, else (every unit stale) the one heard last: the train is not forgotten."""
        # A parted train's EOT rides on the rear part: it says nothing of the head (nor does the
        # train's filter, which took it as a witness of the head).
        whole = tr.parted_ns is None
        if self._fresh(tr.head, t_ns):
            tb = self._device_bound(tr, TRAIN) if whole else None
            if tb is not None and tb.settled:
                return tb, "head"
            hb = self._device_bound(tr, HEAD)
            if hb is not None:
                # The train's filter not settled, the head's and the EOT's fixes have not agreed
                # lately, and the head's bound stands on its own fixes alone: a first fix cannot be
                # told from a position jump (nothing to gate it against), nor a jump inside the wide
                # gate after a gap of sparse fixes from motion.  The EOT plus the length is a second
                # witness of the same head: the nearer of the two counts (a jump in either only
                # brings the warning forward).
                if whole and self._fresh(tr.eot, t_ns):
                    eb = self._device_bound(tr, EOT)
                    if eb is not None and eb.t_arrival_ns < hb.t_arrival_ns:
                        return eb, EOT_WITNESS
                return hb, "head"
        if whole and self._fresh(tr.eot, t_ns) and (eb := self._device_bound(tr, EOT)) is not None:
            return eb, "eot+length"
        heard = [(r.t_fix_ns, role) for role, r in ((HEAD, tr.head), (EOT, tr.eot)) if r is not None]
        if not whole and tr.head is not None:
            heard = [(tr.head.t_fix_ns, HEAD)]
        if not heard:
            return None
        role = max(heard)[1]
        b = self._device_bound(tr, role)
        return (b, "stale " + ("head" if role == HEAD else "eot+length")) if b is not None else None

    def _update_direction(self, tr: _Track, fix: Fix) -> None:
        """Direction of travel from evidence one wild fix cannot fake; kept when there is none.

        The witnesses, each +1, −1 or silent:

        * the fix's course against the track's bearing (a receiver's course over ground at
          speed: a measurement of the direction, it counts twice);
        * each device's filter, settled, its speed clear of zero by k·σ and 2 m/s (its gate
          sets jumps aside; the model overshoots a little below zero when a train stops dead);
        * each device's own fixes: the median of the three oldest in the window against the
          median of the three newest.

        An unknown direction is set by any witness no other contradicts; a known one is
        reversed by two that agree with none against.  Witnesses that disagree make the
        direction unknown: a wrong direction reads a train approaching as one whose tail is
        past the crossing (ignored, or its warning ended), an unknown one is treated as
        approaching from the nearer side.  A direction left unknown so is set against the last
        one known only as a reversal is (two witnesses): else one witness, after another had
        disagreed, reversed it.  A standing train gives none but its devices' medians, which
        position jumps its filter took can tilt; reversed so, its EOT standing before the
        crossing read as past it, and its warning ended (found on a randomized run: the road
        opened for a train standing 560 m out, and closed 26 s late when it moved on).  Two fixes
        alone, or the head ahead of the EOT, are no witness: fixes some seconds apart on a fast
        train put the EOT ahead of an older head fix.
        """
        votes = [fix.direction_hint, fix.direction_hint] if fix.direction_hint else []
        for role, ev in ((HEAD, tr.head_ev), (EOT, tr.eot_ev)):
            est = tr.kf[role].estimate
            if est is not None and est.settled and abs(est.speed_mps) > est.k_sigma * est.sigma_speed_mps + 2.0:
                votes.append(1 if est.speed_mps > 0 else -1)
            if moved := ev.direction(medians_only=True):
                votes.append(moved)
        up, down = votes.count(1), votes.count(-1)
        before = tr.direction
        if up and down:
            tr.direction = 0
        elif up or down:
            d, w = (1, up) if up else (-1, down)
            against = before or tr.known_direction  # the direction this would reverse, if any
            if not against or d == against or w >= 2:
                tr.direction = d
        if tr.direction != before:
            tr.direction_set_ns = fix.t_fix_ns
        if tr.direction:
            tr.known_direction = tr.direction

    # -- the state machine -------------------------------------------------
    def _emit(self, t_ns: int, tr: _Track, kind: str, reason: str) -> CrossingEvent:
        ev = CrossingEvent(t_ns, self.crossing.code, tr.spec.train, kind, reason)
        self.events.append(ev)
        return ev

    def _eot_leads(self, tr: _Track) -> bool:
        """The EOT unit ahead of the head unit in the direction of travel, by more than the head can have
        run between their last fixes (and the noise): a train backing, or pushed.  Its rear is then the
        head unit's end, a train's length behind the EOT."""
        eot = tr.eot_kept or tr.eot
        if eot is None or tr.head is None or not tr.direction:
            return False
        reach = tr.head.speed_hi_mps * abs(eot.t_fix_ns - tr.head.t_fix_ns) / NS + 2 * self.s.noise_m
        return tr.direction * (eot.chainage_m - tr.head.chainage_m) > reach

    def _eot_off_m(self, tr: _Track) -> float:
        """How far past the crossing the EOT must be for the tail to be past by d_off: the train's length
        more when the EOT leads (it was d_off alone, and a pushed train's rear was still on the road)."""
        return self.crossing.d_off_m + (tr.spec.length_m if self._eot_leads(tr) else 0.0)

    def _tail_past(self, tr: _Track) -> bool:
        """The tail is past the crossing by d_off in the direction of travel: proven by the off rule's
        evidence (two EOT fixes past, moving away) and no EOT fix the filter took since short of it (one
        fix that jumped back does not put the tail on the road again).  One EOT fix is no proof: a first
        fix that jumped past the crossing (the device's next, true, fix then set aside against it, the
        device silent after) kept a train approaching from ever being warned."""
        if not tr.direction:
            return False
        if tr.eot is not None:
            return tr.tail_past_dir == tr.direction
        if tr.head is None or tr.head.speed_basis != REPORTED:
            return False
        # No EOT at all: only the head's own position (moved on by a reported speed) can tell.
        past_m = tr.direction * (tr.head.chainage_m - self.crossing.chainage_m)
        return past_m > tr.spec.length_m + self.crossing.d_off_m + 2 * self.s.noise_m

    def _approach(self, tr: _Track, t_ns: int) -> tuple[float, float, str, ArrivalBound] | None:
        """The head's distance from the road (m, the nearest it may be; < 0 once past), its earliest
        arrival from now (s), the bound's basis and the bound; None without one or once the tail is past."""
        if self._tail_past(tr):
            return None
        got = self._bound(tr, t_ns)
        if got is None:
            return None
        b, basis = got
        return b.ahead_m, max(0.0, (b.t_arrival_ns - t_ns) / NS), basis, b

    def arrival_bound(self, train: str, t_ns: int) -> tuple[ArrivalBound, str] | None:
        """The bound on a train's arrival the unit acts on at ``t_ns``, and its basis (head,
        eot+length, stale …); None: no fix of the train yet, or its tail is past the crossing."""
        tr = self.tracks.get(train)
        if tr is None or self._tail_past(tr):
            return None
        return self._bound(tr, t_ns)

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

    def _wake_ns(self, tr: _Track, now_ns: int) -> int | None:
        """The first instant after ``now_ns`` at which time alone may change what the unit does for
        ``tr``: a device going stale, or (no warning on) its bound coming due."""
        stale_ns = int(self.s.stale_after_s * NS)
        wake = [r.t_fix_ns + stale_ns for r in (tr.head, tr.eot) if r is not None]  # the instants they go stale
        if not tr.warned and (a := self._approach(tr, now_ns)) is not None:
            wake.append(a[3].t_arrival_ns - int(self.horizon_s * NS))
        later = [t for t in wake if t > now_ns]
        return min(later) if later else None

    def _late_ns(self, tr: _Track) -> int | None:
        """``tr``'s share of :meth:`next_change_ns`: the latest instant one of its bounds comes due, while
        no warning is on for it and its tail is not past (None: none)."""
        if tr.warned or self._tail_past(tr):
            return None
        horizon_ns = int(self.horizon_s * NS)
        due = [b.t_arrival_ns - horizon_ns for role in (HEAD, EOT, TRAIN) if (b := self._device_bound(tr, role))]
        return max(due) if due else None

    def _entry_ok(self, entry: tuple[int, int, str]) -> bool:
        tr = self.tracks.get(entry[2])
        return tr is not None and tr.seq == entry[1] and tr.due_ns == entry[0]

    def _arm(self, tr: _Track, t_ns: int) -> None:
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

    def _at_once(self, tr: _Track) -> None:
        """``tr``'s state changed outside an evaluation: evaluated at the next tick or fix."""
        tr.due_ns = _AT_ONCE
        heapq.heappush(self._due, (_AT_ONCE, tr.seq, tr.spec.train))

    def _pop_due(self, t_ns: int) -> list[_Track]:
        """The trains due at or before ``t_ns``, taken off the agenda, in the order they were followed."""
        due: dict[int, _Track] = {}
        while self._due and self._due[0][0] <= t_ns:
            entry = heapq.heappop(self._due)
            if self._entry_ok(entry):
                due[entry[1]] = self.tracks[entry[2]]
        return [due[k] for k in sorted(due)]

    def _evaluate(self, t_ns: int, skip: _Track | None = None) -> list[CrossingEvent]:
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

    def _onset(self, tr: _Track, t_ns: int, b: ArrivalBound, basis: str) -> Onset:
        """The bound's parts when the warning came on: what each doubt cost (ETA s)."""
        eta = (b.t_arrival_ns - t_ns) / NS
        doubt: dict[str, float] = {}

        def add(cause: str, s: float) -> None:
            if s > 0.05:
                doubt[cause] = doubt.get(cause, 0.0) + s

        last = tr.eot if "eot" in basis else tr.head
        no_speed = last is not None and last.speed_basis != REPORTED
        nominal = None
        if b.t_nominal_ns is not None and b.t_position_ns is not None and b.t_filter_ns is not None:
            nominal = (b.t_nominal_ns - t_ns) / NS
        if basis not in ("head", EOT_WITNESS):
            # The head unit lost (or every unit silent): the bound stands on the EOT and the length,
            # or on an old fix: all of what it cost is the stale units'.
            add(STALE, max(1.0, (nominal or eta) - eta))
        elif nominal is not None:
            assert b.t_nominal_ns is not None and b.t_position_ns is not None and b.t_filter_ns is not None
            add(SPARSE, (b.t_nominal_ns - b.t_position_ns) / NS)  # the position's σ
            add(NO_SPEED if no_speed else SPARSE, (b.t_position_ns - b.t_filter_ns) / NS)  # the speed's σ
            fallback = (b.t_filter_ns - b.t_arrival_ns) / NS  # the model-free bound came first
            clean_ns = int(max(self.s.speed_window_s, 3 * self.s.report_period_s) * NS)
            jumped = any(d is not None and t_ns - d < clean_ns for d in tr.doubt_ns.values())
            add(JUMPS if jumped else NO_SPEED if no_speed else SPARSE, fallback)
        return Onset(t_ns, eta, nominal, doubt)

    def _check_on(self, tr: _Track, t_ns: int) -> list[CrossingEvent]:
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
            how = self._speed_basis(tr) if not b.settled else "estimated from the fixes"
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
        tr.onset = self._onset(tr, t_ns, b, basis)
        tr.onsets.append(tr.onset)
        return [self._emit(t_ns, tr, "on", reason)]

    def _check_release(self, tr: _Track, fix: Fix) -> list[CrossingEvent]:
        """Off before the head arrives, at a fix of either unit while the head unit is fresh, when a
        settled estimate proves the train cannot arrive for a while yet (a train standing out of
        reach, or slower than first feared).  An EOT fix counts only through the train's filter,
        where it is a witness of the head (at fixes every 10 s it comes between two head fixes)."""
        s = self.s
        # A stale EOT does not hold a release back: whatever it would show is behind the head.
        # Direction unknown, the bound is the nearer way round (it holds whichever way the train goes).
        if not tr.warned or "head" in tr.alarms or not tr.kf_ok[HEAD] or not self._fresh(tr.head, fix.t_ns):
            return []
        if self._eot_leads(tr):
            # The head unit trails: its bound is not the front's, and a release by it came on again at the
            # next EOT fix (a pushed 300 m train: 22 times off and on, a second apart).
            return []
        # The head's own filter settled too: a bound that leans on the train's filter alone, just
        # after the head's track was in doubt (a brake, a jump), came on again within seconds.
        head_est = tr.kf[HEAD].estimate
        if head_est is None or not head_est.settled:
            return []
        b = self._device_bound(tr, TRAIN) if tr.parted_ns is None else None
        if fix.role != HEAD:
            # An EOT fix renews the bound only as the train filter's witness of the head, and only
            # while the head reports on time: a head unit silent since would go stale, and the
            # EOT-plus-length bound that then counts can come due at once.
            assert tr.head is not None
            head_age_s = (fix.t_ns - tr.head.t_fix_ns) / NS
            if b is None or not b.settled or not tr.kf_ok[fix.role] or head_age_s > s.report_period_s + s.latency_s:
                return []
        if b is None or not b.settled:
            b = self._device_bound(tr, HEAD)
        if b is None or not b.settled or b.ahead_m <= s.guard_distance_m:
            return []
        clean_s = max(s.speed_window_s, 3 * s.report_period_s)
        for role in (HEAD, EOT):
            last_doubt = tr.doubt_ns[role]
            if last_doubt is not None and fix.t_fix_ns - last_doubt < clean_s * NS:
                return []  # a jump set aside lately is doubt
        if tr.head_ev.rejected_since_last or tr.eot_ev.rejected_since_last:
            return []
        eta = (b.t_arrival_ns - fix.t_ns) / NS
        # The next fix of either unit is due one report period after its last, plus the latency:
        # until then nothing can renew the bound, so it must not come due before that.
        fresh = [r.t_fix_ns for r in (tr.head, tr.eot) if r is not None and self._fresh(r, fix.t_ns)]
        next_fix_s = (min(fresh) - fix.t_ns) / NS + s.report_period_s + s.latency_s
        # Released, the road stays open for release_hold_s at least by this bound, and until the
        # next fix is in (no flicker); a later fix can only push the bound out for a train as seen.
        if eta <= self.horizon_s + max(next_fix_s, s.release_hold_s):
            return []
        what = "train standing" if b.standing else f"head at most {b.speed_hi_mps:.1f} m/s"
        reason = f"released: {what} {b.ahead_m:.0f} m out cannot arrive within {eta:.0f} s"
        assert tr.t_on is not None
        tr.releases.append((tr.t_on, fix.t_ns, reason))
        tr.episodes.append((tr.t_on, fix.t_ns, tr.reason_on, reason))
        tr.warned, tr.t_off, tr.reason_off = False, fix.t_ns, reason
        return [self._emit(fix.t_ns, tr, "off", reason)]

    def _tail_past_evidence(self, tr: _Track, fix: Fix, prev_eot: Report | None, rep: Report) -> float | None:
        """How far past the crossing an EOT fix proves the tail (m), with the one before it; None when it
        proves nothing: the two past by the margin in a known direction, consistent, and moving away."""
        if fix.role != EOT or tr.direction == 0:
            return None
        if not self._past_margin(tr, fix.chainage_m):
            return None
        if prev_eot is None or rep.restarted or tr.direction_set_ns >= prev_eot.t_fix_ns:
            # A first EOT fix alone is not evidence, nor a pair read in a direction that has
            # just changed: wait for the next.
            return None
        if not self._past_margin(tr, prev_eot.chainage_m):
            return None  # one fix past could be a jump: two in a row are evidence
        dt = (fix.t_fix_ns - prev_eot.t_fix_ns) / NS
        step = tr.direction * (fix.chainage_m - prev_eot.chainage_m)
        if dt <= 0 or step < -self.s.noise_m or step > self.s.max_speed_mps * dt + self.s.noise_m:
            return None  # not consistent with the previous fix: not evidence
        if not self._moving_away(tr, step):
            return None
        return self._past_m(tr, fix.chainage_m)

    def _moving_away(self, tr: _Track, step_m: float) -> bool:
        """The EOT moves in the direction of travel, beyond its noise (the paper's "distance increasing"),
        or it was seen short of the crossing in this direction and is past it now: it crossed.  A standing
        EOT never seen on the near side is no evidence: read in a wrong direction (turned round by position
        jumps), a train standing before the crossing, or with its tail on the road, was "past it and moving
        away" (randomized runs: the road opened with the train standing on it).  A train that crossed and
        stands beyond (a station past the crossing) is past."""
        if tr.direction and tr.eot_short_dir == tr.direction:
            return True
        if step_m > 2 * self.s.noise_m:
            return True
        if tr.eot_ev.direction(medians_only=True) == tr.direction:
            return True
        est = tr.kf[EOT].estimate
        return (
            est is not None
            and est.settled
            and tr.kf_ok[EOT]
            and tr.direction * est.speed_mps > est.k_sigma * est.sigma_speed_mps + 2.0
        )

    def _note_tail(self, tr: _Track, fix: Fix, prev_eot: Report | None, rep: Report) -> float | None:
        """After an accepted fix: the tail proven past (→ how far, latched), or no longer (an EOT fix the
        filter took, short of the margin)."""
        if fix.role == EOT and tr.kf_ok[EOT] and self._past_m(tr, fix.chainage_m) < 0:
            tr.eot_short_dir = tr.direction
        past = self._tail_past_evidence(tr, fix, prev_eot, rep)
        if past is not None:
            tr.tail_past_dir = tr.direction
        elif fix.role == EOT and tr.kf_ok[EOT] and not self._past_margin(tr, fix.chainage_m):
            tr.tail_past_dir = 0
        return past

    def _past_m(self, tr: _Track, chainage_m: float) -> float:
        """How far past the crossing a chainage is in the train's direction of travel (m; < 0 short of it)."""
        return tr.direction * (chainage_m - self.crossing.chainage_m)

    def _past_margin(self, tr: _Track, eot_chainage_m: float) -> bool:
        """An EOT position past the crossing by the margin its tail needs (:meth:`_eot_off_m`)."""
        return self._past_m(tr, eot_chainage_m) >= self._eot_off_m(tr)

    def _check_off(self, tr: _Track, past: float | None, fix: Fix) -> list[CrossingEvent]:
        if not tr.warned or past is None:
            return []
        need = self._eot_off_m(tr)
        tr.warned, tr.t_off = False, fix.t_ns
        leads = (
            " (the EOT leading: the head unit's end a train's length behind)" if need > self.crossing.d_off_m else ""
        )
        tr.reason_off = f"EOT {past:.0f} m past the crossing and moving away{leads}"
        tr.episodes.append((tr.t_on or fix.t_ns, fix.t_ns, tr.reason_on, tr.reason_off))
        return [self._emit(fix.t_ns, tr, "off", tr.reason_off)]

    def _cleared(self, tr: _Track) -> bool:
        """The whole train is past this crossing and its warning is off: its head
        unit no longer matters here (a head running off the mapped line at the
        end of the run is not worth an alarm at a crossing it left behind)."""
        if tr.warned or tr.eot is None or not tr.direction:
            return False
        return self._past_margin(tr, tr.eot.chainage_m)

    def _alarms(self, tr: _Track, t_ns: int) -> list[CrossingEvent]:
        out = []
        if tr.warned and not self._fresh(tr.eot, t_ns) and "eot" not in tr.alarms:
            tr.alarms.add("eot")
            what = "no EOT fix yet" if tr.eot is None else f"EOT stale for {(t_ns - tr.eot.t_fix_ns) / NS:.0f} s"
            out.append(self._emit(t_ns, tr, "alarm", f"{what}: warning held on"))
        if (
            not self._fresh(tr.head, t_ns)
            and self._fresh(tr.eot, t_ns)
            and "head" not in tr.alarms
            and tr.head is not None
            and not self._cleared(tr)
        ):
            tr.alarms.add("head")
            fallback = (
                "the train parted: its head is not placed" if tr.parted_ns else "using EOT position + train length"
            )
            out.append(self._emit(t_ns, tr, "alarm", f"head unit stale: {fallback}"))
        if self._fresh(tr.eot, t_ns):
            tr.alarms.discard("eot")
        if self._fresh(tr.head, t_ns):
            tr.alarms.discard("head")
        return out

    def _filter(self, tr: _Track, fix: Fix, rep: Report, ev: DeviceEvidence) -> None:
        """Feed the device's filter; a fix it sets aside (or a track started over) is doubt."""
        kf = tr.kf[fix.role]
        if rep.restarted:
            kf.reset()
            tr.doubt_ns[fix.role] = fix.t_fix_ns
            if len(ev.history) > 1:  # the set-aside fix the new track began with
                t0, ch0 = ev.history[0]
                kf.offer(t0, ch0, math.nan, tr.direction)
        ok = kf.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps, tr.direction)
        tr.kf_ok[fix.role] = ok
        if not ok:
            tr.doubt_ns[fix.role] = fix.t_fix_ns
        elif fix.role == EOT:
            tr.eot_kept = rep

    def _filter_train(self, tr: _Track, fix: Fix, rep: Report) -> None:
        """The head's motion from both units: the EOT rides a train's length behind the head, so its
        fix is a head fix with the length's doubt added (only with the direction known)."""
        train = tr.kf[TRAIN]
        if rep.restarted:
            train.reset()
        # Each fix with its own device's noise (the two receivers need not be alike).
        sigma_m = tr.kf[fix.role].noise_sigma_m
        if fix.role == HEAD:
            train.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps, tr.direction, sigma_m=sigma_m)
        elif tr.direction and tr.parted_ns is None:  # a parted train's EOT is on the rear part
            at = fix.chainage_m + tr.direction * tr.spec.length_m
            train.offer(fix.t_fix_ns, at, fix.speed_mps, tr.direction, self.s.length_sigma_m**2, sigma_m)

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
        self._filter(tr, fix, rep, ev)
        self._update_direction(tr, fix)
        self._filter_train(tr, fix, rep)
        tr.bounds.clear()  # recomputed as they are asked for
        # A jump set aside since the previous fix is doubt: that pair is no evidence for off;
        # nor is a fix the filter set aside, or one after such a fix.
        kept = prev_kept and tr.kf_ok[fix.role]
        prev_eot = prev if fix.role == EOT and not jumped_before and kept else None
        past = self._note_tail(tr, fix, prev_eot, rep)
        out = self._check_off(tr, past, fix)
        out += self._check_release(tr, fix)
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
        if self._cleared(tr):
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


def run_controller(
    crossing: LevelCrossing,
    trains: Sequence[TrainSpec],
    fixes: Sequence[Fix],
    settings: ControllerSettings | None = None,
    tick_s: float | None = None,
    partings: Sequence[tuple[int, str, str]] = (),
) -> CrossingController:
    """Batch: feed fixes in reception order, ticking every ``tick_s`` (default: the settings') between them;
    ``partings`` (time, train, evidence) from the integrity monitor are told to the unit as they come."""
    ctl = CrossingController(crossing, trains, settings)
    ordered = sorted(fixes, key=lambda f: f.t_ns)
    if not ordered:
        return ctl
    tick_s = ctl.s.tick_s if tick_s is None else tick_s
    t = ordered[0].t_ns
    step = max(1, int(tick_s * NS))
    told = sorted(partings)
    for f in ordered:
        if f.t_ns > t:
            wake_until(ctl, _tick(ctl, t, (f.t_ns - t - 1) // step, step), f.t_ns)  # every tick and wake-up before it
        while told and told[0][0] <= f.t_ns:
            ctl.train_parted(told[0][1], told[0][0], told[0][2])
            told.pop(0)
        ctl.step(f)
        t = f.t_ns
    # A live unit keeps its clock running: let pending stale-device alarms fire, and the warning
    # for a train last heard approaching come on when it could be near (it is not forgotten).
    end = max(t + int((ctl.s.stale_after_s + tick_s) * NS), (ctl.next_change_ns() or t) + 2 * step)
    _tick(ctl, t, -(-(end - t) // step), step)
    return ctl


def _tick(ctl: CrossingController, t0_ns: int, n: int, step_ns: int) -> int:
    """``ctl.tick`` at ``t0 + k·step`` for k = 1..n, and at each instant between them when a warning
    comes due (:meth:`CrossingController.next_onset_ns`), as a live unit's clock wakes.

    Ticks stop one tick after nothing a tick does can change until the next fix
    (:meth:`CrossingController.next_change_ns`): every device gone stale and every
    warning due.  So a fix dated years after the one before it (a damaged year) costs
    the stale time's ticks, not one tick per second of the years.  Returns the last instant ticked.
    """
    if n < 1:
        return t0_ns
    settled = ctl.next_change_ns()
    done = t0_ns
    for k in range(1, n + 1):
        t = t0_ns + k * step_ns
        if settled is None or t > settled + 2 * step_ns:  # two ticks past it: the stale time is a float
            return done
        wake_until(ctl, done, t)
        ctl.tick(t)
        done = t
    return done


def wake_until(ctl: CrossingController, from_ns: int, to_ns: int) -> tuple[int, list[CrossingEvent]]:
    """Tick ``ctl`` at each instant in (``from_ns``, ``to_ns``) when something falls due (every driver's
    wake-ups between its steady ticks); returns the last instant ticked (``from_ns`` if none) and the
    events of those ticks."""
    out: list[CrossingEvent] = []
    while (w := ctl.next_onset_ns(from_ns)) is not None and w < to_ns:
        out += ctl.tick(w)
        from_ns = w
    return from_ns, out
