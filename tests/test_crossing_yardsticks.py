"""The speed bound the kinematic yardsticks take from positions (console/sim/crossing_yardsticks.py).

Two fixes Δt apart known to ± m bound the speed at the later one by
(Δs + 2m) / Δt + a·Δt / 2, for any motion that accelerates at no more than a.
Checked on random motions with braking, coasting and accelerating, sampled
at uneven times, with and without noise; and the same check must fail where
the motion breaks the acceleration bound, so it can.
"""

from __future__ import annotations

import numpy as np

from console.sim.crossing_yardsticks import speed_bound_from_positions
from parsers.units import NS

ACCEL_MPS2 = 0.5


def _motion(rng: np.random.Generator, accel_max_mps2: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A train's (times s, positions m, speeds m/s) on a 0.1 s grid: segments of constant
    acceleration up to ``accel_max`` (braking up to 1.2 m/s²), speed kept in 0..35 m/s."""
    t = np.arange(0.0, 600.0, 0.1)
    a = np.repeat(rng.uniform(-1.2, accel_max_mps2, 60), 100)[: len(t)]
    v = np.empty(len(t))
    v[0] = rng.uniform(0, 30)
    for k in range(1, len(t)):  # a sequential integration with clipping: the test's own truth
        v[k] = min(35.0, max(0.0, v[k - 1] + a[k - 1] * 0.1))
    x = np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 * 0.1)])
    return t, x, v


def _coverage(accel_max_mps2: float, noise_m: float, margin_m: float, seed: int) -> float:
    rng = np.random.default_rng(seed)
    hits = total = 0
    for _ in range(40):
        t, x, v = _motion(rng, accel_max_mps2)
        # Fix times on the motion's own grid: its positions there are exact (no interpolation error).
        t_fix = t[np.sort(rng.choice(len(t), rng.integers(20, 200), replace=False))]
        pos = np.interp(t_fix, t, x) + rng.normal(0, noise_m, len(t_fix)) if noise_m else np.interp(t_fix, t, x)
        hi = speed_bound_from_positions((t_fix * NS).astype(np.int64), pos, margin_m, ACCEL_MPS2, 45.0)
        true_v = np.interp(t_fix, t, v)
        hits += int(np.sum(hi >= true_v - 1e-6))
        total += len(t_fix)
    return hits / total


def test_the_bound_holds_on_exact_positions() -> None:
    assert _coverage(ACCEL_MPS2, 0.0, 0.0, seed=1) == 1.0


def test_the_bound_holds_with_noise_inside_the_margin() -> None:
    # Noise σ 5 m against a margin of 3.3 σ: a miss needs an error beyond 3.3 σ on a fix that counts.
    assert _coverage(ACCEL_MPS2, 5.0, 16.5, seed=2) >= 0.999


def test_the_check_can_fail() -> None:
    # Trains that accelerate at up to 1.5 m/s² break the bound the rule assumes (0.5): it misses.
    assert _coverage(1.5, 0.0, 0.0, seed=3) < 0.99
    # And so does a margin well under the noise.
    assert _coverage(ACCEL_MPS2, 5.0, 0.5, seed=4) < 0.99


def test_the_first_fix_is_the_worst_case_a_standing_train_the_acceleration_term() -> None:
    t = (np.array([0.0, 10.0, 20.0]) * NS).astype(np.int64)
    hi = speed_bound_from_positions(t, np.array([100.0, 50.0, 0.0]), 0.0, ACCEL_MPS2, 45.0)  # running away
    assert hi[0] == 45.0 and list(hi[1:]) == [0.0, 0.0]
    # Standing: it may have set off just after the fix before (the nearest baseline is the tightest).
    hi = speed_bound_from_positions(t, np.array([7.0, 7.0, 7.0]), 0.0, ACCEL_MPS2, 45.0)
    assert list(hi[1:]) == [ACCEL_MPS2 * 10 / 2] * 2
    # The margin: ±2 m on each of two fixes 10 s apart is 0.4 m/s more.
    hi = speed_bound_from_positions(t, np.array([7.0, 7.0, 7.0]), 2.0, ACCEL_MPS2, 45.0)
    assert abs(hi[2] - (ACCEL_MPS2 * 10 / 2 + 0.4)) < 1e-9
