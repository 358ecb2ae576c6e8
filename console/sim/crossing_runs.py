"""Synthetic head and EOT tracks past a level crossing, with a ground truth.

One run: a train of known length runs along the layout towards a crossing and
past it, perhaps stopping before it (a station), crawling, or stopping with
its tail still on the road (the fixed-time method's classic failure).  A head
unit and an EOT unit report GNSS fixes every ``period_s`` with position noise
``noise_m`` (σ, metres, east and north), packet loss ``loss`` and radio
latency; either unit may fail for good at a chosen time.  Exports may carry
no speed at all (as many device exports do: the controller must estimate it
from the positions), and a share of fixes may be position jumps (multipath,
a receiver re-acquiring: displaced along the track by 50 m to 2 km, small
ones look plausible).  The truth gives when the head really reached the road
and when the tail really cleared it.

The crossing controller runs on the received fixes only; :func:`judge`
compares its switching with the truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from console.analysis.crossing.clock import run_controller
from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.timeline import timeline
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, Fix, TrainSpec
from console.analysis.geo import TrackProjector
from console.layout import Layout, LevelCrossing
from console.sim.crossing_yardsticks import Truth, fix_oracle_onset, kinematic_onset, oracle_onset, paper_onset
from parsers.units import NS

SCENARIOS = ("through", "stop_before", "stop_on_crossing", "crawl", "stop_far")
# A train leaving a stop runs up to the line speed at most (the line speed the crossing unit is told);
# only trains already running faster when first seen exceed it.
LINE_SPEED_MPS = 25.0


@dataclass(frozen=True)
class RunConditions:
    period_s: float = 10.0
    noise_m: float = 5.0
    loss: float = 0.0
    latency_s: float = 0.5
    head_fails_at_s: float | None = None  # seconds after the start
    eot_fails_at_s: float | None = None
    scenario: str = "through"
    speed_mps: float = 15.0
    direction: int = 1
    length_m: float = 200.0
    seed: int = 0
    run_past_m: float = 600.0  # how far the head runs on past the crossing
    speed_reported: bool = True  # False: the export has no speed column (NaN), nor a course
    jump_rate: float = 0.0  # share of fixes displaced along the track (position jumps)


def _motion(
    c: LevelCrossing, cond: RunConditions, rng: np.random.Generator, half: float
) -> tuple[np.ndarray, np.ndarray]:
    """(times s, head chainage m) at 0.2 s steps: cruise, brake, dwell, go."""
    d, v0, L = cond.direction, cond.speed_mps, cond.length_m
    brake, accel, dt = 0.6, 0.5, 0.2
    approach = v0 * (cond_horizon := 100.0) + 800.0 + rng.uniform(0, 500)
    stop_at = None  # head chainage (signed distance past the crossing) to stop at
    dwell = rng.uniform(20, 120)
    if cond.scenario == "stop_before":
        stop_at = -rng.uniform(60, 600)  # a platform before the crossing
    elif cond.scenario == "stop_on_crossing":
        stop_at = rng.uniform(half + 5, max(half + 6, L - 2 * half))  # tail still on the road
    elif cond.scenario == "stop_far":
        # A station or a signal 1.5-3 km out: beyond the reach of the crossing within its warning time,
        # from a standstill.  The train is seen running before it brakes there.
        stop_at = -rng.uniform(1500, 3000)
        dwell = rng.uniform(30, 300)
        approach = max(approach, -stop_at + v0 * v0 / (2 * brake) + 200.0 + rng.uniform(0, 500))
    start = c.chainage_m - d * approach
    vmax = 3.0 if cond.scenario == "crawl" else v0
    t, x, v = 0.0, 0.0, vmax  # x: head distance run from start
    ts, xs = [0.0], [0.0]
    stopped_until = None
    # Far enough past for the EOT to report from beyond the crossing a few times, even at 0.1 Hz.
    end = approach + L + max(cond.run_past_m, 10 * cond.period_s * vmax)
    while x < end and t < 3600:
        past = x - approach  # head's signed distance past the crossing
        if stop_at is not None and stopped_until is None and past <= stop_at:
            to_go = stop_at - past
            if v * v / (2 * brake) >= to_go:  # time to brake
                v = max(0.0, v - brake * dt)
            # Stopped at the point: a step that would run past it ends there, braking or creeping the last
            # centimetres (a train that ran past its stop would leave it at its cruising speed, not from a stand).
            if v == 0.0 or to_go < 0.05 or v * dt >= to_go:
                v, stopped_until = 0.0, t + dwell
        elif stopped_until is not None and t < stopped_until:
            v = 0.0
        else:
            v = min(vmax if stopped_until is None else min(vmax, LINE_SPEED_MPS), v + accel * dt)
        x += v * dt
        t += dt
        ts.append(t)
        xs.append(x)
        _ = cond_horizon
    return np.array(ts), start + d * np.array(xs)


@dataclass(frozen=True)
class RawFix:
    """A fix as the device sends it (for writing telemetry files)."""

    t_fix_ns: int
    role: str
    lat: float
    lon: float
    speed_mps: float
    course_deg: float


def simulate(
    layout: Layout,
    crossing: LevelCrossing,
    cond: RunConditions,
    settings: ControllerSettings,
    start_ns: int = 1_700_000_000 * NS,
    raw: list[RawFix] | None = None,
) -> tuple[list[Fix], Truth, TrainSpec]:
    """Fixes as the crossing unit receives them, the truth, the train; ``raw`` collects the sent fixes."""
    rng = np.random.default_rng(cond.seed)
    half = settings.crossing_half_width_m
    ts, head = _motion(crossing, cond, rng, half)
    d, L = cond.direction, cond.length_m
    tail = head - d * L
    t0 = start_ns
    t_ns = (t0 + ts * NS).astype(np.int64)
    c = crossing.chainage_m

    def first(mask: np.ndarray) -> int | None:
        idx = np.flatnonzero(mask)
        return int(t_ns[idx[0]]) if len(idx) else None

    speed = np.gradient(head, ts) * d
    truth = Truth(
        t_ns, head, first(d * (head - c) >= -half), first(d * (tail - c) >= half), direction=d, speed_mps=speed
    )
    proj = TrackProjector(layout.track)
    m_lat, m_lon = proj.m_per_deg_lat, proj.m_per_deg_lon
    fixes: list[Fix] = []
    for role, pos, fails in ((HEAD, head, cond.head_fails_at_s), (EOT, tail, cond.eot_fails_at_s)):
        phase = rng.uniform(0, cond.period_s)
        times = np.arange(phase, ts[-1], cond.period_s)
        times = times + rng.normal(0, 0.05, len(times))  # receiver timing jitter
        times = times[(times >= 0) & (times <= ts[-1])]
        if fails is not None:
            times = times[times < fails]
        keep = rng.random(len(times)) >= cond.loss
        times = times[keep]
        ch = np.interp(times, ts, pos)
        lat, lon = proj.position(ch)
        lat = lat + rng.normal(0, cond.noise_m, len(ch)) / m_lat
        lon = lon + rng.normal(0, cond.noise_m, len(ch)) / m_lon
        v = np.maximum(0.0, np.interp(times, ts, speed) + rng.normal(0, 0.2, len(ch)))
        if not cond.speed_reported:
            v[:] = np.nan
        jumped = rng.random(len(ch)) < cond.jump_rate
        if jumped.any():
            # Along the track, either way, 50 m to 2 km: the small ones are plausible for a train.
            shift = rng.choice([-1.0, 1.0], jumped.sum()) * rng.uniform(50, 2000, jumped.sum())
            jlat, jlon = proj.position(ch[jumped] + shift)
            lat[jumped] = jlat + rng.normal(0, cond.noise_m, len(shift)) / m_lat
            lon[jumped] = jlon + rng.normal(0, cond.noise_m, len(shift)) / m_lon
            truth.jumps += int(jumped.sum())
        p = proj.project(lat, lon)
        latency = rng.uniform(0.1, max(0.1, 2 * cond.latency_s), len(ch))
        bearing = (proj.bearing_deg(float(c)) + (0.0 if d > 0 else 180.0)) % 360.0
        for k in range(len(ch)):  # per fix of one run
            t_fix = t0 + int(times[k] * NS)
            if raw is not None:
                raw.append(RawFix(t_fix, role, float(lat[k]), float(lon[k]), float(v[k]), bearing))
            fixes.append(
                Fix(
                    t_ns=t_fix + int(latency[k] * NS),
                    t_fix_ns=t_fix,
                    train="T1",
                    role=role,
                    chainage_m=float(p.chainage_m[k]),
                    speed_mps=float(v[k]),
                    direction_hint=d if v[k] > 1.0 else 0,  # NaN (no speed): no course either
                )
            )
    return fixes, truth, TrainSpec("T1", L)


@dataclass(frozen=True)
class Verdict:
    violation: str | None  # why the road was open with the train on it, if it was
    lead_s: float | None  # truth head arrival − the warning's onset (the one in effect at the arrival)
    excess_s: float | None  # warning off − truth tail clear (None: held on)
    held: bool  # the warning never ended (no evidence): safe, but the road stays closed
    alarms: int
    baseline_early_s: float | None  # > 0 the fixed-time method opened too early
    warning_time_s: float = 70.0  # the crossing's required lead
    late_by_s: float | None = None  # > 0: on this much short of the warning time (a safety violation)
    jumps_sent: int = 0
    jumps_set_aside: int = 0
    # The oracle (:mod:`console.analysis.crossing.oracle`): the unit's bounds on the true motion.
    oracle_lead_s: float | None = None  # truth head arrival − the oracle's onset (≥ the warning time)
    avoidable_s: float | None = None  # the oracle's onset − the controller's: warned this much early from doubt
    fix_oracle_lead_s: float | None = None  # the same for an oracle that knows the truth at the fixes only
    paper_avoidable_s: float | None = None  # the same for the paper's rule d/v ≤ T at each head fix
    paper_late_by_s: float | None = None  # > 0: the paper's rule came this much short of the warning time
    released: int = 0  # warnings switched off before the head arrived (a train proven out of reach)
    released_on_s: float = 0.0  # how long those warnings had been on, in all
    min_open_s: float | None = None  # the shortest a released road stayed open before the warning came back
    # What `trackside crossing` shows for this warning, judged from the fixes alone (no truth):
    hindsight_physics_s: float | None = None
    hindsight_doubt_s: dict[str, float] | None = None
    # The kinematic yardsticks (:mod:`console.sim.crossing_yardsticks`): their leads.
    exact_lead_s: float | None = None  # the true positions at the fixes, the speed only where reported
    allowance_lead_s: float | None = None  # the measured positions ± the unit's noise allowance, jumps set aside

    def yardstick_avoidable_s(self, lead_s: float | None) -> float | None:
        """How much earlier than the oracle a yardstick with this lead warned."""
        return None if lead_s is None or self.oracle_lead_s is None else lead_s - self.oracle_lead_s

    @property
    def sparse_s(self) -> float | None:
        """What the sparse fixes cost a perfect estimator: the fix-time oracle's lead − the oracle's."""
        if self.fix_oracle_lead_s is None or self.oracle_lead_s is None:
            return None
        return self.fix_oracle_lead_s - self.oracle_lead_s

    @property
    def estimation_s(self) -> float | None:
        """What the unit's estimate cost beyond that: its lead − the fix-time oracle's."""
        if self.fix_oracle_lead_s is None or self.lead_s is None:
            return None
        return self.lead_s - self.fix_oracle_lead_s

    @property
    def physics_s(self) -> float | None:
        """The spare the bounds cost even with perfect knowledge (oracle lead − warning time)."""
        return None if self.oracle_lead_s is None else self.oracle_lead_s - self.warning_time_s


def judge(
    ctl: CrossingController, truth: Truth, train: TrainSpec, settings: ControllerSettings, fixes: list[Fix]
) -> Verdict:
    """Compare the controller's switching with the truth, and its onset with the oracle's."""
    ons = [e.t_ns for e in ctl.events if e.kind == "on"]
    offs = [e.t_ns for e in ctl.events if e.kind == "off"]
    th, tt = truth.t_head_arrival_ns, truth.t_tail_clear_ns
    violation = None
    wt = ctl.crossing.warning_time_s
    late_by = None
    # The warning that counts is the one in effect when the head arrived (a road released for a
    # train standing out of reach, then closed again when it moved, owes its lead to the second).
    on_before = [t for t in ons if th is not None and t <= th]
    t_on = on_before[-1] if on_before else (ons[0] if ons else None)
    if th is not None and t_on is not None and (th - t_on) / NS < wt:
        late_by = wt - (th - t_on) / NS
        violation = f"late warning: {late_by:.1f} s short of {wt:g} s"
    if th is not None and violation is None:
        if not on_before:
            violation = "warning not on when the head reached the crossing"
        else:
            off_inside = [t for t in offs if on_before[-1] < t and (tt is None or t < tt)]
            if off_inside:
                violation = "warning off while the train was on the crossing"
    lead = (th - t_on) / NS if th is not None and t_on is not None else None
    off_after = [t for t in offs if tt is not None and t >= tt]
    excess = (off_after[0] - tt) / NS if off_after and tt is not None else None
    held = ctl.warning_on
    # Fixed-time baseline: head arrival + length / speed at arrival + margin.
    base_early = None
    if th is not None and tt is not None:
        i = int(np.searchsorted(truth.t_ns, th))
        v = float(np.abs(np.gradient(truth.head_m, truth.t_ns / NS))[min(i, len(truth.t_ns) - 1)])
        base_off = th + (train.length_m / max(v, 0.1) + settings.baseline_margin_s) * NS
        base_early = max(0.0, (tt - base_off) / NS)
    alarms = sum(1 for e in ctl.events if e.kind == "alarm")
    released_on = [
        (off - on) / NS for on, off in zip(ons, offs, strict=False) if th is not None and off <= th and on < off
    ]
    gaps = [
        (min((on for on in ons if on > off), default=th) - off) / NS for off in offs if th is not None and off <= th
    ]
    t_oracle = oracle_onset(truth, ctl.crossing, settings)
    first_rx = min((f.t_ns for f in fixes), default=None)
    if t_oracle is not None and first_rx is not None:
        # Nor can the oracle warn before any unit has been heard: a slow train may set off within
        # reach, and a unit that hears it only then owes no spare for the seconds before.
        t_oracle = max(t_oracle, first_rx)
    oracle_lead = avoidable = paper_avoidable = paper_late = fix_lead = None
    t_fix_oracle = fix_oracle_onset(truth, ctl.crossing, settings, fixes)
    if th is not None and t_fix_oracle is not None:
        fix_lead = (th - t_fix_oracle) / NS
    if th is not None and t_oracle is not None:
        oracle_lead = (th - t_oracle) / NS
        if t_on is not None:
            avoidable = (t_oracle - t_on) / NS
        t_paper = paper_onset(fixes, ctl.crossing, truth.direction, th)
        if t_paper is not None:
            paper_avoidable = (t_oracle - t_paper) / NS
        paper_lead = (th - t_paper) / NS if t_paper is not None else 0.0
        paper_late = wt - paper_lead if paper_lead < wt else None
    row = next(iter(timeline(ctl, fixes, settings)), None)
    hind = row.spare if row is not None else None
    exact_lead = allowance_lead = None
    if th is not None:
        reported = any(not math.isnan(f.speed_mps) for f in fixes)

        def yardstick_lead(margin_m: float) -> float | None:
            t = kinematic_onset(truth, ctl.crossing, settings, fixes, train.length_m, reported, margin_m)
            return None if t is None else (th - t) / NS

        exact_lead = yardstick_lead(0.0)
        # The unit's own allowance: k·σ of the worst noise it assumes (its filter's gate and bounds).
        allowance_lead = yardstick_lead(settings.k_sigma * settings.noise_m / 3.0)
    return Verdict(
        violation,
        lead,
        excess,
        held,
        alarms,
        base_early,
        wt,
        late_by,
        truth.jumps,
        ctl.position_jumps,
        oracle_lead,
        avoidable,
        fix_lead,
        paper_avoidable,
        paper_late,
        len(released_on),
        float(sum(released_on)),
        float(min(gaps)) if gaps else None,
        hind.physics_s if hind is not None else None,
        dict(hind.doubt_s) if hind is not None else None,
        exact_lead,
        allowance_lead,
    )


FIX_RATES = ("2.5 Hz", "0.1 Hz", "1-10 s")


def random_conditions(rng: np.random.Generator, seed: int) -> RunConditions:
    """Conditions across the issues' ranges: fixes at 2.5 Hz, at 0.1 Hz or every 1-10 s; noise ≤ 5 m;
    loss ≤ 30 %; device failures; trains up to 35 m/s (126 km/h, faster than the line speed the
    unit is told); half the exports without speed; half the runs with up to 5 % position jumps."""
    rate = str(rng.choice(FIX_RATES))
    period = 0.4 if rate == "2.5 Hz" else 10.0 if rate == "0.1 Hz" else float(rng.uniform(1, 10))
    failure = rng.choice(["none", "none", "head", "eot"])
    length = float(rng.choice([28.6, 40.0, 120.0, 300.0, 600.0]))
    return RunConditions(
        period_s=period,
        noise_m=float(rng.uniform(0, 5)),
        loss=float(rng.uniform(0, 0.3)),
        latency_s=float(rng.uniform(0.1, 1.5)),
        head_fails_at_s=float(rng.uniform(0, 200)) if failure == "head" else None,
        eot_fails_at_s=float(rng.uniform(0, 200)) if failure == "eot" else None,
        scenario=str(rng.choice(SCENARIOS)),
        speed_mps=float(rng.uniform(5, 35)),
        direction=int(rng.choice([1, -1])),
        length_m=length,
        seed=seed,
        speed_reported=bool(rng.random() < 0.5),
        jump_rate=float(rng.uniform(0, 0.05)) if rng.random() < 0.5 else 0.0,
    )


TUNE: dict[str, float] = {}  # settings under trial (benchmarks only)


def one_run(layout: Layout, crossing: LevelCrossing, cond: RunConditions) -> Verdict:
    # The crossing unit knows the line (its speed, the trains' acceleration) and the radio's report period.
    settings = ControllerSettings(
        **TUNE,  # type: ignore[arg-type]
        report_period_s=cond.period_s,
        latency_s=2 * cond.latency_s + 0.5,
        line_speed_mps=LINE_SPEED_MPS,
        accel_mps2=0.5,
    )
    fixes, truth, train = simulate(layout, crossing, cond, settings)
    ctl = run_controller(crossing, [train], fixes, settings)
    return judge(ctl, truth, train, settings, fixes)


def many_runs(layout: Layout, n: int, seed: int = 0) -> list[tuple[RunConditions, Verdict]]:
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        crossing = layout.crossings[k % len(layout.crossings)]
        cond = random_conditions(rng, seed * 100_000 + k)
        out.append((cond, one_run(layout, crossing, cond)))
    return out


def summary(results: list[tuple[RunConditions, Verdict]]) -> dict[str, float | int | None]:
    """Violations, lead times, excess warning, held runs; the baseline beside."""
    v = [r for _, r in results]
    conds = [c for c, _ in results]
    excess = [r.excess_s for r in v if r.excess_s is not None]
    leads = [r.lead_s for r in v if r.lead_s is not None]
    spare = [r.lead_s - r.warning_time_s for r in v if r.lead_s is not None]
    periods = [c.period_s for c, r in results if r.excess_s is not None]
    early = [r.baseline_early_s for r in v if r.baseline_early_s is not None]
    within = [e <= p + 5 for e, p in zip(excess, periods, strict=True)]
    err = [abs(h - t) for r in v if (h := r.hindsight_physics_s) is not None and (t := r.physics_s) is not None]
    return {
        "runs": len(v),
        "runs_without_speed": sum(not c.speed_reported for c in conds),
        "runs_with_jumps": sum(c.jump_rate > 0 for c in conds),
        "runs_at_2_5_hz": sum(c.period_s == 0.4 for c in conds),
        "runs_at_0_1_hz": sum(c.period_s == 10.0 for c in conds),
        "jumps_sent": sum(r.jumps_sent for r in v),
        "jumps_set_aside": sum(r.jumps_set_aside for r in v),
        "violations": sum(r.violation is not None for r in v),
        "late_warnings": sum(r.late_by_s is not None for r in v),
        "held_on": sum(r.held for r in v),
        "median_excess_s": float(np.median(excess)) if excess else None,
        "median_excess_minus_period_s": float(np.median([e - p for e, p in zip(excess, periods, strict=True)]))
        if excess
        else None,
        "p95_excess_s": float(np.percentile(excess, 95)) if excess else None,
        "share_excess_within_period_plus_5s": float(np.mean(within)) if within else None,
        "min_lead_s": float(min(leads)) if leads else None,
        "min_lead_minus_warning_time_s": float(min(spare)) if spare else None,
        "median_lead_s": float(np.median(leads)) if leads else None,
        "baseline_early_runs": sum(e > 0 for e in early),
        "baseline_max_early_s": float(max(early)) if early else None,
        "mean_alarms": float(np.mean([r.alarms for r in v])) if v else math.nan,
        **_spare_stats([r.avoidable_s for r in v], "avoidable"),
        **_spare_stats([r.physics_s for r in v], "physics"),
        "runs_released": sum(r.released > 0 for r in v),
        "runs_reopened_under_10s": sum(r.min_open_s is not None and r.min_open_s < 10 for r in v),
        "median_released_on_s": float(np.median(rel)) if (rel := [r.released_on_s for r in v if r.released]) else None,
        "median_abs_error_hindsight_physics_s": float(np.median(err)) if err else None,
        "min_oracle_lead_minus_warning_time_s": min(p, default=None)
        if (p := [x for r in v if (x := r.physics_s) is not None])
        else None,
    }


def _spare_stats(values: list[float | None], name: str) -> dict[str, float | None]:
    xs = [x for x in values if x is not None]
    return {
        f"median_{name}_spare_s": float(np.median(xs)) if xs else None,
        f"p95_{name}_spare_s": float(np.percentile(xs, 95)) if xs else None,
    }


def fix_rate(cond: RunConditions) -> str:
    """The run's fix rate as :data:`FIX_RATES` names it."""
    return "2.5 Hz" if cond.period_s == 0.4 else "0.1 Hz" if cond.period_s == 10.0 else "1-10 s"


@dataclass(frozen=True)
class SpareRow:
    """The avoidable spare over one group of runs (seconds)."""

    case: str
    runs: int
    median_s: float | None
    p95_s: float | None
    physics_median_s: float | None  # the oracle's own spare: what the bounds cost
    sparse_median_s: float | None  # what sparse fixes cost an estimator that knew the truth at each fix
    sparse_p95_s: float | None
    estimation_median_s: float | None  # the rest: what the unit's estimate cost (avoidable − sparse)
    estimation_p95_s: float | None
    paper_median_s: float | None  # the paper's rule d/v ≤ T, against the same oracle
    paper_late: int  # runs where the paper's rule warned short of the warning time
    exact_median_s: float | None = None  # the exact-positions yardstick's avoidable spare
    exact_p95_s: float | None = None
    allowance_median_s: float | None = None  # the noise-allowance yardstick's
    allowance_p95_s: float | None = None


def spare_table(results: list[tuple[RunConditions, Verdict]]) -> list[SpareRow]:
    """Avoidable spare (the oracle's onset − the controller's) overall, by speed column, fix rate
    and scenario, and their crossings; the paper's rule beside it."""
    groups: list[tuple[str, list[Verdict]]] = [("all runs", [r for _, r in results])]

    def add(case: str, keep: Callable[[RunConditions], bool]) -> None:
        groups.append((case, [r for c, r in results if keep(c)]))

    add("all runs but stop_far", lambda c: c.scenario != "stop_far")

    add("speed reported", lambda c: c.speed_reported)
    add("no speed", lambda c: not c.speed_reported)

    def rate_is(rate: str, speed: bool | None = None) -> Callable[[RunConditions], bool]:
        return lambda c: fix_rate(c) == rate and (speed is None or c.speed_reported == speed)

    def scenario_is(sc: str, speed: bool | None = None) -> Callable[[RunConditions], bool]:
        return lambda c: c.scenario == sc and (speed is None or c.speed_reported == speed)

    for rate in FIX_RATES:
        add(f"fixes {rate}", rate_is(rate))
    for rate in FIX_RATES:
        add(f"speed reported, fixes {rate}", rate_is(rate, True))
    for rate in FIX_RATES:
        add(f"no speed, fixes {rate}", rate_is(rate, False))
    for sc in SCENARIOS:
        add(f"scenario {sc}", scenario_is(sc))
    for sc in SCENARIOS:
        add(f"no speed, {sc}", scenario_is(sc, False))
    add("with position jumps", lambda c: c.jump_rate > 0)
    add("a unit failed", lambda c: c.head_fails_at_s is not None or c.eot_fails_at_s is not None)
    rows = []
    for case, vs in groups:
        xs = [r.avoidable_s for r in vs if r.avoidable_s is not None]
        ph = [p for r in vs if (p := r.physics_s) is not None]
        sp = [p for r in vs if (p := r.sparse_s) is not None]
        es = [p for r in vs if (p := r.estimation_s) is not None]
        pa = [r.paper_avoidable_s for r in vs if r.paper_avoidable_s is not None]
        fl = [x for r in vs if (x := r.yardstick_avoidable_s(r.exact_lead_s)) is not None]
        nr = [x for r in vs if (x := r.yardstick_avoidable_s(r.allowance_lead_s)) is not None]
        rows.append(
            SpareRow(
                case,
                len(xs),
                float(np.median(xs)) if xs else None,
                float(np.percentile(xs, 95)) if xs else None,
                float(np.median(ph)) if ph else None,
                float(np.median(sp)) if sp else None,
                float(np.percentile(sp, 95)) if sp else None,
                float(np.median(es)) if es else None,
                float(np.percentile(es, 95)) if es else None,
                float(np.median(pa)) if pa else None,
                sum(r.paper_late_by_s is not None for r in vs),
                float(np.median(fl)) if fl else None,
                float(np.percentile(fl, 95)) if fl else None,
                float(np.median(nr)) if nr else None,
                float(np.percentile(nr, 95)) if nr else None,
            )
        )
    return rows
