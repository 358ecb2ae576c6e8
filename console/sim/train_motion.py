"""The trains' motion: the target speed their speed control follows (speed limits, platform stops, the
train ahead), the platform stops themselves, and the motion models (the ATO on the force model, or a
bounded-acceleration point mass)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from console.layout import Layout
from console.sim.dynamics import LEVEL_LINE, TrainState, scaled_train
from console.sim.line_values import SimConfig, SimTrain

CONTROLLERS = ("pid", "fuzzy", "fuzzy-d")
PROTECTION_GAP_M = 80.0  # a follower stays this far behind the tail of the train ahead


def speed_limit_mps(layout: Layout, tr: SimTrain, x: float) -> float:
    """The speed limit for the whole train at head position x."""
    lo, hi = sorted((x, x - tr.direction * tr.consist.length_m))
    v = layout.line_speed_mps
    for lim in layout.speed_limits:
        if lim.to_m > lo and lim.from_m < hi:
            v = min(v, lim.limit_mps)
    return v


def target_speed_mps(layout: Layout, tr: SimTrain, t_s: float, brake_mps2: float, on_line: Sequence[SimTrain]) -> float:
    """The speed the train's control follows now; ``on_line``: every train and standing rear part."""
    if tr.dwell_until_s is not None:
        return 0.0
    b = brake_mps2 * 0.8  # plan with a margin on the service brake
    v = speed_limit_mps(layout, tr, tr.x_m)
    # Lower limits ahead and the next stop: the speed from which the train can still brake.
    for lim in layout.speed_limits:
        edge = lim.from_m if tr.direction > 0 else lim.to_m
        dist = tr.direction * (edge - tr.x_m)
        if 0 < dist < 2000 and lim.limit_mps < v:
            v = min(v, math.sqrt(lim.limit_mps**2 + 2 * b * dist))
    if tr.stops:
        dist = tr.direction * (tr.stops[0] - tr.x_m)
        v = min(v, math.sqrt(max(0.0, 2 * b * max(dist - 1.0, 0.0))))
    # Protection: stay 80 m behind the train ahead (or a parted train's rear part, standing).
    for other in on_line:
        if other is tr or other.direction != tr.direction:
            continue
        gap = tr.direction * (other.tail_m - tr.x_m) - PROTECTION_GAP_M
        if tr.direction * (other.x_m - tr.x_m) > 0:
            v = min(v, math.sqrt(max(0.0, 2 * b * gap)) if gap > 0 else 0.0)
    return v


def stop_check(tr: SimTrain, t_s: float, dwell_s: float) -> None:
    """A train at its next platform stop, nearly standing, stops there and dwells ``dwell_s``."""
    if tr.stops and tr.dwell_until_s is None:
        dist = tr.direction * (tr.stops[0] - tr.x_m)
        if dist < 2.0 and tr.v_mps < 0.3:
            tr.v_mps = 0.0
            tr.dwell_until_s = t_s + dwell_s
            tr.stops.pop(0)


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
