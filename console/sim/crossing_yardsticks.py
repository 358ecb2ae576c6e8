"""What a crossing unit could have done in a harness run: the yardsticks its warning is judged by.

Each yardstick applies the unit's own bounds (the earliest arrival, the guard
distance, the release rule) to more knowledge than the unit had:

* the **oracle** knows the true position and speed at every instant
  (:mod:`console.analysis.crossing.oracle`): what it warns beyond the warning
  time is physics, what the unit warns beyond the oracle is the *avoidable*
  spare;
* the **fix-time oracle** knows the true position and speed at each received
  fix, nothing between: it shows what the sparse fixes cost;
* the **exact-positions yardstick** knows the true position at each received
  fix, and the true speed only where the export reports one; else it bounds
  the speed from the earlier fixes' positions.  It shows what an export
  without speed costs a unit that bounds the speed by kinematics (not a
  floor for a statistical estimate with another release history: the unit
  warned later than it in 3 to 4 of 3,600 runs, seeds 20261129 and 4242);
* the **noise-allowance yardstick** is the same with the fixes' measured
  positions, taken with the unit's own worst-case noise allowance; it sets
  every position jump aside (it knows which fixes jumped).  It shows what the
  issue's noise range (σ up to 5 m, not known for a device until several
  fixes have shown it) costs a unit that bounds the speed by the kinematic
  rule alone;
* the paper's rule d/v ≤ T (Co Nhu Van, TCSJ 2026, eq. 6-8) at each head fix.

The speed bound from positions: two fixes Δt apart, their positions known to
±m, give the mean speed between them at most ``(Δs + 2m) / Δt`` (Δs in the
direction of travel); the train
may have accelerated at ``a`` since, so the speed at the later fix is at most
that plus ``a·Δt / 2``.  The smallest over the last few earlier fixes counts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from console.analysis.crossing.oracle import earliest_arrival_vec, oracle_onset_ns
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, Fix
from console.layout import LevelCrossing
from parsers.units import NS

BASELINES = 8  # the speed bound from positions looks back this many fixes
# A fix further than this from the truth was sent displaced (the harness's jumps are 50 m to 2 km,
# its noise σ ≤ 5 m): the noise-allowance yardstick sets it aside, as a perfect jump filter would.
JUMPED_M = 30.0


@dataclass
class Truth:
    t_ns: np.ndarray  # simulation times
    head_m: np.ndarray  # head chainage over time
    t_head_arrival_ns: int | None  # head reaches the road's near edge
    t_tail_clear_ns: int | None  # tail passes the road's far edge
    jumps: int = 0  # fixes sent displaced (position jumps)
    direction: int = 1  # +1: towards increasing chainage
    speed_mps: np.ndarray | None = None  # the head's true speed along the track at t_ns


def oracle_onset(truth: Truth, crossing: LevelCrossing, settings: ControllerSettings) -> int | None:
    """The oracle's onset for the head's arrival in this run (None: the head never arrived)."""
    th = truth.t_head_arrival_ns
    if th is None or truth.speed_mps is None:
        return None
    near_edge = crossing.chainage_m - truth.direction * settings.crossing_half_width_m
    ahead = truth.direction * (near_edge - truth.head_m)
    return oracle_onset_ns(
        truth.t_ns,
        ahead,
        truth.speed_mps,
        th,
        crossing.warning_time_s,
        settings.guard_distance_m,
        settings.accel_mps2,
        settings.line_speed_mps,
    )


def _received_with_truth(truth: Truth, fixes: Sequence[Fix]) -> tuple[list[Fix], np.ndarray, np.ndarray] | None:
    """The fixes of the run's train received before the head arrived (reception order), with the
    head's true chainage and speed at each one's measurement time; None: the head never arrived,
    or nothing was received before."""
    th = truth.t_head_arrival_ns
    if th is None or truth.speed_mps is None:
        return None
    got = sorted((f for f in fixes if f.t_ns < th and f.train == "T1"), key=lambda f: f.t_ns)
    if not got:
        return None
    ts = (truth.t_ns - truth.t_ns[0]) / NS
    t_fix = np.array([(f.t_fix_ns - truth.t_ns[0]) / NS for f in got])
    return got, np.interp(t_fix, ts, truth.head_m), np.interp(t_fix, ts, truth.speed_mps)


def _onset_from_bounds(
    truth: Truth, crossing: LevelCrossing, settings: ControllerSettings, got: Sequence[Fix], arrival_ns: np.ndarray
) -> int | None:
    """The onset for the head's arrival of a unit whose bound at each received fix is ``arrival_ns``
    (the earliest arrival that fix proves); the unit's bound is the latest of those received so far.

    It releases a warning as the unit does: only when it would stay open ``release_hold_s`` at
    least, and not come on again before the next fix of either unit is due."""
    th = truth.t_head_arrival_ns
    assert th is not None
    bound = np.maximum.accumulate(arrival_ns)
    wt_ns = int(crossing.warning_time_s * NS)
    onset: int | None = None
    last_fix: dict[str, int] = {}  # per unit, its latest fix so far (measurement time)
    period_ns = int((settings.report_period_s + settings.latency_s) * NS)
    for k, f in enumerate(got):  # per received fix of one run
        last_fix[f.role] = max(last_fix.get(f.role, f.t_fix_ns), f.t_fix_ns)
        hold_ns = max(int(settings.release_hold_s * NS), min(last_fix.values()) + period_ns - f.t_ns)
        end = got[k + 1].t_ns if k + 1 < len(got) else th
        due = int(bound[k]) - wt_ns
        if onset is not None and due > f.t_ns + hold_ns:
            onset = None  # this fix proves the warning is not needed for a while yet: released
        if onset is None and due < end:
            onset = max(due, f.t_ns)
    return onset


def _arrivals_ns(
    truth: Truth,
    crossing: LevelCrossing,
    settings: ControllerSettings,
    got: Sequence[Fix],
    head_m: np.ndarray,
    v: np.ndarray,
) -> np.ndarray:
    near_edge = crossing.chainage_m - truth.direction * settings.crossing_half_width_m
    eta = earliest_arrival_vec(truth.direction * (near_edge - head_m), v, settings.accel_mps2, settings.line_speed_mps)
    return np.array([f.t_fix_ns for f in got], dtype=np.int64) + (eta * NS).astype(np.int64)


def fix_oracle_onset(
    truth: Truth, crossing: LevelCrossing, settings: ControllerSettings, fixes: Sequence[Fix]
) -> int | None:
    """The best any unit could do with the fixes this run's unit received: it knows the true state
    (position, speed) at each received fix's measurement time, exactly, and nothing between fixes.
    Beside the oracle's onset it separates what sparse fixes cost (they hide an acceleration between
    two of them) from what the estimate costs.  None: the head never arrived."""
    received = _received_with_truth(truth, fixes)
    if received is None:
        return None
    got, head, speed = received
    return _onset_from_bounds(truth, crossing, settings, got, _arrivals_ns(truth, crossing, settings, got, head, speed))


def speed_bound_from_positions(
    t_fix_ns: np.ndarray, along_m: np.ndarray, margin_m: float, accel_mps2: float, max_speed_mps: float
) -> np.ndarray:
    """Per fix, the fastest the train can run at its time (m/s) from the positions of the
    ``BASELINES`` fixes before it (``along_m``: chainage in the direction of travel, each known to
    ± ``margin_m``): the smallest of ``(Δs + 2·margin) / Δt + a·Δt / 2``; the first fix: the most
    a train runs."""
    n = len(t_fix_ns)
    hi = np.full(n, max_speed_mps)
    t_s = t_fix_ns / NS
    for back in range(1, min(BASELINES, n - 1) + 1):  # a few baselines, each vectorized over the fixes
        dt = t_s[back:] - t_s[:-back]
        with np.errstate(divide="ignore", invalid="ignore"):
            b = (along_m[back:] - along_m[:-back] + 2 * margin_m) / dt + accel_mps2 * dt / 2
        b = np.where(dt > 0, np.maximum(b, 0.0), np.inf)
        hi[back:] = np.minimum(hi[back:], b)
    return hi


def kinematic_onset(
    truth: Truth,
    crossing: LevelCrossing,
    settings: ControllerSettings,
    fixes: Sequence[Fix],
    length_m: float,
    speed_reported: bool,
    margin_m: float = 0.0,
) -> int | None:
    """The exact-positions yardstick (``margin_m`` 0: the true positions at the fixes) or the noise-allowance one
    (``margin_m`` > 0: the measured positions, each known to ± that, the jumped fixes set aside).
    The speed where the export reports one is the truth at the fix; without, the bound from the
    positions (:func:`speed_bound_from_positions`).  An EOT fix is a head fix a length behind."""
    received = _received_with_truth(truth, fixes)
    if received is None:
        return None
    got, head, speed = received
    d = truth.direction
    if margin_m > 0:
        measured = np.array([f.chainage_m + (d * length_m if f.role == EOT else 0.0) for f in got])
        kept = np.abs(measured - head) < JUMPED_M
        got = [f for f, k in zip(got, kept, strict=True) if k]
        if not got:
            return None
        head, speed = measured[kept], speed[kept]
    t_fix = np.array([f.t_fix_ns for f in got], dtype=np.int64)
    if not speed_reported:
        # Fixes measured out of order (the two units' latencies differ): bounded in measurement order.
        order = np.argsort(t_fix, kind="stable")
        hi = np.empty(len(got))
        hi[order] = speed_bound_from_positions(
            t_fix[order], d * head[order], margin_m, settings.accel_mps2, settings.max_speed_mps
        )
        speed = hi
    # The position at its near end: the head may be up to the margin nearer the road.
    return _onset_from_bounds(
        truth, crossing, settings, got, _arrivals_ns(truth, crossing, settings, got, head + d * margin_m, speed)
    )


def paper_onset(fixes: Sequence[Fix], crossing: LevelCrossing, direction: int, t_arrival_ns: int) -> int | None:
    """The paper's rule (Co Nhu Van, TCSJ 2026, eq. 6-8): on at the first head fix with d_L / v_L ≤ T,
    with the reported speed, or the mean speed from the last two head fixes when the export has none;
    the warning then holds until the EOT has passed.  None: no such fix before the arrival."""
    prev: Fix | None = None
    for f in sorted((f for f in fixes if f.role == HEAD), key=lambda f: f.t_ns):  # one run's head fixes
        if f.t_ns >= t_arrival_ns:
            return None
        v = f.speed_mps
        if math.isnan(v):
            dt = (f.t_fix_ns - prev.t_fix_ns) / NS if prev is not None else 0.0
            v = abs(f.chainage_m - prev.chainage_m) / dt if prev is not None and dt > 0 else 0.0
        prev = f
        ahead = direction * (crossing.chainage_m - f.chainage_m)
        if ahead <= 0 or (v > 0 and ahead / v <= crossing.warning_time_s):
            return f.t_ns
    return None
