"""Randomized runs of one train along a long line, whole or parted, with a ground truth.

Each run: a train (a consist of vehicles, each with its axles) runs up or
down a 250 km line with counting heads every 1.2–3 km (sections between
them), cruising, changing speed, stopping at stations, now and then making
an emergency stop whole.  Its head and EOT units report GNSS fixes every
``period_s`` (0.1–2.5 Hz) with along-track noise σ ≤ 5 m, Doppler speed
noise, packet loss ≤ 30 %, radio latency, unit clock offsets and, in half
the runs, position jumps (50 m to 2 km along the track).  The counting
heads count every axle that passes; a section engine turns the counts into
section states.

* **parted**: at a random moment while running, the train parts at a random
  coupling; the rear part, carrying the EOT unit, brakes to a stop on the
  simulator's force model (:mod:`console.sim.dynamics`, full service brake
  on the rear part's mass, as a vented brake pipe applies), while the head
  part runs on as planned;
* **whole**: the train stays whole for the whole run (the false-alarm
  hours);
* **eot_loss**: whole, but the EOT unit falls silent for good at a random
  moment.

In most runs (``brake_pipe``) the units also report their brake-pipe
pressure (:mod:`console.sim.brake_pipe`): the head the front's, the EOT
the rear's, in every report (so with the fixes' loss and latency); the EOT
unit sends an emergency status at once when its pipe vents, repeated, each
transmission lost or delayed on its own.  The other runs are units that
report no pressure (plain NMEA trackers): GNSS and the counters only.

The motion is piecewise constant acceleration, evaluated with numpy; the
monitor (:class:`~console.analysis.integrity.monitor.IntegrityMonitor`, the one the
console runs) is fed every fix, axle and section change in the order the
console receives them.  :func:`judge` compares its events with the truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.integrity.monitor import IntegrityMonitor
from console.analysis.integrity.values import (
    DOUBTFUL,
    EOT,
    HEAD,
    PARTED,
    ConsistSpec,
    IntegrityEvent,
    IntegritySettings,
)
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState
from console.layout import Layout, layout_from_dict
from console.sim import brake_pipe as bp
from console.sim.dynamics import LEVEL_LINE, TrainState, scaled_train, step
from parsers.units import NS

KINDS = ("parted", "whole", "eot_loss")
RATES_HZ = (2.5, 1.0, 0.5, 0.2, 0.1)
LINE_M = 250_000.0
DT_S = 0.2  # motion grid
START_NS = 1_772_438_400 * NS
BRAKE_PIPE_SHARE = 0.7  # runs whose units report the brake pipe
# An input as the console receives it: (reception ns, 0 fix | 1 axle | 2 brake pipe,
# (role or head, time ns, chainage m or bar, speed m/s)).
Item = tuple[int, int, tuple[str, int, float, float]]


@dataclass(frozen=True)
class Vehicle:
    length_m: float
    axles_m: tuple[float, ...]  # from the vehicle's front


def _vehicles(kind: str, n: int) -> list[Vehicle]:
    if kind == "unit":  # multiple-unit cars: two bogies of two axles
        return [Vehicle(20.0, (2.5, 5.0, 15.0, 17.5)) for _ in range(n)]
    loco = Vehicle(20.0, (2.0, 4.0, 6.0, 14.0, 16.0, 18.0))
    return [loco] + [Vehicle(14.0, (1.5, 3.3, 10.7, 12.5)) for _ in range(n)]


# (name, kind, vehicles after the first): a 2-car and a 4-car unit, two freight trains.
CONSISTS = (("unit2", "unit", 2), ("unit4", "unit", 4), ("freight20", "freight", 20), ("freight40", "freight", 40))


@dataclass(frozen=True)
class Train:
    name: str
    axles_m: np.ndarray  # from the first wheel
    couplings: tuple[int, ...]  # number of axles before each coupling

    @property
    def length_m(self) -> float:
        return float(self.axles_m[-1])


def make_train(name: str) -> Train:
    _, kind, n = next(c for c in CONSISTS if c[0] == name)
    axles: list[float] = []
    couplings: list[int] = []
    front = 0.0
    for v in _vehicles(kind, n):
        if axles:
            couplings.append(len(axles))
        axles += [front + a for a in v.axles_m]
        front += v.length_m
    arr = np.array(axles) - axles[0]
    return Train(name, arr, tuple(couplings))


def line_layout(seed: int = 7) -> Layout:
    """The harness's line: counting heads every 1.2–3 km over 250 km, a section between each pair."""
    rng = np.random.default_rng(seed)
    gaps = rng.uniform(1200, 3000, int(LINE_M / 1200))
    ch = np.cumsum(gaps)
    ch = ch[ch < LINE_M - 1000]
    heads = [{"id": f"H{k}", "chainage_m": float(c)} for k, c in enumerate(ch)]
    sections = [
        {"id": f"S{k}", "bounds": [{"head": f"H{k}", "sign": 1}, {"head": f"H{k + 1}", "sign": -1}]}
        for k in range(len(ch) - 1)
    ]
    return layout_from_dict({"line": {"name": "integrity harness"}, "heads": heads, "sections": sections}, "harness")


@dataclass(frozen=True)
class Conditions:
    kind: str = "parted"
    period_s: float = 1.0
    noise_m: float = 3.0
    speed_noise_mps: float = 0.1
    loss: float = 0.1
    latency_s: float = 1.0  # the most a fix takes to arrive
    clock_offset_s: float = 0.2  # each unit's clock is off by up to this
    jump_rate: float = 0.0
    consist: str = "unit4"
    direction: int = 1
    vmax_mps: float = 25.0
    duration_s: float = 900.0
    parting_after_s: float = 300.0  # parted: the earliest moment it may part
    eot_fails_at_s: float | None = None
    seed: int = 0
    brake_pipe: bool = False  # the units report the brake-pipe pressure (and the EOT its emergencies)


@dataclass
class Plan:
    """Piecewise constant acceleration: phase k starts at t[k] with speed v[k], position s[k], accel a[k]."""

    t: np.ndarray
    v: np.ndarray
    s: np.ndarray
    a: np.ndarray

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 1)
        dt = times - self.t[k]
        return self.s[k] + self.v[k] * dt + 0.5 * self.a[k] * dt * dt, self.v[k] + self.a[k] * dt

    def accel_at(self, times: np.ndarray) -> np.ndarray:
        return self.a[np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 1)]


def make_plan(rng: np.random.Generator, vmax: float, duration_s: float) -> Plan:
    """A driver's run: cruise, change speed, stop at stations, now and then an emergency stop."""
    phases: list[tuple[float, float]] = []  # (accel, duration)
    v = float(rng.uniform(0, vmax)) if rng.random() < 0.7 else 0.0
    v0 = v
    emergency = False
    while sum(p[1] for p in phases) < duration_s:
        r = rng.random()
        if v == 0.0:
            # dwell; after an emergency stop at least the brake's hold and the pipe's recharge
            dwell = float(rng.uniform(20, 120))
            phases.append((0.0, max(dwell, bp.HOLD_S + 30.0) if emergency else dwell))
            emergency = False
            target = float(rng.uniform(5, vmax))
            a = float(rng.uniform(0.3, 1.0))
        elif r < 0.25:
            target, a = 0.0, -float(rng.uniform(0.5, 1.0))  # a station stop
        elif r < 0.28:
            target, a = 0.0, -float(rng.uniform(1.2, 1.5))  # an emergency stop, the train whole
            emergency = True
        else:
            target = float(rng.uniform(5, vmax))
            a = float(rng.uniform(0.3, 1.0)) if target > v else -float(rng.uniform(0.4, 1.0))
        if target != v:
            phases.append((a, (target - v) / a))
            v = target
        if v > 0:
            phases.append((0.0, float(rng.uniform(30, 300))))  # cruise
    phases.append((0.0, duration_s))  # whatever runs past the end holds its speed
    acc = np.array([p[0] for p in phases])
    dur = np.array([p[1] for p in phases])
    t0 = np.r_[0.0, np.cumsum(dur)[:-1]]
    v_start = v0 + np.r_[0.0, np.cumsum(acc * dur)[:-1]]
    v_start = np.maximum(v_start, 0.0)
    s0 = np.r_[0.0, np.cumsum(v_start * dur + 0.5 * acc * dur * dur)[:-1]]
    return Plan(t0, v_start, s0, acc)


def rear_braking(train_len_m: float, v0: float) -> tuple[np.ndarray, np.ndarray]:
    """(distance run, speed) of a parted rear part every DT_S from ``v0`` to a stop, on the force model."""
    model = scaled_train(max(train_len_m, 1.0))
    state = TrainState(0.0, v0)
    xs, vs = [0.0], [v0]
    while state.v_mps > 0.0 and len(xs) < 10_000:  # one RK4 step per 0.2 s: a few hundred at most
        state = step(model, LEVEL_LINE, state, -1.0, DT_S)
        xs.append(state.x_m)
        vs.append(state.v_mps)
    return np.array(xs), np.array(vs)


@dataclass
class Truth:
    parting_ns: int | None = None
    parting_s_m: float | None = None
    rear_axles: int = 0
    rear_stop_m: float | None = None  # chainage of the rear part's EOT where it stopped
    eot_fails_ns: int | None = None
    fixes_in_window: int = 0  # EOT fixes received measured within 2 report periods of the parting
    hours: float = 0.0
    vent_s: float | None = None  # brake pipe: the parting → the vent reaching the EOT unit


@dataclass
class RunResult:
    cond: Conditions
    truth: Truth
    events: list[IntegrityEvent] = field(default_factory=list)
    items: list[Item] = field(default_factory=list)  # the monitor's inputs, in the order it got them


def _first_passing(s_grid: np.ndarray, t_grid: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """First time the (non-decreasing) position reaches each target, interpolated; NaN if never."""
    k = np.searchsorted(s_grid, targets, side="left")
    ok = (k > 0) & (k < len(s_grid))
    kk = np.clip(k, 1, len(s_grid) - 1)
    s0, s1 = s_grid[kk - 1], s_grid[kk]
    frac = np.where(s1 > s0, (targets - s0) / np.where(s1 > s0, s1 - s0, 1.0), 1.0)
    t = t_grid[kk - 1] + np.clip(frac, 0, 1) * (t_grid[kk] - t_grid[kk - 1])
    return np.where(ok, t, np.nan)


def simulate(layout: Layout, cond: Conditions, monitor: bool = True) -> RunResult:
    """One run: the motion, the fixes and axles as the console receives them, the monitor's events.

    ``monitor``: False for the inputs alone (no events): a caller that drives its own monitor on them.
    """
    rng = np.random.default_rng(cond.seed)
    train = make_train(cond.consist)
    L = train.length_m
    plan = make_plan(rng, cond.vmax_mps, cond.duration_s)
    t_grid = np.arange(0.0, cond.duration_s + DT_S, DT_S)
    s_head, v_head = plan.at(t_grid)
    d = cond.direction
    # The train starts before the first counting head on its way (the line is known empty).
    ends = (layout.heads[0].chainage_m, layout.heads[-1].chainage_m)
    x0 = ends[0] - 500.0 if d > 0 else ends[1] + 500.0
    truth = Truth(hours=cond.duration_s / 3600.0)
    # The EOT's position along the run (s coordinate): a train length behind, until a parting.
    s_eot, v_eot = s_head - L, v_head.copy()
    rear_idx = np.arange(0)
    part_k = None
    rear_part_m = 0.0
    if cond.kind == "parted":
        # Couplings part under drawbar pull (running or accelerating), not while braking in buff.
        pulling = plan.accel_at(t_grid) >= 0
        # ... early enough to watch what follows: 20 report periods, and two minutes at least.
        latest = cond.duration_s - max(120.0, 20 * cond.period_s)
        moving = np.flatnonzero((v_head > 2.0) & pulling & (t_grid >= cond.parting_after_s) & (t_grid <= latest))
        if len(moving):
            part_k = int(moving[rng.integers(0, min(len(moving), int(600 / DT_S)))])
    if part_k is not None:
        cut = int(rng.choice(train.couplings))
        rear_idx = np.arange(cut, len(train.axles_m))
        front_len = float(train.axles_m[cut - 1])
        rear_off = float(train.axles_m[cut])  # the rear part's first axle, from the head
        rear_len = L - rear_off
        rear_part_m = rear_len
        truth.vent_s = rear_len / bp.WAVE_MPS
        dist, vel = rear_braking(rear_len, float(v_head[part_k]))
        n_after = len(t_grid) - part_k
        dist = np.r_[dist, np.full(max(0, n_after - len(dist)), dist[-1])][:n_after]
        vel = np.r_[vel, np.zeros(max(0, n_after - len(vel)))][:n_after]
        rear_front = s_head[part_k] - rear_off + dist
        # The rear part cannot run into the head part's last axle.
        rear_front = np.minimum(rear_front, s_head[part_k:] - front_len - 1.0)
        s_eot[part_k:] = rear_front - rear_len
        v_eot[part_k:] = vel
        truth.parting_ns = START_NS + int(t_grid[part_k] * NS)
        truth.parting_s_m = float(s_head[part_k])
        truth.rear_axles = len(rear_idx)
        truth.rear_stop_m = x0 + d * float(s_eot[-1])
    eot_fails = None
    if cond.kind == "eot_loss" and cond.eot_fails_at_s is not None:
        eot_fails = cond.eot_fails_at_s
        truth.eot_fails_ns = START_NS + int(eot_fails * NS)

    items: list[Item] = []  # (console time ns, 0 fix | 1 axle | 2 brake pipe, what)
    pressure = {HEAD: np.zeros(0), EOT: np.zeros(0)}
    prng = np.random.default_rng([cond.seed, 26])  # its own draws: the GNSS of a run is the same without it
    if cond.brake_pipe:
        tp_s = None if part_k is None else float(t_grid[part_k])
        front_bar, rear_bar = bp.pipe(t_grid, plan.accel_at(t_grid), v_head, L, tp_s, rear_part_m)
        pressure = {HEAD: front_bar, EOT: rear_bar}
    # -- GNSS fixes (and the pressure each report carries)
    for role, pos, vel in ((HEAD, s_head, v_head), (EOT, s_eot, v_eot)):
        phase = rng.uniform(0, cond.period_s)
        times = np.arange(phase, cond.duration_s, cond.period_s)
        times = times + rng.normal(0, 0.02, len(times))  # receiver timing jitter
        times = times[(times >= 0) & (times < cond.duration_s)]
        if role == EOT and eot_fails is not None:
            times = times[times < eot_fails]
        times = times[rng.random(len(times)) >= cond.loss]
        ch = np.interp(times, t_grid, pos) + rng.normal(0, cond.noise_m, len(times))
        speed = np.maximum(0.0, np.interp(times, t_grid, vel) + rng.normal(0, cond.speed_noise_mps, len(times)))
        jumped = rng.random(len(times)) < cond.jump_rate
        ch[jumped] += rng.choice([-1.0, 1.0], int(jumped.sum())) * rng.uniform(50, 2000, int(jumped.sum()))
        offset = rng.uniform(-cond.clock_offset_s, cond.clock_offset_s)
        rx = times + rng.uniform(0.05, max(0.05, cond.latency_s), len(times))
        if role == EOT and truth.parting_ns is not None:
            tp = (truth.parting_ns - START_NS) / NS
            truth.fixes_in_window = int(np.sum((times >= tp) & (times <= tp + 2 * cond.period_s)))
        for k in range(len(times)):  # one item per fix: the monitor's input
            items.append(
                (
                    START_NS + int(rx[k] * NS),
                    0,
                    (role, START_NS + int((times[k] + offset) * NS), x0 + d * float(ch[k]), float(speed[k])),
                )
            )
        if cond.brake_pipe:
            bar = bp.reading(prng, np.interp(times, t_grid, pressure[role]))
            items += [
                (START_NS + int(rx[k] * NS), 2, (role, START_NS + int((times[k] + offset) * NS), float(bar[k]), 0.0))
                for k in range(len(times))
            ]
            if role == EOT:
                items += _alarms(prng, cond, t_grid, pressure[EOT], offset, eot_fails)
    # -- axles at the counting heads
    heads = np.array([h.chainage_m for h in layout.heads])
    names = [h.id for h in layout.heads]
    s_at_head = d * (heads - x0)
    ahead = (s_at_head > s_head[0] - L - 1) & (s_at_head < s_head[-1] + 1)
    front_idx = np.arange(len(train.axles_m)) if part_k is None else np.arange(len(train.axles_m) - len(rear_idx))
    for h in np.flatnonzero(ahead):
        times_front = _first_passing(s_head, t_grid, s_at_head[h] + train.axles_m[front_idx])
        times_rear = np.zeros(0)
        if part_k is not None:
            rear_first = s_eot + L - train.axles_m[rear_idx[0]]  # rear part's first axle, whole-train frame
            times_rear = _first_passing(
                np.maximum.accumulate(rear_first),
                t_grid,
                s_at_head[h] + train.axles_m[rear_idx] - train.axles_m[rear_idx[0]],
            )
        for t in np.r_[times_front, times_rear]:
            if not np.isnan(t) and t > 0:
                lag = float(rng.uniform(0.0, 1.0))
                items.append((START_NS + int((t + lag) * NS), 1, (names[h], START_NS + int(t * NS), 0.0, 0.0)))
    items.sort(key=lambda x: (x[0], x[1]))
    events = run_monitor(layout, cond, train, items, d) if monitor else []
    return RunResult(cond, truth, events, items)


def _alarms(
    rng: np.random.Generator,
    cond: Conditions,
    t_grid: np.ndarray,
    rear_bar: np.ndarray,
    offset_s: float,
    fails_s: float | None,
) -> list[Item]:
    """The EOT unit's emergency status, sent at once when its pipe vents and repeated: each
    transmission lost, or delayed, on its own."""
    out: list[Item] = []
    for t_ev in bp.emergency_times(t_grid, rear_bar):
        t_meas = float(t_ev)  # the end of the grid step it fell in
        if fails_s is not None and t_meas >= fails_s:
            continue
        bar = float(bp.reading(rng, np.interp([t_meas], t_grid, rear_bar))[0])
        for j in range(bp.ALARM_REPEATS):
            sent = t_meas + j * bp.ALARM_GAP_S
            lost = rng.random() < cond.loss
            rx = sent + rng.uniform(0.05, max(0.05, cond.latency_s))
            if not lost and sent < cond.duration_s:
                # The speed slot says it is the emergency status (1.0), not a periodic reading (0.0).
                out.append((START_NS + int(rx * NS), 2, (EOT, START_NS + int((t_meas + offset_s) * NS), bar, 1.0)))
    return out


def run_monitor(
    layout: Layout, cond: Conditions, train: Train, items: list[Item], direction: int
) -> list[IntegrityEvent]:
    settings = IntegritySettings(
        report_period_s=cond.period_s, latency_s=cond.latency_s, clock_offset_s=max(cond.clock_offset_s, 0.01)
    )
    mon = IntegrityMonitor(settings, layout)
    mon.add_train(ConsistSpec("T1", train.length_m, len(train.axles_m)))
    engine = SectionEngine(layout, initial=SectionState.CLEAR, start_ns=START_NS)
    out: list[IntegrityEvent] = []
    for rx, kind, item in items:  # the console's inputs, one by one, in the order it gets them
        if kind == 0:
            role, t_fix, ch, v = item
            out += mon.fix(rx, t_fix, "T1", role, ch, v)
        elif kind == 2:
            role, t_meas, bar, alarm = item
            out += mon.brake_pipe(rx, t_meas, "T1", role, bar, emergency=alarm > 0)
        else:
            e = DetectionEvent(item[1], EventKind.AXLE, item[0], direction, source="harness")
            out += mon.detection(e)
            for tr in engine.step(e):
                out += mon.transition(tr)
    if items:
        out += mon.tick(items[-1][0])
    return out


@dataclass(frozen=True)
class Verdict:
    kind: str
    period_s: float
    detected_s: float | None  # parted: parting → the monitor's "parted"
    doubt_s: float | None  # parted: parting → the first state other than whole
    within_target: bool | None  # parted: "parted" ≤ 2 report periods + latency after the parting
    doubt_within_target: bool | None  # parted: doubt (or parted) ≤ 2 report periods + latency
    missed: bool
    false_parted: bool  # a "parted" on a whole train (or before the parting)
    eot_loss_doubt: bool | None  # eot_loss: the loss reported as doubt (and nothing else after)
    fixes_in_window: int
    hours: float
    doubt_hours: float  # time spent doubtful on a whole train
    eot_doubt_s: float | None = None  # eot_loss: the loss → doubt
    brake_pipe: bool = False  # the units reported the brake pipe
    vent_late: bool = False  # the vent reached the EOT later than the target less the clocks' allowance


def judge(res: RunResult) -> Verdict:
    c, tr = res.cond, res.truth
    parted = [e for e in res.events if e.state == PARTED]
    tp = tr.parting_ns
    early = [e for e in parted if tp is None or e.t_ns < tp]
    detected = doubt = None
    within = None
    missed = False
    if c.kind == "parted" and tp is not None:
        late = [e for e in parted if e.t_ns >= tp]
        if late:
            detected = (late[0].t_ns - tp) / NS
            within = detected <= 2 * c.period_s + c.latency_s
        else:
            missed = True
        first = [e for e in res.events if e.t_ns >= tp and e.state != "whole"]
        doubt = (first[0].t_ns - tp) / NS if first else None
        # Doubtful already when it parted (a unit stale, say): doubt from the start.
        before = [e for e in res.events if e.t_ns < tp]
        if before and before[-1].state != "whole":
            doubt = 0.0
    eot_doubt = None
    eot_doubt_s = None
    if c.kind == "eot_loss" and tr.eot_fails_ns is not None:
        # Doubtful from some moment after the loss (or already at it), and nothing else from then
        # to the end. Before that a verdict on its last fixes may still come (whole: it was heard,
        # and was where it should be); how long the doubt took is kept.
        fail = tr.eot_fails_ns
        t_doubt = fail if _state_at(res.events, fail) == DOUBTFUL else None
        if t_doubt is None:
            t_doubt = next((e.t_ns for e in res.events if e.t_ns >= fail and e.state == DOUBTFUL), None)
        eot_doubt = t_doubt is not None and all(e.state == DOUBTFUL for e in res.events if e.t_ns >= t_doubt)
        eot_doubt_s = None if t_doubt is None else (t_doubt - fail) / NS
    # Time spent doubtful before any parting (the whole train's share of doubt).
    end = tp if tp is not None else START_NS + int(c.duration_s * NS)
    doubt_ns = 0
    since = None
    for e in res.events:
        if e.t_ns >= end:
            break
        if e.state == DOUBTFUL and since is None:
            since = e.t_ns
        elif e.state != DOUBTFUL and since is not None:
            doubt_ns += e.t_ns - since
            since = None
    if since is not None:
        doubt_ns += end - since
    hours = ((tp - START_NS) / NS if tp is not None else c.duration_s) / 3600.0
    return Verdict(
        c.kind,
        c.period_s,
        detected,
        doubt,
        within,
        None if doubt is None else doubt <= 2 * c.period_s + c.latency_s,
        missed,
        bool(early),
        eot_doubt,
        tr.fixes_in_window,
        hours,
        doubt_ns / NS / 3600.0,
        eot_doubt_s,
        c.brake_pipe,
        tr.vent_s is not None and tr.vent_s + 2 * c.clock_offset_s > 2 * c.period_s + c.latency_s,
    )


def _state_at(events: list[IntegrityEvent], t_ns: int) -> str | None:
    """The monitor's state at ``t_ns``: its last change at or before then."""
    before = [e.state for e in events if e.t_ns <= t_ns]
    return before[-1] if before else None


def random_conditions(rng: np.random.Generator, seed: int, kind: str | None = None) -> Conditions:
    """Across the issue's ranges: fixes at 0.1–2.5 Hz, noise ≤ 5 m, loss ≤ 30 %, jumps in half the runs."""
    kind = kind or str(rng.choice(KINDS, p=[0.5, 0.35, 0.15]))
    duration = float(rng.uniform(1200, 3600)) if kind != "parted" else float(rng.uniform(600, 1500))
    cond = Conditions(
        kind=kind,
        period_s=1.0 / float(rng.choice(RATES_HZ)),
        noise_m=float(rng.uniform(0, 5)),
        speed_noise_mps=float(rng.uniform(0.05, 0.2)),
        loss=float(rng.uniform(0, 0.3)),
        latency_s=float(rng.uniform(0.2, 2.0)),
        clock_offset_s=0.2,
        jump_rate=float(rng.uniform(0, 0.05)) if rng.random() < 0.5 else 0.0,
        consist=str(rng.choice([c[0] for c in CONSISTS])),
        direction=int(rng.choice([1, -1])),
        vmax_mps=float(rng.uniform(10, 35)),
        duration_s=duration,
        parting_after_s=float(rng.uniform(60, 400)),
        eot_fails_at_s=float(rng.uniform(60, duration - 300)) if kind == "eot_loss" else None,
        seed=seed,
    )
    # Drawn last: the other conditions of a seed's runs are those they were without the brake pipe.
    return replace(cond, brake_pipe=bool(rng.random() < BRAKE_PIPE_SHARE))


def many_runs(
    n: int,
    seed: int,
    layout: Layout | None = None,
    progress: Callable[[int], None] | None = None,
    kind: str | None = None,
) -> list[Verdict]:
    """``n`` runs of random conditions from ``seed`` (the same seed, the same runs); ``kind``: only that kind."""
    lay = layout or line_layout()
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        out.append(judge(simulate(lay, random_conditions(rng, seed * 1_000_003 + k, kind))))
        if progress is not None:
            progress(k + 1)
    return out


def summary(verdicts: list[Verdict]) -> dict[str, object]:
    parted = [v for v in verdicts if v.kind == "parted" and (v.detected_s is not None or v.missed)]
    whole_hours = sum(v.hours for v in verdicts)
    false = sum(v.false_parted for v in verdicts)
    eot = [v.eot_doubt_s for v in verdicts if v.eot_doubt_s is not None]
    return {
        "runs": len(verdicts),
        **_partings(parted),
        # Split: units that report the brake pipe, and units that do not (GNSS and counters only).
        "brake_pipe": _partings([v for v in parted if v.brake_pipe]),
        "gnss_only": _partings([v for v in parted if not v.brake_pipe]),
        "whole_train_hours": whole_hours,
        "false_parted": false,
        "false_parted_per_1000_h": 1000.0 * false / whole_hours if whole_hours else math.nan,
        "false_parted_brake_pipe_hours": sum(v.hours for v in verdicts if v.brake_pipe),
        "false_parted_brake_pipe": sum(v.false_parted for v in verdicts if v.brake_pipe),
        "eot_loss_runs": sum(v.kind == "eot_loss" for v in verdicts),
        "eot_loss_as_doubt": sum(bool(v.eot_loss_doubt) for v in verdicts),
        "eot_loss_doubt_median_s": float(np.median(eot)) if eot else math.nan,
        "eot_loss_doubt_max_s": float(max(eot)) if eot else math.nan,
        "doubt_share_whole": (
            sum(v.doubt_hours for v in verdicts if v.kind != "eot_loss")
            / sum(v.hours for v in verdicts if v.kind != "eot_loss")
        )
        if any(v.kind != "eot_loss" for v in verdicts)
        else math.nan,
    }


def _partings(parted: list[Verdict]) -> dict[str, object]:
    det = [v.detected_s for v in parted if v.detected_s is not None]
    by_rate: dict[str, dict[str, object]] = {}
    for hz in RATES_HZ:
        sel = [v for v in parted if abs(v.period_s - 1 / hz) < 1e-9]
        d = [v.detected_s for v in sel if v.detected_s is not None]
        dd = [v.doubt_s for v in sel if v.doubt_s is not None]
        by_rate[f"{hz:g} Hz"] = {
            "runs": len(sel),
            "within_target": float(np.mean([bool(v.within_target) for v in sel])) if sel else math.nan,
            "doubt_within_target": float(np.mean([bool(v.doubt_within_target) for v in sel])) if sel else math.nan,
            "median_s": float(np.median(d)) if d else math.nan,
            "p90_s": float(np.percentile(d, 90)) if d else math.nan,
            "p99_s": float(np.percentile(d, 99)) if d else math.nan,
            "max_s": float(max(d)) if d else math.nan,
            "doubt_median_s": float(np.median(dd)) if dd else math.nan,
            "doubt_p90_s": float(np.percentile(dd, 90)) if dd else math.nan,
            # No EOT fix measured within 2 report periods of the parting: no GNSS rule could have
            # seen it in time (all lost, or none due yet).
            "no_eot_fix_in_window": sum(v.fixes_in_window == 0 for v in sel),
            # Brake pipe: the vent reached the EOT unit too late for any rule (its travel along the
            # rear part, plus the units' clock allowance, beyond the target).
            "vent_late": sum(v.vent_late for v in sel),
            "within_target_vent_in_time": float(np.mean([bool(v.within_target) for v in sel if not v.vent_late]))
            if any(not v.vent_late for v in sel)
            else math.nan,
        }
    return {
        "parted_runs": len(parted),
        "missed": sum(v.missed for v in parted),
        "within_target": float(np.mean([bool(v.within_target) for v in parted])) if parted else math.nan,
        "median_detection_s": float(np.median(det)) if det else math.nan,
        "vent_late": sum(v.vent_late for v in parted),
        "within_target_vent_in_time": float(np.mean([bool(v.within_target) for v in parted if not v.vent_late]))
        if any(not v.vent_late for v in parted)
        else math.nan,
        "by_rate": by_rate,
    }
