"""The last safe moment to warn, given the true motion: the yardstick for a crossing unit.

A crossing unit must warn no later than the warning time before the
*earliest possible* arrival: the train may accelerate at up to the line's
acceleration to the line speed (or keep a higher speed it already runs at),
and a train inside the guard distance is warned whatever its speed.  Even
with perfect knowledge of where the train is and how fast it runs, those
bounds make the warning come on before the train's real arrival minus the
warning time: that part of the spare is **physics**.

The **oracle** knows the true position and speed at every instant (not the
future) and applies exactly those bounds: it wants the warning on at ``t``
when, from the true state at ``t``, the train could reach the road's near
edge within the warning time, or is inside the guard distance.  Its onset
for an arrival is the start of the last stretch of such instants before the
head arrived.  What a unit warns earlier than that came from **doubt**
(missing speed, sparse or stale fixes, position jumps): the *avoidable*
spare.

Vectorized over the samples of a motion; used by the randomized harness
(:mod:`console.sim.crossing_runs`, with the simulated truth) and by the
timelines (with a reconstruction of the motion from all the fixes, in
hindsight).
"""

from __future__ import annotations

import numpy as np

from parsers.units import NS


def earliest_arrival_vec(
    distance_m: np.ndarray, speed_mps: np.ndarray, accel_mps2: float, line_speed_mps: float
) -> np.ndarray:
    """Shortest time (s) to run ``distance_m`` from ``speed_mps``, accelerating at ``accel_mps2``
    up to ``max(line_speed_mps, speed)`` (a train already faster keeps its speed): elementwise.

    The same bound as :func:`console.analysis.crossing.values.earliest_arrival_s` with the line speed as
    the top speed, for arrays."""
    d = np.maximum(np.asarray(distance_m, dtype=float), 0.0)
    v = np.maximum(np.asarray(speed_mps, dtype=float), 0.0)
    a = accel_mps2
    vmax = np.maximum(np.maximum(line_speed_mps, v), 1e-3)
    t1 = (vmax - v) / a
    d1 = v * t1 + 0.5 * a * t1 * t1
    accelerating = (-v + np.sqrt(v * v + 2 * a * d)) / a
    cruising = t1 + (d - d1) / vmax
    return np.where(d <= d1, accelerating, cruising)


def required_on(
    ahead_m: np.ndarray,
    speed_mps: np.ndarray,
    warning_time_s: float,
    guard_distance_m: float,
    accel_mps2: float,
    line_speed_mps: float,
) -> np.ndarray:
    """Per sample: the unit's bounds, applied to this state, want the warning on."""
    eta = earliest_arrival_vec(ahead_m, speed_mps, accel_mps2, line_speed_mps)
    return (np.asarray(ahead_m) <= guard_distance_m) | (eta <= warning_time_s)


def oracle_onset_ns(
    t_ns: np.ndarray,
    ahead_m: np.ndarray,
    speed_mps: np.ndarray,
    t_arrival_ns: int,
    warning_time_s: float,
    guard_distance_m: float,
    accel_mps2: float,
    line_speed_mps: float,
) -> int | None:
    """When the oracle turns the warning on for the arrival at ``t_arrival_ns``.

    ``ahead_m``: the head's distance to the road's near edge (≤ 0 once there) at the sample
    times ``t_ns`` (ascending); ``speed_mps`` the speed along the track there.  The onset is the
    first sample of the last stretch of wanted-on samples before the arrival (the first sample
    when the motion began already within reach).  None without a sample before the arrival.
    """
    before = np.flatnonzero(np.asarray(t_ns) < t_arrival_ns)
    if len(before) == 0:
        return None
    n = int(before[-1]) + 1
    want = required_on(ahead_m[:n], speed_mps[:n], warning_time_s, guard_distance_m, accel_mps2, line_speed_mps)
    free = np.flatnonzero(~want)
    if len(free) == 0:
        return int(t_ns[0])
    last_free = int(free[-1])
    # The stretch begins at the next sample (or at the arrival if the last sample was free).
    return int(t_ns[last_free + 1]) if last_free + 1 < n else int(t_arrival_ns)


def physics_spare_s(onset_ns: int, t_arrival_ns: int, warning_time_s: float) -> float:
    """The oracle's lead beyond the warning time: what the bounds cost even with perfect knowledge."""
    return (t_arrival_ns - onset_ns) / NS - warning_time_s
