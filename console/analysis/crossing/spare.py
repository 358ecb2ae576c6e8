"""How much of a warning's spare was physics, and how much doubt (in hindsight, from the fixes).

The **spare** of a warning is its lead beyond the crossing's warning time.  Part
of it is **physics**: the unit must assume the train may accelerate at the
line's acceleration to the line speed, so even a unit that knew where the
train was and how fast it ran would warn before the train's real arrival
minus the warning time (:mod:`console.analysis.crossing.oracle`).  The rest
is **doubt**: what the unit did not know then.

A log has no truth, so the physics is judged in hindsight: the head's motion
is reconstructed from *all* the fixes, later ones included (a Kalman filter
forward and the Rauch-Tung-Striebel smoother back: Rauch, Tung and Striebel,
*AIAA Journal* 3(8), 1965; filterpy's ``rts_smoother`` step for step), and the oracle is
run on it.  The doubt is split among its causes in proportion to how far each
brought the unit's bound forward when it turned the warning on
(:class:`console.analysis.crossing.values.Onset`): the speed unknown (no speed in
the export), units stale (the head unit lost), position jumps, sparse fixes
(the estimate's σ).  On the randomized harness the
hindsight physics is compared with the true one (benchmarks/crossing_spare.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from console.analysis.crossing.estimate import Cov, State, predict_ca, update_position, update_speed
from console.analysis.crossing.oracle import oracle_onset_ns
from parsers.units import NS

SPARSE = "sparse fixes"


@dataclass(frozen=True)
class SpareSplit:
    spare_s: float  # lead − warning time
    physics_s: float  # what the bounds cost a unit that knew the motion (hindsight)
    doubt_s: dict[str, float]  # the rest, by cause; the values add up to spare − physics

    def to_dict(self) -> dict[str, object]:
        return {
            "spare_s": round(self.spare_s, 3),
            "physics_s": round(self.physics_s, 3),
            "doubt_s": round(sum(self.doubt_s.values()), 3),
            "doubt_by_cause_s": {k: round(v, 3) for k, v in sorted(self.doubt_s.items())},
        }


def smoothed_motion(
    times_ns: np.ndarray,
    chainage_m: np.ndarray,
    speed_mps: np.ndarray,
    direction: int,
    sigma_m: float,
    speed_sigma_mps: float,
    jerk_psd: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """(chainage, speed along ``direction``) at ``times_ns`` (ascending, the fixes' own), smoothed
    with every fix before and after: forward filter, then the RTS smoother.  Reported speeds
    (not NaN) are used with the direction known.  None for fewer than two fixes."""
    n = len(times_ns)
    if n < 2:
        return None
    x: State = (float(chainage_m[0]), 0.0, 0.0)
    p: Cov = (sigma_m**2, 0.0, 0.0, 30.0**2, 0.0, 0.5**2)
    xs = np.empty((n, 3))
    ps = np.empty((n, 3, 3))
    # The smoother wants, at k, the transition from k to k+1 (none after the last): F, and filterpy's
    # Q_continuous_white_noise(3, dt, jerk_psd) entry for entry (its scipy block_diag cost more than the filter).
    fs = np.empty((n, 3, 3))
    qs = np.empty((n, 3, 3))
    fs[-1], qs[-1] = np.eye(3), np.zeros((3, 3))
    q = jerk_psd
    for k in range(n):  # one train's fixes: the filter is sequential
        if k:
            dt = (int(times_ns[k]) - int(times_ns[k - 1])) / NS
            x, p = predict_ca(x, p, dt, jerk_psd)
            fs[k - 1] = ((1.0, dt, 0.5 * dt * dt), (0.0, 1.0, dt), (0.0, 0.0, 1.0))
            q5, q4, q3, q2 = (dt**5) / 20.0 * q, (dt**4) / 8.0 * q, (dt**3) / 6.0 * q, (dt**2) / 2.0 * q
            qs[k - 1] = ((q5, q4, q3), (q4, (dt**3) / 3.0 * q, q2), (q3, q2, dt * q))
        x, p = update_position(x, p, float(chainage_m[k]), sigma_m**2)
        v = float(speed_mps[k])
        if direction and not math.isnan(v):
            x, p = update_speed(x, p, direction * v, speed_sigma_mps**2)
        xs[k] = x
        p00, p01, p02, p11, p12, p22 = p
        ps[k] = ((p00, p01, p02), (p01, p11, p12), (p02, p12, p22))
    xs_s = rts_smoothed(xs, ps, fs, qs)
    return xs_s[:, 0], (direction or 1) * xs_s[:, 1]


def rts_smoothed(xs: np.ndarray, ps: np.ndarray, fs: np.ndarray, qs: np.ndarray) -> np.ndarray:
    """The Rauch-Tung-Striebel smoother's states from a forward filter's states ``xs`` and covariances ``ps``,
    with ``fs[k]``, ``qs[k]`` the transition from k to k+1 and its noise.

    filterpy's ``rts_smoother`` step for step (the same numpy products and inverse, so the same numbers:
    tests/test_crossing_estimate.py compares them), written here because importing filterpy costs every
    command that draws a crossing timeline 0.6 s of start-up (its package imports scipy.stats)."""
    x, p = xs.copy(), ps.copy()
    for k in range(len(xs) - 2, -1, -1):
        p_pred = np.dot(np.dot(fs[k], p[k]), fs[k].T) + qs[k]
        gain = np.dot(np.dot(p[k], fs[k].T), np.linalg.inv(p_pred))
        x[k] += np.dot(gain, x[k + 1] - np.dot(fs[k], x[k]))
        p[k] += np.dot(np.dot(gain, p[k + 1] - p_pred), gain.T)
    return x


def split_spare(
    lead_s: float,
    warning_time_s: float,
    t_head_ns: int,
    motion: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
    onset_doubt_s: dict[str, float],
    guard_distance_m: float,
    accel_mps2: float,
    line_speed_mps: float,
) -> SpareSplit:
    """The spare of one warning split into physics and doubt.

    ``motion``: (times, head's distance to the road's near edge, speed towards it) in hindsight
    (None: too few fixes to tell: all the spare is counted as doubt of sparse fixes)."""
    spare = lead_s - warning_time_s
    physics = 0.0
    if motion is not None and spare > 0:
        t, ahead, speed = motion
        # Between the fixes the motion is taken as linear: 0.5 s samples are plenty for the oracle.
        grid = np.arange(int(t[0]), t_head_ns, NS // 2, dtype=np.int64)
        if len(grid):
            a = np.interp(grid, t, ahead)
            v = np.maximum(np.interp(grid, t, speed), 0.0)
            onset = oracle_onset_ns(grid, a, v, t_head_ns, warning_time_s, guard_distance_m, accel_mps2, line_speed_mps)
            if onset is not None:
                physics = min(spare, max(0.0, (t_head_ns - onset) / NS - warning_time_s))
    doubt = max(0.0, spare - physics)
    total = sum(onset_doubt_s.values())
    if doubt <= 0:
        parts: dict[str, float] = {}
    elif total <= 0:
        parts = {SPARSE: doubt}
    else:
        parts = {cause: doubt * s / total for cause, s in onset_doubt_s.items()}
    return SpareSplit(spare, physics, parts)


def head_motion(
    fixes: Sequence[tuple[int, str, float, float]],
    direction: int,
    length_m: float,
    target_m: float,
    half_width_m: float,
    sigma_m: float,
    speed_sigma_mps: float,
    jerk_psd: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The head's motion towards the road in hindsight from a train's accepted fixes
    ``(t_fix_ns, role, chainage, speed)``: the head unit's, else the EOT's moved on by the length.
    (times, distance to the road's near edge, speed towards it); None without a direction or
    with fewer than two fixes."""
    if not direction:
        return None
    heads = [f for f in fixes if f[1] == "head"]
    use = heads if len(heads) >= 2 else [f for f in fixes if f[1] == "eot"]
    if len(use) < 2:
        return None
    use.sort(key=lambda f: f[0])
    t = np.array([f[0] for f in use], dtype=np.int64)
    keep = np.concatenate([[True], np.diff(t) > 0])  # one fix per instant
    extra = 0.0 if use is heads else direction * length_m
    ch = np.array([f[2] for f in use]) + extra
    sp = np.array([f[3] for f in use])
    got = smoothed_motion(t[keep], ch[keep], sp[keep], direction, sigma_m, speed_sigma_mps, jerk_psd)
    if got is None:
        return None
    x, v = got
    return t[keep], direction * (target_m - direction * half_width_m - x), v
