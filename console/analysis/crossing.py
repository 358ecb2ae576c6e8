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

* **On** (per train, at each fix): the estimated head position, moved on by
  its speed to the current time (the most advanced of its last few fixes,
  so one fix that jumped back cannot delay the warning), is within
  ``v × (warning time + report period + latency)`` of the crossing, or
  within the guard distance whatever the speed (a slow or stopped train near
  the crossing), or already at or past it while the tail is not.  Adding
  one report period and the latency means the warning is on a full warning
  time before arrival even when the next fix comes late.
* **Speed** (:mod:`console.analysis.crossing_evidence`): the device's
  reported speed, or, when the export has none, an upper bound estimated
  from successive fixes; a single fix without speed is the worst case (the
  most a train can run), never a standstill.  Position jumps are set aside
  and counted; they do not refresh the device.
* **Off** (per train): on positive evidence only: two consecutive accepted
  EOT fixes past the crossing by ``d_off`` in the direction of travel, the
  second consistent with the first (it moved forward, by no more than the
  train could have run), with no fix set aside as a jump between them and
  the device's track not just restarted: one wild fix, plausible-looking or
  not, cannot open the road.  This is the paper's "d ≤ d_off, then
  increasing" in signed form: past the crossing by the margin and moving
  away.
* **Fail-safe.**  Nothing ever ends a warning by timeout.  A stale EOT
  (no fix for ``stale_after_s``) raises an alarm and keeps the warning on.
  A lost head unit falls back to the EOT position plus the train length.
  A train with no EOT keeps the warning on (alarm).  Direction unknown:
  treated as approaching.
* **A parted train** (:meth:`CrossingController.train_parted`, from the
  integrity monitor, :mod:`console.analysis.integrity`): its warning is
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

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from console.analysis.crossing_evidence import ESTIMATED, REPORTED, DeviceEvidence, EvidenceLimits, Report
from console.analysis.timefmt import NS
from console.layout import LevelCrossing

HEAD, EOT = "head", "eot"


@dataclass(frozen=True)
class TrainSpec:
    train: str
    length_m: float  # first to last wheel; the EOT rides on the last vehicle


@dataclass(frozen=True)
class Fix:
    """One position report as the crossing unit sees it."""

    t_ns: int  # when it is received and processed
    t_fix_ns: int  # when it was measured
    train: str
    role: str  # head | eot
    chainage_m: float
    speed_mps: float = math.nan
    direction_hint: int = 0  # +1 up, -1 down, 0 unknown (e.g. course against the track bearing)
    valid: bool = True


@dataclass(frozen=True)
class ControllerSettings:
    guard_distance_m: float = 300.0  # warn inside this, whatever the speed
    # The ETA is the *earliest* arrival: the train may accelerate at up to
    # this to the line speed.  A train standing within reach of the crossing
    # inside the warning time therefore keeps the road closed: nothing here
    # knows when it will leave (a departure signal would).
    accel_mps2: float = 0.5
    line_speed_mps: float = 25.0
    report_period_s: float = 10.0  # expected time between two fixes of a device
    latency_s: float = 2.0  # radio and processing delay allowance
    stale_after_s: float = 30.0  # no fix for this long: the device is stale
    max_speed_mps: float = 45.0  # no train runs faster (plausibility; the speed assumed when none is known)
    jump_accel_mps2: float = 1.5  # no train changes speed faster (a fix implying more is a position jump)
    speed_window_s: float = 45.0  # how far back the speed bound from positions looks
    noise_m: float = 15.0  # GNSS noise allowance in the plausibility check
    crossing_half_width_m: float = 5.0  # the road's half width along the track
    baseline_margin_s: float = 10.0  # the fixed-time method's safety margin
    # Lights flash first; the barriers come down this much later (road users clear
    # the crossing) and rise with the lights going out.
    barrier_delay_s: float = 8.0


def earliest_arrival_s(distance_m: float, speed_mps: float, accel_mps2: float, max_speed_mps: float) -> float:
    """Shortest time to run ``distance_m`` from ``speed_mps``, accelerating up to ``max_speed_mps``."""
    if distance_m <= 0:
        return 0.0
    v, a, vmax = max(0.0, speed_mps), accel_mps2, max(max_speed_mps, speed_mps, 1e-3)
    if a <= 0:
        return distance_m / max(v, 1e-3)
    t1 = (vmax - v) / a
    d1 = v * t1 + 0.5 * a * t1 * t1
    if distance_m <= d1:
        return (-v + math.sqrt(v * v + 2 * a * distance_m)) / a
    return t1 + (distance_m - d1) / vmax


@dataclass(frozen=True)
class CrossingEvent:
    t_ns: int
    crossing: str
    train: str
    kind: str  # on | off | alarm
    reason: str


RECENT_FIXES = 3  # the head estimate is the most advanced of this many last fixes


@dataclass
class _Track:
    spec: TrainSpec
    head_ev: DeviceEvidence
    eot_ev: DeviceEvidence
    head: Report | None = None
    eot: Report | None = None
    recent: dict[str, deque[Report]] = field(
        default_factory=lambda: {HEAD: deque(maxlen=RECENT_FIXES), EOT: deque(maxlen=RECENT_FIXES)}
    )
    direction: int = 0
    direction_set_ns: int = 0  # fix time of the last change of direction
    warned: bool = False
    t_on: int | None = None
    reason_on: str = ""
    t_off: int | None = None
    reason_off: str = ""
    alarms: set[str] = field(default_factory=set)
    episodes: list[tuple[int, int | None, str, str]] = field(default_factory=list)
    parted_ns: int | None = None  # when the integrity monitor saw the train parted


class CrossingController:
    """The warning logic of one level crossing, for any number of trains."""

    def __init__(
        self, crossing: LevelCrossing, trains: Iterable[TrainSpec], settings: ControllerSettings | None = None
    ) -> None:
        self.crossing = crossing
        self.s = settings or ControllerSettings()
        self.tracks = {t.train: self._new_track(t) for t in trains}
        self.events: list[CrossingEvent] = []
        # Fixes set aside as position jumps, per (train, role): their fix times.
        self.set_aside: dict[tuple[str, str], list[int]] = {}

    def _new_track(self, spec: TrainSpec) -> _Track:
        s = self.s
        lim = EvidenceLimits(s.noise_m, s.accel_mps2, s.jump_accel_mps2, s.max_speed_mps, s.speed_window_s)
        return _Track(spec, DeviceEvidence(lim), DeviceEvidence(lim))

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
        del self.tracks[train]
        return True

    @property
    def warning_on(self) -> bool:
        return any(t.warned for t in self.tracks.values())

    # -- estimates -------------------------------------------------------
    def _fresh(self, r: Report | None, t_ns: int) -> bool:
        return r is not None and (t_ns - r.t_fix_ns) <= self.s.stale_after_s * NS

    def _speed(self, tr: _Track, t_ns: int) -> float:
        """The fastest the train may be running now (m/s): reported speeds where the devices
        give them, else the tightest bound the positions prove; unknown is the worst case."""
        reps = [r for r in (tr.head, tr.eot) if r is not None]
        fresh = [r for r in reps if self._fresh(r, t_ns)] or reps
        reported = [r.speed_hi_mps for r in fresh if r.speed_basis == REPORTED]
        if reported:
            return max(reported)
        # Head and EOT ride one train: each bound holds for both, the smaller is the better.
        return min((r.speed_hi_mps for r in fresh), default=self.s.max_speed_mps)

    def _speed_basis(self, tr: _Track) -> str:
        bases = {r.speed_basis for r in (tr.head, tr.eot) if r is not None}
        for b, text in ((REPORTED, "reported"), (ESTIMATED, "estimated from the fixes")):
            if b in bases:
                return text
        return "unknown: the most a train runs"

    def _head_estimate(self, tr: _Track, t_ns: int) -> tuple[float, float, str] | None:
        """Head chainage now: (furthest it can be, where it surely is at least, basis).

        The furthest moves each of the device's last few fixes on at the speed bound and
        keeps the most advanced (the earliest arrival); the nearest moves the last fix on
        only by a reported speed (the tail-past test must not run ahead of the evidence).
        Without a fresh head fix: the EOT plus the train length."""
        d = tr.direction
        v = self._speed(tr, t_ns)
        for role, r, extra in ((HEAD, tr.head, 0.0), (EOT, tr.eot, tr.spec.length_m)):
            if not self._fresh(r, t_ns) or (role == EOT and (d == 0 or tr.parted_ns is not None)):
                continue  # a parted train's EOT rides on the rear part: it says nothing of the head
            assert r is not None
            far = r.chainage_m
            if d:
                far = d * max(d * q.chainage_m + v * (t_ns - q.t_fix_ns) / NS for q in tr.recent[role])
            v_sure = r.speed_mps if r.speed_basis == REPORTED else 0.0
            near = r.chainage_m + d * v_sure * (t_ns - r.t_fix_ns) / NS
            return far + d * extra, near + d * extra, "head" if role == HEAD else "eot+length"
        return None

    def _update_direction(self, tr: _Track, fix: Fix, ev: DeviceEvidence) -> None:
        """Direction of travel from the best evidence at hand; kept when there is none.

        1. the same device moved by more than the noise over its recent fixes (medians);
        2. the fix's course against the track's bearing;
        3. the head ahead of the EOT, only when both fixes are recent together
           (a stale head report must not set the direction), and only while the
           direction is unknown: a short train's head fix some seconds older than
           its EOT fix can lie behind it, and a reversed direction reads an EOT
           still on the road as past it.
        """
        before = tr.direction
        moved = ev.direction()
        if moved:
            tr.direction = moved
        elif fix.direction_hint:
            tr.direction = fix.direction_hint
        elif tr.head is not None and tr.eot is not None and not tr.direction:
            together = abs(tr.head.t_fix_ns - tr.eot.t_fix_ns) <= 2 * self.s.report_period_s * NS
            apart = abs(tr.head.chainage_m - tr.eot.chainage_m) > 0.5 * tr.spec.length_m
            if together and apart:
                tr.direction = 1 if tr.head.chainage_m > tr.eot.chainage_m else -1
        if tr.direction != before:
            tr.direction_set_ns = fix.t_fix_ns

    # -- the state machine -------------------------------------------------
    def _emit(self, t_ns: int, tr: _Track, kind: str, reason: str) -> CrossingEvent:
        ev = CrossingEvent(t_ns, self.crossing.code, tr.spec.train, kind, reason)
        self.events.append(ev)
        return ev

    def _approach(self, tr: _Track, t_ns: int) -> tuple[float, float, str] | None:
        """The head's distance to the crossing (m, < 0 once past), its earliest
        arrival (s) and the estimate's basis; None without an estimate or once the tail is past."""
        est = self._head_estimate(tr, t_ns)
        if est is None:
            return None
        head_ch, head_near, basis = est
        c = self.crossing.chainage_m
        ahead = tr.direction * (c - head_ch) if tr.direction else abs(c - head_ch)
        tail_past = False
        if tr.eot is not None and tr.direction:
            tail_past = tr.direction * (tr.eot.chainage_m - c) >= self.crossing.d_off_m
        elif tr.direction:
            past_m = tr.direction * (head_near - c)
            tail_past = past_m > tr.spec.length_m + self.crossing.d_off_m + 2 * self.s.noise_m
        if tail_past:
            return None
        v = self._speed(tr, t_ns)
        return ahead, earliest_arrival_s(ahead, v, self.s.accel_mps2, max(v, self.s.line_speed_mps)), basis

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

    def _check_on(self, tr: _Track, t_ns: int) -> list[CrossingEvent]:
        if tr.warned:
            return []
        approach = self._approach(tr, t_ns)
        if approach is None:
            return []
        ahead, eta, basis = approach
        horizon_s = self.crossing.warning_time_s + self.s.report_period_s + self.s.latency_s
        reason = ""
        if ahead <= 0:
            reason = "head at or past the crossing"
        elif ahead <= self.s.guard_distance_m:
            reason = f"within the guard distance ({ahead:.0f} m)"
        elif eta <= horizon_s:
            extra = horizon_s - self.crossing.warning_time_s
            reason = f"ETA {eta:.0f} s ≤ {self.crossing.warning_time_s:g} s + {extra:.0f} s"
            reason += f" (speed ≤ {self._speed(tr, t_ns):.1f} m/s, {self._speed_basis(tr)})"
        if not reason:
            return []
        if basis != "head":
            reason += " (head unit lost: EOT + train length)"
        tr.warned, tr.t_on, tr.reason_on, tr.t_off, tr.reason_off = True, t_ns, reason, None, ""
        return [self._emit(t_ns, tr, "on", reason)]

    def _check_off(self, tr: _Track, fix: Fix, prev_eot: Report | None, rep: Report) -> list[CrossingEvent]:
        if not tr.warned or fix.role != EOT or tr.direction == 0:
            return []
        c = self.crossing.chainage_m
        past = tr.direction * (fix.chainage_m - c)
        if past < self.crossing.d_off_m:
            return []
        if prev_eot is None or rep.restarted or tr.direction_set_ns >= prev_eot.t_fix_ns:
            # A first EOT fix alone is not evidence, nor a pair read in a direction that has
            # just changed: wait for the next.
            return []
        if tr.direction * (prev_eot.chainage_m - c) < self.crossing.d_off_m:
            return []  # one fix past could be a jump: two in a row are evidence
        dt = (fix.t_fix_ns - prev_eot.t_fix_ns) / NS
        step = tr.direction * (fix.chainage_m - prev_eot.chainage_m)
        if dt <= 0 or step < -self.s.noise_m or step > self.s.max_speed_mps * dt + self.s.noise_m:
            return []  # not consistent with the previous fix: not evidence
        tr.warned, tr.t_off = False, fix.t_ns
        tr.reason_off = f"EOT {past:.0f} m past the crossing and moving away"
        tr.episodes.append((tr.t_on or fix.t_ns, fix.t_ns, tr.reason_on, tr.reason_off))
        return [self._emit(fix.t_ns, tr, "off", tr.reason_off)]

    def _cleared(self, tr: _Track) -> bool:
        """The whole train is past this crossing and its warning is off: its head
        unit no longer matters here (a head running off the mapped line at the
        end of the run is not worth an alarm at a crossing it left behind)."""
        if tr.warned or tr.eot is None or not tr.direction:
            return False
        return tr.direction * (tr.eot.chainage_m - self.crossing.chainage_m) >= self.crossing.d_off_m

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

    def step(self, fix: Fix) -> list[CrossingEvent]:
        """Process one received fix."""
        tr = self.tracks.get(fix.train)
        if tr is None or not fix.valid or math.isnan(fix.chainage_m) or fix.role not in (HEAD, EOT):
            return self.tick(fix.t_ns)
        prev = tr.head if fix.role == HEAD else tr.eot
        if prev is not None and fix.t_fix_ns <= prev.t_fix_ns:
            return self.tick(fix.t_ns)  # late or repeated packet: older than what we know
        ev = tr.head_ev if fix.role == HEAD else tr.eot_ev
        jumped_before = ev.rejected_since_last
        rep = ev.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps)
        aside = self.set_aside.setdefault((fix.train, fix.role), [])
        if rep is None:
            aside.append(fix.t_fix_ns)  # a position jump: the device is not refreshed by it
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
        self._update_direction(tr, fix, ev)
        # A jump set aside since the previous fix is doubt: that pair is no evidence for off.
        prev_eot = prev if fix.role == EOT and not jumped_before else None
        out = self._check_off(tr, fix, prev_eot, rep)
        out += self._check_on(tr, fix.t_ns)
        out += self._alarms(tr, fix.t_ns)
        for other in self.tracks.values():
            if other is not tr:
                out += self._check_on(other, fix.t_ns) + self._alarms(other, fix.t_ns)
        return out

    def train_parted(self, train: str, t_ns: int, evidence: str) -> list[CrossingEvent]:
        """The integrity monitor saw ``train`` parted.  A warning on for it is held until the rear
        part is accounted for: the off rule's two EOT fixes past the crossing (the EOT rides on the
        rear part).  An alarm says so, once."""
        tr = self.tracks.get(train)
        if tr is None or tr.parted_ns is not None:
            return []
        tr.parted_ns = t_ns
        if self._cleared(tr):
            return []  # its rear part is past this crossing already
        what = "warning held until the rear part is accounted for" if tr.warned else "its rear part is short of here"
        tr.alarms.add("parted")
        return [self._emit(t_ns, tr, "alarm", f"train parted ({evidence}): {what}")]

    def settled_ns(self) -> int | None:
        """When every device's last fix has gone stale (None: no fix yet). After that, until the
        next fix, no estimate of a head exists (no warning by extrapolation), a head-unit alarm
        needs a fresh EOT, and a stale-EOT alarm fires at the first tick: later ticks do nothing."""
        last = [r.t_fix_ns for tr in self.tracks.values() for r in (tr.head, tr.eot) if r is not None]
        return max(last) + int(self.s.stale_after_s * NS) if last else None

    def tick(self, t_ns: int) -> list[CrossingEvent]:
        """The passing of time: activation by extrapolation, stale-device alarms."""
        out: list[CrossingEvent] = []
        for tr in self.tracks.values():
            out += self._check_on(tr, t_ns) + self._alarms(tr, t_ns)
        return out


def run_controller(
    crossing: LevelCrossing,
    trains: Sequence[TrainSpec],
    fixes: Sequence[Fix],
    settings: ControllerSettings | None = None,
    tick_s: float = 1.0,
    partings: Sequence[tuple[int, str, str]] = (),
) -> CrossingController:
    """Batch: feed fixes in reception order, ticking every ``tick_s`` between them; ``partings``
    (time, train, evidence) from the integrity monitor are told to the unit as they come."""
    ctl = CrossingController(crossing, trains, settings)
    ordered = sorted(fixes, key=lambda f: f.t_ns)
    if not ordered:
        return ctl
    t = ordered[0].t_ns
    step = max(1, int(tick_s * NS))
    told = sorted(partings)
    for f in ordered:
        if f.t_ns > t:
            _tick(ctl, t, (f.t_ns - t - 1) // step, step)  # every tick before the fix
        while told and told[0][0] <= f.t_ns:
            ctl.train_parted(told[0][1], told[0][0], told[0][2])
            told.pop(0)
        ctl.step(f)
        t = f.t_ns
    # A live unit keeps its clock running: let pending stale-device alarms fire.
    end = t + int((ctl.s.stale_after_s + tick_s) * NS)
    _tick(ctl, t, -(-(end - t) // step), step)
    return ctl


def _tick(ctl: CrossingController, t0_ns: int, n: int, step_ns: int) -> None:
    """``ctl.tick`` at ``t0 + k·step`` for k = 1..n, as a walk over every tick would give it.

    Ticks stop one tick after every device has gone stale (:meth:`CrossingController.settled_ns`):
    from then on a tick emits nothing and changes nothing until the next fix. So a fix dated
    years after the one before it (a damaged year) costs the stale time's ticks, not one tick
    per second of the years.
    """
    settled = ctl.settled_ns()
    for k in range(1, n + 1):
        t = t0_ns + k * step_ns
        if settled is None or t > settled + 2 * step_ns:  # two ticks past it: the stale time is a float
            return
        ctl.tick(t)
