"""The simulated line: trains, counting heads, GNSS units, the radio, faults, and the truth.

:class:`StationSim` is the world only, deterministic for a seed and advanced
by one call, :meth:`StationSim.step` (the live view calls it; tests step it
by hand).  Each step:

1. trains move under their speed control along the speed limits, platform
   stops and the train ahead (a simple protection rule keeps followers
   behind and opposing trains off the line: :mod:`console.sim.train_motion`);
   a train parts on demand, its rear part braking to a stop
   (:mod:`console.sim.parting`);
2. every wheel passing a counting head damps Sys1 and Sys2 over the
   detection zone: onset and release times are interpolated exactly inside
   the step; faults on demand alter what the heads *report* (a head without
   power reports nothing, status records included: :mod:`console.sim.head_reports`);
3. each head's device writes a status record every heartbeat, and counts its
   own axles as an intelligent sensor does (:mod:`console.sim.sensor_count`);
4. head and EOT GNSS units send fixes every radio report period (LoRa duty
   cycle), with noise; the radio loses some and delivers the rest after its
   latency (:mod:`console.sim.gnss_units`);
5. the **truth** (every axle at every head, true section occupancy, true
   head and tail times at crossings) is kept beside it, here.

The settings and the values passed between these parts are in :mod:`console.sim.line_values`.

What the devices reported in a step (:class:`StepResult`) goes to the
console watching the line, when one is attached (:meth:`StationSim.attach`):
the station's console is the live engine, fed those reports as the written
files would feed ``trackside follow`` (:mod:`console.live.simulated`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from console.analysis.crossing.values import ControllerSettings
from console.analysis.geo import TrackProjector
from console.layout import Layout
from console.sim.devices import line_devices, with_devices
from console.sim.faults import Fault
from console.sim.gnss_units import radio_delivery, unit_fixes
from console.sim.head_reports import fault_records, heartbeats_until, reported_records, wheel_edges
from console.sim.line_values import Console, SentFix, SimConfig, SimTrain, StepResult, TruthAxle, WheelRecord
from console.sim.parting import PartingTruth, brake_pipe_step, braking_step, part_train
from console.sim.sensor_count import SensorCounts
from console.sim.slow_faults import HeadHealth, HealthRows, HealthSettings
from console.sim.train_motion import CONTROLLERS, ato_motion, speed_limit_mps, stop_check, target_speed_mps
from parsers.units import NS

# The truth's head arrival and tail clearance at a crossing: at the road's half width (the crossing units' figure).
CROSSING_HALF_WIDTH_M = ControllerSettings().crossing_half_width_m
ENTRY_ROOM_M = 400.0  # a new train enters only this far behind the tail of the one before it


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
            target = target_speed_mps(self.layout, tr, t0, self.cfg.brake_mps2, [*self.active, *self.rears])
            tr.x_m, tr.v_mps = self.motion(tr, target, dt_s, self.cfg)
            brake_pipe_step(tr, (tr.v_mps - v0) / dt_s if dt_s > 0 else 0.0, t1, dt_s)
            if tr.dwell_until_s is not None and t1 >= tr.dwell_until_s:
                tr.dwell_until_s = None
            stop_check(tr, t1, self.cfg.dwell_s)
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
            brake_pipe_step(rear, 0.0, t1, dt_s)
            records += self._wheels(rear, x0, rear.x_m, t0, t1, v0)
            fixes += self._gnss(rear, t0, t1, x0)
        self.active = [t for t in self.active if not t.done]
        records += fault_records(self.faults, self.cfg.start_ns, t0, t1)
        records = reported_records(records, self.faults, self.cfg.start_ns, self._swallowed, self.rng)
        records.sort(key=lambda r: (r.t_ns, r.head, r.channel))
        self.all_records += records
        self.sensors.feed(
            [r.head for r in records],
            [r.channel for r in records],
            [r.t_ns for r in records],
            [r.value for r in records],
        )
        beats, self._next_heartbeat_s = heartbeats_until(
            self.layout, self.faults, self.cfg.start_ns, self._next_heartbeat_s, self.cfg.heartbeat_s, t1
        )
        self.heartbeats += beats
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
        tr.v_mps = min(self.layout.line_speed_mps, speed_limit_mps(self.layout, tr, start))
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

    # -- partings ------------------------------------------------------------
    def _parting(self, tr: SimTrain, t_s: float) -> None:
        """Part ``tr`` now if a ``train_parting`` fault says so: its rear part stays on the line, braking."""
        parted = part_train(tr, t_s, self.faults, self.cfg.start_ns)
        if parted is not None:
            rear, truth = parted
            self.rears.append(rear)
            self.truth_partings.append(truth)

    def _rear_stopped(self, rear: SimTrain, t_s: float) -> None:
        for rec in self.truth_partings:
            if rec.train == rear.id and rec.t_rear_stopped_ns is None:
                rec.t_rear_stopped_ns = self.cfg.start_ns + round(t_s * NS)
                rec.rear_stop_front_m, rec.rear_stop_tail_m = rear.x_m, rear.tail_m

    # -- counting heads and the truth at them -----------------------------------
    def _wheels(self, tr: SimTrain, x0: float, x1: float, t0: float, t1: float, v0: float) -> list[WheelRecord]:
        """Onsets and releases of every coil the train's wheels passed in this step (the truth noted)."""
        out, passages = wheel_edges(self.layout, self.cfg.start_ns, tr, x0, x1, t0, t1, v0)
        for head, axle, t_s, v in passages:
            self._truth_axle(tr, head, axle, t_s, v)
        return out

    def _truth_axle(self, tr: SimTrain, head: str, axle: int, t_s: float, v: float) -> None:
        t_ns = self.cfg.start_ns + int(t_s * NS)
        self.truth_axles.append(TruthAxle(tr.id, head, axle, t_ns, v, tr.direction))
        for sec, sign in self.layout.sections_of(head):
            n = self.truth_sections[sec.id][-1][1] + sign * tr.direction
            self.truth_sections[sec.id].append((t_ns, n))

    # -- GNSS units, the radio, and the truth at the crossings --------------------
    def _gnss(self, tr: SimTrain, t0: float, t1: float, x0: float) -> list[SentFix]:
        return unit_fixes(
            tr,
            t0,
            t1,
            x0,
            faults=self.faults,
            period_s=self.period_s,
            proj=self.proj,
            noise_m=self.cfg.gnss_noise_m,
            start_ns=self.cfg.start_ns,
            reports_lost=self.reports_lost,
            rng=self.rng,
            unit_rng=self._unit_rng,
            alarm_rng=self._alarm_rng,
        )

    def _radio(self, sent: list[SentFix], t1: float) -> list[SentFix]:
        """The fixes the radio delivers by ``t1``.  (The truth at the crossings is noted here too, once per
        step.)"""
        now = self.cfg.start_ns + int(t1 * NS)
        received = radio_delivery(sent, self._in_flight, now, self.latency_s, self.cfg.gnss_loss, self.rng)
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
