"""The earliest a train's head can reach a crossing, from what one device's fixes prove.

Every bound here is anchored at a fix: "measured at ``t_ref``, the head was at
most ``ahead`` metres from the road and ran at most ``v`` m/s; accelerating
at the line's acceleration to the line speed from then on, it cannot arrive
before ``t_ref + E(ahead, v)``".  The bound holds however late the next fix
comes, so the unit needs no allowance for the report period or the radio
latency: time passing between fixes brings the bound nearer by itself, and a
unit that falls silent ends up warning (fail-safe), never forgetting the
train.

Two sources of ``ahead`` and ``v``:

* the device's **filter** (:mod:`console.analysis.crossing.estimate`):
  estimate + k·σ, capped by the model-free speed bound;
* the **model-free** bounds of :mod:`console.analysis.crossing.evidence`
  (the speed bound the positions prove, the worst case when nothing is
  known), from the most advanced of the device's last few fixes so that one
  fix that jumped back cannot delay the warning.

While the filter is not settled (its first fixes, or fixes set aside as
jumps lately) the earlier of the two counts; once settled, the filter's.

The components of the bound (how far the margins on position and speed and
the model-free fallback brought the arrival forward) are kept: they say how
much of an early warning came from doubt, and which doubt.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from console.analysis.crossing.estimate import MotionEstimate
from console.analysis.crossing.evidence import Report
from parsers.units import NS


def earliest_s(distance_m: float, speed_mps: float, accel_mps2: float, line_speed_mps: float) -> float:
    """Shortest time to run ``distance_m`` from ``speed_mps``, accelerating at ``accel_mps2`` up to
    the line speed (a train already faster keeps its speed)."""
    if distance_m <= 0:
        return 0.0
    v, a = max(0.0, speed_mps), accel_mps2
    vmax = max(line_speed_mps, v, 1e-3)
    if a <= 0:
        return distance_m / max(v, 1e-3)
    t1 = (vmax - v) / a
    d1 = v * t1 + 0.5 * a * t1 * t1
    if distance_m <= d1:
        return (-v + math.sqrt(v * v + 2 * a * distance_m)) / a
    return t1 + (distance_m - d1) / vmax


@dataclass(frozen=True)
class Motion:
    """The line's bounds and the road: what every arrival bound is computed against."""

    target_m: float  # the crossing's chainage
    half_width_m: float  # the road's half width along the track (arrival: its near edge)
    accel_mps2: float
    line_speed_mps: float
    noise_m: float  # model-free position allowance per fix

    def ahead_m(self, chainage_m: float, direction: int, extra_m: float = 0.0) -> float:
        """How far a head at ``chainage_m`` + ``extra_m`` (in the direction of travel) is from
        the road's near edge; direction unknown: the nearer way."""
        if direction:
            return direction * (self.target_m - chainage_m) - extra_m - self.half_width_m
        return abs(self.target_m - chainage_m) - extra_m - self.half_width_m

    def arrival_ns(self, t_ref_ns: int, ahead_m: float, speed_mps: float) -> int:
        return t_ref_ns + int(earliest_s(ahead_m, speed_mps, self.accel_mps2, self.line_speed_mps) * NS)


@dataclass(frozen=True)
class ArrivalBound:
    """The earliest arrival from one device, with what brought it forward."""

    t_arrival_ns: int
    t_ref_ns: int  # the fix it is anchored at
    ahead_m: float  # the head's distance from the road then (the furthest it may have been)
    speed_hi_mps: float  # the fastest it may have run then
    settled: bool  # the filter's estimate alone (no model-free fallback)
    # The arrival from the filter's best estimate (no margins), and from the estimate with the
    # position margin only: with t_arrival_ns they split the bound into its parts (ns, None: no filter).
    t_nominal_ns: int | None = None
    t_position_ns: int | None = None
    t_filter_ns: int | None = None  # the filter's bound (both margins), before any fallback
    standing: bool = False  # the filter proves the train stands (|v| + k·σ below 1 m/s)


def device_bound(
    m: Motion,
    est: MotionEstimate | None,
    recent: Sequence[Report],
    direction: int,
    extra_m: float,
    speed_cap_mps: float,
) -> ArrivalBound | None:
    """The earliest arrival of the head from one device's evidence (None: no fix yet).

    ``recent``: the device's last few accepted fixes, oldest first.  ``extra_m``: how far the head
    runs ahead of this device (0 for the head unit, the train's length for the EOT).
    ``speed_cap_mps``: the model-free bound on the speed at the last fix (the smaller of what the
    train's two devices prove, the worst case when nothing is known)."""
    if not recent:
        return None
    last = recent[-1]
    fallback = None
    if est is None or not est.settled:
        # Model-free: the most advanced of the last few fixes, moved on to the last one's time at
        # the speed bound (one fix that jumped back cannot delay the warning), the noise allowed.
        d = direction
        v = speed_cap_mps
        ahead = min(m.ahead_m(q.chainage_m, d, extra_m) - v * (last.t_fix_ns - q.t_fix_ns) / NS for q in recent)
        ahead -= m.noise_m
        fallback = ArrivalBound(m.arrival_ns(last.t_fix_ns, ahead, v), last.t_fix_ns, ahead, v, False)
    if est is None:
        return fallback
    d = direction
    k_x = est.k_sigma * est.sigma_m
    ahead_nom = m.ahead_m(est.chainage_m, d, extra_m)
    ahead_hi = ahead_nom - k_x
    v_nom = max(0.0, abs(est.speed_mps) if d == 0 else d * est.speed_mps)
    v_hi = min(est.speed_hi_mps(d), max(speed_cap_mps, v_nom))
    t_kf = m.arrival_ns(est.t_ns, ahead_hi, v_hi)
    t_nominal = m.arrival_ns(est.t_ns, ahead_nom, v_nom)
    t_position = m.arrival_ns(est.t_ns, ahead_hi, v_nom)
    standing = est.settled and abs(est.speed_mps) + est.k_sigma * est.sigma_speed_mps < 1.0
    if fallback is None or t_kf <= fallback.t_arrival_ns:
        return ArrivalBound(t_kf, est.t_ns, ahead_hi, v_hi, est.settled, t_nominal, t_position, t_kf, standing)
    f = fallback
    return ArrivalBound(f.t_arrival_ns, f.t_ref_ns, f.ahead_m, f.speed_hi_mps, False, t_nominal, t_position, t_kf)
