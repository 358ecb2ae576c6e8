"""The simulated line: trains, counting heads, GNSS units, the radio, faults, and the truth.

:class:`StationSim` is the world only, deterministic for a seed and advanced
by one call, :meth:`StationSim.step` (the live view calls it; tests step it
by hand).  Each step:

1. trains move under their speed control along the speed limits, platform
   stops and the train ahead (a simple protection rule keeps followers
   behind and opposing trains off the line);
2. every wheel passing a counting head damps Sys1 and Sys2 over the
   detection zone: onset and release times are interpolated exactly inside
   the step; faults on demand alter what the heads *report* (a head without
   power reports nothing, status records included);
3. each head's device writes a status record every heartbeat, and counts its
   own axles as an intelligent sensor does (:mod:`console.sim.sensor_count`);
4. head and EOT GNSS units send fixes every radio report period (LoRa duty
   cycle), with noise; the radio loses some and delivers the rest after its
   latency;
5. the **truth** (every axle at every head, true section occupancy, true
   head and tail times at crossings) is kept beside it.

What the devices reported in a step (:class:`StepResult`) goes to the
console watching the line, when one is attached (:meth:`StationSim.attach`):
the station's console is the live engine, fed those reports as the written
files would feed ``trackside follow`` (:mod:`console.live.simulated`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from console.analysis.counting.wheels import SYS1, SYS2
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, CrossingEvent
from console.analysis.geo import TrackProjector
from console.layout import Consist, Layout
from console.sim import brake_pipe as bp
from console.sim.devices import line_devices, with_devices
from console.sim.dynamics import LEVEL_LINE, TrainState, scaled_train
from console.sim.faults import Fault
from console.sim.parting import PartingTruth, braking_step, part_consist, split_axles
from console.sim.radio import LoRaLink
from console.sim.sensor_count import SensorCounts
from console.sim.slow_faults import HeadHealth, HealthRows, HealthSettings, unit_loss
from parsers.units import NS

DETECTION_ZONE_M = 0.25  # a wheel damps a coil over this length of travel
# The truth's head arrival and tail clearance at a crossing: at the road's half width (the crossing units' figure).
CROSSING_HALF_WIDTH_M = ControllerSettings().crossing_half_width_m
ENTRY_ROOM_M = 400.0  # a new train enters only this far behind the tail of the one before it


@dataclass(frozen=True)
class SimConfig:
    seed: int = 1
    trains_per_hour: float = 6.0
    first_train_s: float = 60.0
    dwell_s: float = 30.0
    accel_mps2: float = 0.6
    brake_mps2: float = 0.7
    gnss_noise_m: float = 3.0
    gnss_loss: float = 0.05
    radio: LoRaLink = field(default_factory=LoRaLink)
    heartbeat_s: float = 20.0  # each head's device writes a status record this often
    faults: tuple[Fault, ...] = ()
    start_ns: int = 1_772_438_400 * NS  # 2026-03-02 08:00 UTC
    # Each head's health registers (1-edge counters, analog values) every this often; None: not written,
    # unless a slow fault on a head needs them (then every HealthSettings.period_s).
    health_period_s: float | None = None
    fleet: int = 0  # > 0: trains are this many trainsets, T1..Tn, each with its own units, making trip after trip


@dataclass
class SimTrain:
    id: str
    consist: Consist
    direction: int
    x_m: float  # head chainage
    v_mps: float = 0.0
    entered_s: float = 0.0
    dwell_until_s: float | None = None
    stops: list[float] = field(default_factory=list)  # head chainages to stop at, in order
    done: bool = False
    next_head_fix_s: float = 0.0
    next_eot_fix_s: float = 0.0
    controller: str = "pid"
    driver: Any = None  # the ATO driver (console.sim.ato.Driver) when the force model runs the train
    travelled_m: float = 0.0
    units: tuple[str, ...] = ("head", "eot")  # the GNSS units riding on it
    axle_offset: int = 0  # a rear part's first axle, in the whole consist's numbering
    rear: SimTrain | None = None  # the rear part, once the train has parted
    pipe_bar: float = bp.NOMINAL_BAR  # its brake pipe (both ends: the reduction's travel is neglected)
    vent_from_s: float | None = None  # a rear part: its pipe vents from then (the break's wave at the EOT)
    alarms_s: list[float] = field(default_factory=list)  # the EOT unit's emergency statuses still to send

    @property
    def tail_m(self) -> float:
        return self.x_m - self.direction * self.consist.length_m


@dataclass(frozen=True)
class TruthAxle:
    """One wheel passing one head's centre, as it really happened."""

    train: str
    head: str
    axle: int
    time_ns: int
    speed_mps: float
    direction: int


@dataclass(frozen=True)
class WheelRecord:
    t_ns: int
    head: str
    channel: int
    value: int  # 1 damped, 0 free


@dataclass(frozen=True)
class SentFix:
    """A GNSS fix as a unit sends it (written to NMEA; the radio delivers it, or not, after its latency)."""

    t_ns: int
    train: str
    role: str
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    valid: bool
    brake_pipe_bar: float = math.nan  # the unit's end of the brake pipe (the LoRa payload's version 2)
    emergency: bool = False  # the unit's emergency status: its brake pipe venting, sent at once


@dataclass
class StepResult:
    """What the devices reported in one step (each list in time order), up to ``t_ns``."""

    t_ns: int
    records: list[WheelRecord]  # wheel-sensor onsets and releases, as the heads report them
    heartbeats: list[tuple[int, str]]  # (time, head): each powered head's status record
    health: list[HealthRows]  # the heads' health registers written in this step
    fixes: list[SentFix]  # fixes the units sent (their own logs: NMEA)
    received: list[SentFix]  # fixes the radio delivered (sent earlier, less those it lost), in delivery order


class Console(Protocol):
    """What watches the simulated line: the station's console (console.live.simulated)."""

    def take(self, step: StepResult) -> None:
        """A step's reports."""

    def finish(self) -> None:
        """The run ends: what the console still holds is decided."""

    def section_states(self) -> dict[str, str]:
        """Each section's state as the console shows it."""

    def crossing_events(self) -> dict[str, list[CrossingEvent]]:
        """Each crossing unit's events so far (warnings on and off, alarms)."""


class StationSim:
    """A simulated line: trains, devices, radio, faults and truth.  ``step(dt)`` advances it."""

    def __init__(
        self, layout: Layout, config: SimConfig | None = None, motion: Callable[..., tuple[float, float]] | None = None
    ) -> None:
        if len(layout.track) < 2:
            raise ValueError(f"{layout.source}: the simulator needs a [[track]] polyline")
        if not layout.consists:
            # Found at the first spawn otherwise, mid-run, where it is no longer a clean usage error.
            raise ValueError(f"{layout.source}: the simulator needs [[consists]]")
        spaced = next((h.id for h in layout.heads if any(c.isspace() for c in h.id)), None)
        if spaced is not None:
            # Its sensor_frames.txt line is "<time> <sensor> <frame>": a space in the sensor splits the line.
            raise ValueError(
                f"{layout.source}: head {spaced!r}: the simulator writes head ids into sensor frames,"
                " where a space ends the id; name the head without spaces"
            )
        self.layout = layout
        self.cfg = config or SimConfig()
        self.rng = np.random.default_rng(self.cfg.seed)
        self.t_s = 0.0
        self.proj = TrackProjector(layout.track)
        ch = [p.chainage_m for p in layout.track]
        self.line_start, self.line_end = min(ch), max(ch)
        self.trains: list[SimTrain] = []  # every train so far
        self.active: list[SimTrain] = []  # those still on the line
        self.rears: list[SimTrain] = []  # rear parts of parted trains (they stay where they stopped)
        self._spawned = 0
        self._next_spawn_s = self.cfg.first_train_s
        self.faults: list[Fault] = list(self.cfg.faults)
        self.motion = motion or ato_motion
        # The devices' timing, as the layout the run writes states it (the console reads it there).
        self.devices = line_devices(layout, self.cfg.heartbeat_s, self.cfg.radio)
        self.console_layout = with_devices(layout, self.devices)
        self.period_s = self.devices.gnss_report_period_s
        self.latency_s = self.cfg.radio.latency_s()  # the radio's own delay (the console allows more)
        self._in_flight: list[tuple[int, SentFix]] = []  # fixes the radio is delivering, by delivery time
        self._next_heartbeat_s = 0.0
        self._swallowed: set[tuple[str, int]] = set()  # (head, channel) whose onset a fault removed
        # The truth.
        self.truth_axles: list[TruthAxle] = []
        self.truth_sections: dict[str, list[tuple[int, int]]] = {
            s.id: [(self.cfg.start_ns, 0)] for s in layout.sections
        }
        self.truth_crossings: list[dict[str, object]] = []
        self.truth_partings: list[PartingTruth] = []
        # Reports an eot_loss / head_loss fault kept back, per (train, role): none means it hit no train.
        self.reports_lost: dict[tuple[str, str], int] = {}
        self._crossing_seen: dict[tuple[str, str], dict[str, object]] = {}
        # Everything reported, for the writers.
        self.all_records: list[WheelRecord] = []
        self.heartbeats: list[tuple[int, str]] = []
        self.all_fixes: list[SentFix] = []  # as sent (the units' own logs)
        self.all_received: list[SentFix] = []  # as the radio delivered them (the network's device stream)
        self.sensors = SensorCounts(layout)  # each head's own axle count (for the frame writer)
        self.console: Console | None = None  # what watches the line (attach)
        self.injected: list[tuple[int, Fault]] = [(self.cfg.start_ns + int(f.start_s * NS), f) for f in self.faults]
        period = self.cfg.health_period_s
        if period is None and any(f.kind in ("analog_drift", "disturbance_growth") for f in self.faults):
            period = HealthSettings().period_s
        self.health = (
            None if period is None else HeadHealth(layout, self.faults, self.cfg.seed, HealthSettings(period_s=period))
        )
        self.health_rows: list[HealthRows] = []  # the health registers written, for the writers
        self._unit_rng = np.random.default_rng([self.cfg.seed, 27, 3])  # gnss_decay's losses: their own stream
        self._alarm_rng = np.random.default_rng([self.cfg.seed, 26, 1])  # the EOT units' emergency statuses

    # -- public API --------------------------------------------------------
    @property
    def now_ns(self) -> int:
        return self.cfg.start_ns + round(self.t_s * NS)

    def attach(self, console: Console) -> None:
        """``console`` takes every step's reports from now on."""
        self.console = console

    @property
    def axle_events(self) -> list[Any]:
        """The heads' own counted axles (time_ns, head, direction), for the frame writer."""
        return self.sensors.axles

    def inject(self, fault: Fault) -> None:
        """Add a fault from now on (the live view's fault keys)."""
        self.faults.append(fault)
        self.injected.append((self.now_ns, fault))

    def add_train(self, consist_id: str | None = None, direction: int | None = None) -> SimTrain | None:
        """A train enters now (or as soon as the line allows)."""
        return self._spawn(consist_id, direction)

    def true_count(self, section_id: str) -> int:
        return self.truth_sections[section_id][-1][1]

    def step(self, dt_s: float) -> StepResult:
        """Advance the simulation by ``dt_s`` seconds."""
        t0, t1 = self.t_s, self.t_s + dt_s
        if t1 >= self._next_spawn_s:
            self._spawn(None, None)
            interval = 3600.0 / self.cfg.trains_per_hour
            self._next_spawn_s += interval * float(self.rng.uniform(0.8, 1.2))
        records: list[WheelRecord] = []
        fixes: list[SentFix] = []
        for tr in self.active:
            x0, v0 = tr.x_m, tr.v_mps
            if tr.rear is None and tr.v_mps > 1.0:
                self._parting(tr, t0)
            target = self._target_speed(tr, t0)
            tr.x_m, tr.v_mps = self.motion(tr, target, dt_s, self.cfg)
            self._pipe(tr, (tr.v_mps - v0) / dt_s if dt_s > 0 else 0.0, t1, dt_s)
            if tr.dwell_until_s is not None and t1 >= tr.dwell_until_s:
                tr.dwell_until_s = None
            self._stop_check(tr, t1)
            records += self._wheels(tr, x0, tr.x_m, t0, t1, v0)
            fixes += self._gnss(tr, t0, t1, x0)
            if (tr.direction > 0 and tr.tail_m > self.line_end + 50) or (
                tr.direction < 0 and tr.tail_m < self.line_start - 50
            ):
                tr.done = True
        for rear in self.rears:
            x0, v0 = rear.x_m, rear.v_mps
            if v0 > 0.0:
                before = rear.travelled_m
                rear.travelled_m, rear.v_mps = braking_step(rear.consist, before, v0, dt_s)
                rear.x_m = x0 + rear.direction * (rear.travelled_m - before)
                if rear.v_mps == 0.0:
                    self._rear_stopped(rear, t1)
            self._pipe(rear, 0.0, t1, dt_s)
            records += self._wheels(rear, x0, rear.x_m, t0, t1, v0)
            fixes += self._gnss(rear, t0, t1, x0)
        self.active = [t for t in self.active if not t.done]
        records += self._sensor_faults(t0, t1)
        records = self._reported(records, t0)
        records.sort(key=lambda r: (r.t_ns, r.head, r.channel))
        self.all_records += records
        self.sensors.feed(
            [r.head for r in records],
            [r.channel for r in records],
            [r.t_ns for r in records],
            [r.value for r in records],
        )
        beats = self._heartbeat(t1)
        health: list[HealthRows] = []
        if self.health is not None and self.health.next_s < t1:
            health.append(self.health.until(t1, self.cfg.start_ns))
            self.health_rows += health
        received = self._radio(fixes, t1)
        self.all_fixes += fixes
        self.t_s = t1
        result = StepResult(self.now_ns, records, beats, health, fixes, received)
        if self.console is not None:
            self.console.take(result)
        return result

    def run(
        self,
        duration_s: float,
        dt_s: float = 0.5,
        on_step: Callable[[float], None] | None = None,
        *,
        finish: bool = True,
    ) -> None:
        """Headless: step until ``duration_s``, with larger steps while the line is empty; then
        :meth:`finish` (unless ``finish`` is False: the run goes on later)."""
        while self.t_s < duration_s:
            busy = bool(self.active) or self.t_s + 1.0 >= self._next_spawn_s
            dt = dt_s if busy else min(5.0, max(dt_s, self._next_spawn_s - self.t_s - 1.0))
            dt = min(dt, duration_s - self.t_s)
            self.step(dt)
            if on_step is not None:
                on_step(self.t_s)
        if finish:
            self.finish()

    def run_health_only(self, duration_s: float, on_step: Callable[[float], None] | None = None) -> None:
        """Only the heads' health registers, no trains (``simulate --health-only``): the same rounds a full
        run writes, for runs of weeks over hundreds of heads.  ``on_step`` after each simulated hour."""
        if self.health is None:
            self.health = HeadHealth(self.layout, self.faults, self.cfg.seed, HealthSettings())
        while self.t_s < duration_s:
            self.t_s = min(duration_s, self.t_s + 3600.0)
            self.health_rows.append(self.health.until(self.t_s, self.cfg.start_ns))
            if on_step is not None:
                on_step(self.t_s)

    def finish(self) -> None:
        """The run ends: the heads settle their counts, and the console what it still holds."""
        self.sensors.finish()
        if self.console is not None:
            self.console.finish()

    # -- trains --------------------------------------------------------------
    def _spawn(self, consist_id: str | None, direction: int | None) -> SimTrain | None:
        consists = self.layout.consists
        if not consists:
            raise ValueError(f"{self.layout.source}: the simulator needs [[consists]]")
        k = self._spawned
        consist = next((c for c in consists if c.id == consist_id), consists[k % len(consists)])
        d = direction if direction in (1, -1) else (1 if k % 2 == 0 else -1)
        # Dispatcher rules: no train enters against another still on the line,
        # nor onto the tail of the one before it.
        if not self.entry_clear(d):
            self._next_spawn_s = self.t_s + 30.0
            return None
        name = f"T{k + 1}"
        if self.cfg.fleet > 0:
            name_or_none = self._trainset(k)
            if name_or_none is None:  # every trainset is on the line: the next that comes back goes
                self._next_spawn_s = self.t_s + 30.0
                return None
            name = name_or_none
            if consist_id is None:  # a trainset keeps its consist
                consist = consists[(int(name[1:]) - 1) % len(consists)]
        self._spawned += 1
        start = self.line_start - 300.0 if d > 0 else self.line_end + 300.0
        stops = sorted(((p.to_m - 15.0) if d > 0 else (p.from_m + 15.0) for p in self.layout.platforms), reverse=d < 0)
        tr = SimTrain(name, consist, d, start, 0.0, self.t_s, stops=stops)
        tr.controller = CONTROLLERS[k % len(CONTROLLERS)]
        tr.v_mps = min(self.layout.line_speed_mps, self._limit(tr, start))
        tr.next_head_fix_s = self.t_s + float(self.rng.uniform(0, self.period_s))
        tr.next_eot_fix_s = self.t_s + float(self.rng.uniform(0, self.period_s))
        self.trains.append(tr)
        self.active.append(tr)
        return tr

    def _trainset(self, k: int) -> str | None:
        """The trainset for the k-th trip: the k-th in rotation, else the next one not on the line."""
        busy = {t.id for t in self.active}
        n = self.cfg.fleet
        for j in range(n):
            name = f"T{(k + j) % n + 1}"
            if name not in busy:
                for c in self.layout.crossings:  # a new trip: its truth at each crossing starts again
                    self._crossing_seen.pop((c.code, name), None)
                return name
        return None

    def entry_clear(self, direction: int) -> bool:
        """May a train enter now in this direction (no opposing train, room behind the last one)?"""
        start = self.line_start - 300.0 if direction > 0 else self.line_end + 300.0
        return all(
            t.direction == direction and direction * (t.tail_m - start) >= ENTRY_ROOM_M
            for t in [*self.active, *self.rears]
        )

    def next_direction(self) -> int:
        """The direction the next train would take: with the trains on the line, else alternating."""
        if self.active:
            return self.active[0].direction
        return 1 if self._spawned % 2 == 0 else -1

    def _limit(self, tr: SimTrain, x: float) -> float:
        """The speed limit for the whole train at head position x."""
        lo, hi = sorted((x, x - tr.direction * tr.consist.length_m))
        v = self.layout.line_speed_mps
        for lim in self.layout.speed_limits:
            if lim.to_m > lo and lim.from_m < hi:
                v = min(v, lim.limit_mps)
        return v

    def _target_speed(self, tr: SimTrain, t_s: float) -> float:
        if tr.dwell_until_s is not None:
            return 0.0
        b = self.cfg.brake_mps2 * 0.8  # plan with a margin on the service brake
        v = self._limit(tr, tr.x_m)
        # Lower limits ahead and the next stop: the speed from which the train can still brake.
        for lim in self.layout.speed_limits:
            edge = lim.from_m if tr.direction > 0 else lim.to_m
            dist = tr.direction * (edge - tr.x_m)
            if 0 < dist < 2000 and lim.limit_mps < v:
                v = min(v, math.sqrt(lim.limit_mps**2 + 2 * b * dist))
        if tr.stops:
            dist = tr.direction * (tr.stops[0] - tr.x_m)
            v = min(v, math.sqrt(max(0.0, 2 * b * max(dist - 1.0, 0.0))))
        # Protection: stay 80 m behind the train ahead (or a parted train's rear part, standing).
        for other in [*self.active, *self.rears]:
            if other is tr or other.direction != tr.direction:
                continue
            gap = tr.direction * (other.tail_m - tr.x_m) - 80.0
            if tr.direction * (other.x_m - tr.x_m) > 0:
                v = min(v, math.sqrt(max(0.0, 2 * b * gap)) if gap > 0 else 0.0)
        return v

    def _stop_check(self, tr: SimTrain, t_s: float) -> None:
        if tr.stops and tr.dwell_until_s is None:
            dist = tr.direction * (tr.stops[0] - tr.x_m)
            if dist < 2.0 and tr.v_mps < 0.3:
                tr.v_mps = 0.0
                tr.dwell_until_s = t_s + self.cfg.dwell_s
                tr.stops.pop(0)

    # -- partings ------------------------------------------------------------
    def _parting(self, tr: SimTrain, t_s: float) -> None:
        """Part ``tr`` now if a ``train_parting`` fault says so (it parts while running, under pull)."""
        if not any(f.kind == "train_parting" and f.target == tr.id and f.start_s <= t_s for f in self.faults):
            return
        k = split_axles(tr.consist)
        front, rear_consist = part_consist(tr.consist, k)
        rear_front_m = tr.x_m - tr.direction * tr.consist.axles_m[k]
        rear = SimTrain(
            tr.id,
            rear_consist,
            tr.direction,
            rear_front_m,
            tr.v_mps,
            t_s,
            controller="parted",
            units=(EOT,),
            axle_offset=k,
            next_eot_fix_s=tr.next_eot_fix_s,
            pipe_bar=tr.pipe_bar,
            # The hoses part: the rear part's pipe vents from the break, the wave reaching its EOT unit
            # after the rear part's length.
            vent_from_s=t_s + rear_consist.length_m / bp.WAVE_MPS,
        )
        tr.consist, tr.units, tr.rear = front, (HEAD,), rear
        self.rears.append(rear)
        self.truth_partings.append(
            PartingTruth(tr.id, self.cfg.start_ns + round(t_s * NS), tr.v_mps, tr.x_m, k, len(rear_consist.axles_m))
        )

    def _pipe(self, tr: SimTrain, accel_mps2: float, t1: float, dt_s: float) -> None:
        """The train's brake pipe after a step: lowered for service braking, vented from ``vent_from_s``;
        the EOT unit, seeing it vent, queues its emergency status (sent at once, repeated)."""
        before = tr.pipe_bar
        if tr.vent_from_s is not None and t1 >= tr.vent_from_s:
            tr.pipe_bar = max(0.0, before - bp.VENT_BAR_S * dt_s)
        else:
            service = min(1.0, max(0.0, -accel_mps2 / bp.FULL_SERVICE_MPS2))
            want = bp.NOMINAL_BAR - bp.FULL_SERVICE_DROP_BAR * service
            rate = bp.SERVICE_BAR_S if want < before else bp.RECHARGE_FRONT_BAR_S
            tr.pipe_bar = max(want, before - rate * dt_s) if want < before else min(want, before + rate * dt_s)
        seen = dt_s > 0 and (before - tr.pipe_bar) / dt_s > bp.ALARM_FALL_BAR_S
        if seen and EOT in tr.units and not tr.alarms_s and tr.vent_from_s is not None:
            tr.alarms_s = [t1 + k * bp.ALARM_GAP_S for k in range(bp.ALARM_REPEATS)]

    def _rear_stopped(self, rear: SimTrain, t_s: float) -> None:
        for rec in self.truth_partings:
            if rec.train == rear.id and rec.t_rear_stopped_ns is None:
                rec.t_rear_stopped_ns = self.cfg.start_ns + round(t_s * NS)
                rec.rear_stop_front_m, rec.rear_stop_tail_m = rear.x_m, rear.tail_m

    # -- counting heads -------------------------------------------------------
    def _wheels(self, tr: SimTrain, x0: float, x1: float, t0: float, t1: float, v0: float) -> list[WheelRecord]:
        """Onsets and releases of every coil the train's wheels passed in this step."""
        out: list[WheelRecord] = []
        if x1 == x0:
            return out
        axles = np.asarray(tr.consist.axles_m)
        d = tr.direction
        # The wheels run from the head back to the tail, behind the direction of travel.
        ends = (x0, x1, x0 - d * tr.consist.length_m, x1 - d * tr.consist.length_m)
        lo, hi = min(ends) - 1, max(ends) + 1
        for head in self.layout.heads:
            if not lo <= head.chainage_m <= hi:
                continue
            for t, ch, value in coil_edges(
                head.chainage_m, head.spacing_m, head.up_is_first_channel_first, axles, d, x0, x1, t0, t1
            ):
                out.append(WheelRecord(self.cfg.start_ns + int(t * NS), head.id, ch, value))
            # The truth: each wheel passing the head's centre.
            p0, p1 = x0 - d * axles, x1 - d * axles
            passed = (d * (p0 - head.chainage_m) < 0) & (d * (p1 - head.chainage_m) >= 0)
            for k in np.flatnonzero(passed):
                frac = (head.chainage_m - p0[k]) / (p1[k] - p0[k])
                axle = tr.axle_offset + int(k)
                self._truth_axle(tr, head.id, axle, t0 + frac * (t1 - t0), v0 + (tr.v_mps - v0) * frac)
        return out

    def _truth_axle(self, tr: SimTrain, head: str, axle: int, t_s: float, v: float) -> None:
        t_ns = self.cfg.start_ns + int(t_s * NS)
        self.truth_axles.append(TruthAxle(tr.id, head, axle, t_ns, v, tr.direction))
        for sec, sign in self.layout.sections_of(head):
            n = self.truth_sections[sec.id][-1][1] + sign * tr.direction
            self.truth_sections[sec.id].append((t_ns, n))

    def _sensor_faults(self, t0: float, t1: float) -> list[WheelRecord]:
        """Records that faults add: isolated pulses and damped heads."""
        out = []
        for f in self.faults:
            if f.kind == "isolated_pulse" and t0 <= f.start_s < t1:
                t = self.cfg.start_ns + int(f.start_s * NS)
                out += [WheelRecord(t, f.target, f.channel, 1), WheelRecord(t + NS // 5, f.target, f.channel, 0)]
            elif f.kind == "damped_head":
                if t0 <= f.start_s < t1:
                    out.append(WheelRecord(self.cfg.start_ns + int(f.start_s * NS), f.target, f.channel, 1))
                if t0 <= f.end_s < t1:
                    out.append(WheelRecord(self.cfg.start_ns + int(f.end_s * NS), f.target, f.channel, 0))
        return out

    def _reported(self, records: list[WheelRecord], t0: float) -> list[WheelRecord]:
        """What the heads report, after dead channels, power loss and missed detections.

        A damping whose onset a fault swallowed loses its release too (even in
        a later step): a head never reports freeing a coil it never reported
        damped.
        """
        keep = []
        for r in sorted(records, key=lambda r: r.t_ns):
            key = (r.head, r.channel)
            if r.value == 0 and key in self._swallowed:
                self._swallowed.discard(key)
                continue
            t_s = (r.t_ns - self.cfg.start_ns) / NS
            drop = False
            for f in self.faults:
                if f.target != r.head or not f.active(t_s):
                    continue
                if f.kind == "power_loss" or (f.kind == "dead_channel" and f.channel == r.channel):
                    drop = True
                elif f.kind == "missed_detections" and f.channel == r.channel and r.value == 1:
                    drop = bool(self.rng.random() < f.probability)
            if drop and r.value == 1:
                self._swallowed.add(key)
            elif not drop:
                keep.append(r)
        return keep

    def _heartbeat(self, t1: float) -> list[tuple[int, str]]:
        """Each powered head's status records up to ``t1`` (a head without power writes none)."""
        beats = []
        while self._next_heartbeat_s <= t1:
            t = self._next_heartbeat_s
            for h in self.layout.heads:
                dark = any(f.kind == "power_loss" and f.target == h.id and f.active(t) for f in self.faults)
                if not dark:
                    beats.append((self.cfg.start_ns + int(t * NS), h.id))
            self._next_heartbeat_s += self.cfg.heartbeat_s
        self.heartbeats += beats
        return beats

    # -- GNSS units -------------------------------------------------------------
    def _gnss(self, tr: SimTrain, t0: float, t1: float, x0: float) -> list[SentFix]:
        out = []
        for role in tr.units:
            attr = "next_head_fix_s" if role == HEAD else "next_eot_fix_s"
            while getattr(tr, attr) < t1:
                t = getattr(tr, attr)
                setattr(tr, attr, t + self.period_s)
                lost = any(
                    f.kind == ("head_loss" if role == HEAD else "eot_loss") and f.target == tr.id and f.active(t)
                    for f in self.faults
                )
                if lost and t >= t0:
                    key = (str(tr.id), role)
                    self.reports_lost[key] = self.reports_lost.get(key, 0) + 1
                if lost or t < t0:
                    continue
                p_lost = unit_loss(self.faults, f"{tr.id}-{role}", t)
                if p_lost > 0 and self._unit_rng.random() < p_lost:
                    continue  # a wearing unit (gnss_decay): the report is never sent
                frac = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
                head_x = x0 + frac * (tr.x_m - x0)
                x = head_x if role == HEAD else head_x - tr.direction * tr.consist.length_m
                out.append(self._sent(tr, role, t, x))
        # The EOT unit's emergency statuses due in this step: each a fresh report, the flag set.
        while tr.alarms_s and tr.alarms_s[0] < t1 and EOT in tr.units:
            t = max(tr.alarms_s.pop(0), t0)
            if any(f.kind == "eot_loss" and f.target == tr.id and f.active(t) for f in self.faults):
                continue
            frac = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
            x = x0 + frac * (tr.x_m - x0) - tr.direction * tr.consist.length_m
            out.append(self._sent(tr, EOT, t, x, emergency=True))
        return out

    def _sent(self, tr: SimTrain, role: str, t: float, x: float, emergency: bool = False) -> SentFix:
        rng = self._alarm_rng if emergency else self.rng  # the periodic fixes' draws are as they were
        plat, plon = self.proj.position(x)
        lat = float(plat[0]) + float(rng.normal(0, self.cfg.gnss_noise_m)) / self.proj.m_per_deg_lat
        lon = float(plon[0]) + float(rng.normal(0, self.cfg.gnss_noise_m)) / self.proj.m_per_deg_lon
        course = (self.proj.bearing_deg(x) + (0.0 if tr.direction > 0 else 180.0)) % 360.0
        speed = max(0.0, tr.v_mps + float(rng.normal(0, 0.1)))
        bar = round(tr.pipe_bar * 20) / 20  # the payload's 0.05 bar
        return SentFix(self.cfg.start_ns + int(t * NS), tr.id, role, lat, lon, speed, course, True, bar, emergency)

    def _radio(self, sent: list[SentFix], t1: float) -> list[SentFix]:
        """The radio: it loses some of the fixes sent and delivers the others after its latency; those due by
        ``t1``, in delivery order.  (The truth at the crossings is noted here too, once per step.)"""
        latency_ns = int(self.latency_s * NS)
        for f in sent:
            if self.rng.random() < self.cfg.gnss_loss:
                continue
            self._in_flight.append((f.t_ns + latency_ns, f))
        self._in_flight.sort(key=lambda x: x[0])
        now = self.cfg.start_ns + int(t1 * NS)
        due = 0
        while due < len(self._in_flight) and self._in_flight[due][0] <= now:
            due += 1
        received = [f for _, f in self._in_flight[:due]]
        del self._in_flight[:due]
        self.all_received += received
        self._truth_crossings(t1)
        return received

    def _truth_crossings(self, t1: float) -> None:
        half = CROSSING_HALF_WIDTH_M
        now = self.cfg.start_ns + round(t1 * NS)
        on_line = [*self.active, *(t for t in self.trains if t.rear is not None and t not in self.active)]
        for c in self.layout.crossings:
            for tr in on_line:
                tail_m = tr.rear.tail_m if tr.rear is not None else tr.tail_m
                key = (c.code, tr.id)
                rec = self._crossing_seen.get(key)
                if rec is None:
                    rec = self._crossing_seen[key] = {
                        "crossing": c.code,
                        "train": tr.id,
                        "t_head_arrival_ns": None,
                        "t_tail_clear_ns": None,
                    }
                    self.truth_crossings.append(rec)
                if rec["t_head_arrival_ns"] is None and tr.direction * (tr.x_m - c.chainage_m) >= -half:
                    rec["t_head_arrival_ns"] = now
                if rec["t_tail_clear_ns"] is None and tr.direction * (tail_m - c.chainage_m) >= half:
                    rec["t_tail_clear_ns"] = now


def coil_edges(
    head_m: float,
    spacing_m: float,
    sys1_first_up: bool,
    axles_m: np.ndarray,
    direction: int,
    x0: float,
    x1: float,
    t0: float,
    t1: float,
    zone_m: float = DETECTION_ZONE_M,
) -> list[tuple[float, int, int]]:
    """(time s, channel, 1 onset / 0 release) of every coil edge the wheels cross while the
    head of the train moves from x0 to x1 between t0 and t1 (linear inside the step).

    Sys1 sits on the side an up train reaches first when the head is "Sys1 first up"; a
    wheel damps a coil while within ``zone_m / 2`` of it.
    """
    half = spacing_m / 2
    c1 = head_m - half if sys1_first_up else head_m + half
    coils = ((SYS1, c1), (SYS2, 2 * head_m - c1))
    d = direction
    p0, p1 = x0 - d * axles_m, x1 - d * axles_m
    out = []
    for ch, c in coils:
        for edge, value in ((c - d * zone_m / 2, 1), (c + d * zone_m / 2, 0)):
            crossed = (d * (p0 - edge) < 0) & (d * (p1 - edge) >= 0)
            for k in np.flatnonzero(crossed):
                frac = (edge - p0[k]) / (p1[k] - p0[k])
                out.append((t0 + frac * (t1 - t0), ch, value))
    return out


CONTROLLERS = ("pid", "fuzzy", "fuzzy-d")


def ato_motion(tr: SimTrain, target_mps: float, dt_s: float, cfg: SimConfig) -> tuple[float, float]:
    """The train under its ATO controller on the force model (seed 001), on a level, straight line."""
    from console.sim.ato import Driver

    if tr.driver is None:
        tr.driver = Driver(scaled_train(tr.consist.length_m), tr.controller)
    state = tr.driver.step(LEVEL_LINE, TrainState(tr.travelled_m, tr.v_mps), target_mps, dt_s)
    step_m = state.x_m - tr.travelled_m
    tr.travelled_m = state.x_m
    return tr.x_m + tr.direction * step_m, state.v_mps


def kinematic_motion(tr: SimTrain, target_mps: float, dt_s: float, cfg: SimConfig) -> tuple[float, float]:
    """A bounded-acceleration point mass following the target speed (the default motion)."""
    v0 = tr.v_mps
    dv = target_mps - v0
    a = min(cfg.accel_mps2, dv / dt_s) if dv > 0 else max(-cfg.brake_mps2, dv / dt_s)
    v1 = max(0.0, v0 + a * dt_s)
    x1 = tr.x_m + tr.direction * 0.5 * (v0 + v1) * dt_s
    return x1, v1
