"""A device's GNSS noise from its own fixes (console/analysis/crossing/noise.py): robust, conservative.

* White noise along a train's path (constant acceleration, fixes at irregular times): the
  estimate is at or a little above the true σ, never above the worst case it was given; the
  overlapping residuals' sampling doubt is what the module says (≈ 2 σ/√n for its median).
* Too few fixes: the worst case.
* A jerk between fixes (a brake applied) and a few wild fixes raise it, never lower it.
"""

from __future__ import annotations

import numpy as np
import pytest

from console.analysis.crossing import noise
from console.analysis.crossing.noise import NoiseEstimate

NS = 10**9


def _feed(est: NoiseEstimate, t_s: np.ndarray, x_m: np.ndarray) -> NoiseEstimate:
    for t, x in zip(t_s, x_m, strict=True):
        est.add(int(t * NS), float(x))
    return est


def _path(rng: np.random.Generator, n: int, period_s: float, sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.cumsum(rng.uniform(0.8, 1.2, n) * period_s)
    v0, a = rng.uniform(5, 35), rng.uniform(-0.6, 0.5)
    return t, v0 * t + 0.5 * a * t * t + rng.normal(0, sigma_m, n)


@pytest.mark.parametrize("period_s", [0.4, 3.0, 10.0])
@pytest.mark.parametrize("sigma_m", [0.3, 1.0, 2.5, 4.0])
def test_white_noise_is_estimated_at_or_a_little_above_its_sigma(period_s: float, sigma_m: float) -> None:
    rng = np.random.default_rng(int(period_s * 10 + sigma_m * 100))
    got = np.array([_feed(NoiseEstimate(5.0), *_path(rng, 40, period_s, sigma_m)).sigma_m for _ in range(200)])
    assert np.all(got <= 5.0)
    true_m = max(sigma_m, 0.5)  # the floor
    # Widened by its own sampling doubt (one-sided 95 %): rarely below the truth, not far above it.
    assert np.mean(got >= true_m) >= 0.85
    assert np.median(got) <= 2.0 * true_m + 1e-9


def test_too_few_fixes_are_the_worst_case() -> None:
    rng = np.random.default_rng(3)
    est = _feed(NoiseEstimate(5.0), *_path(rng, 8, 1.0, 0.5))  # 5 residuals: fewer than 6
    assert est.sigma_m == 5.0
    est = _feed(est, *(np.array([20.0]), np.array([0.0])))
    assert est.sigma_m < 5.0  # the sixth residual: it counts


def test_a_jerk_or_wild_fixes_raise_the_estimate_never_lower_it() -> None:
    rng = np.random.default_rng(5)
    t = np.arange(30) * 10.0 + rng.uniform(-0.05, 0.05, 30)
    noise = rng.normal(0, 1.0, 30)
    smooth = 20.0 * t + noise
    # A brake at 0.6 m/s² from the 15th fix on, and separately three fixes 40 m off.
    braking = 20.0 * t - 0.3 * np.maximum(0.0, t - t[15]) ** 2 + noise
    wild = smooth + np.where(np.isin(np.arange(30), [8, 17, 25]), 40.0, 0.0)
    base = _feed(NoiseEstimate(5.0), t, smooth).sigma_m
    assert _feed(NoiseEstimate(5.0), t, braking).sigma_m >= base - 1e-9
    assert base <= _feed(NoiseEstimate(5.0), t, wild).sigma_m <= 5.0


def test_a_restarted_track_is_no_baseline() -> None:
    est = NoiseEstimate(5.0)
    t = np.arange(12) * 1.0
    _feed(est, t, 20.0 * t)
    n = len(est._resid)
    est.restart()
    est.add(int(12.5 * NS), 5000.0)  # the new track, 5 km away: no residual across the restart
    assert len(est._resid) == n


def test_the_median_of_overlapping_residuals_has_the_standard_error_the_module_assumes() -> None:
    # MEDIAN_SE: the raw σ (median / half-normal median) over n overlapping residuals spreads by
    # ≈ MEDIAN_SE / √n (1.17 if they were independent).  Measured here, within 15 %.
    rng = np.random.default_rng(11)
    raw = []
    for _ in range(400):
        est = NoiseEstimate(50.0, floor_m=0.0, samples=25, min_samples=25)
        _feed(est, *_path(rng, 28, 1.0, 1.0))  # 25 residuals
        raw.append(np.median(est._resid) / noise.HALF_NORMAL_MEDIAN)
    rel_se = float(np.std(raw)) * np.sqrt(25)
    assert abs(rel_se - noise.MEDIAN_SE) <= 0.15 * noise.MEDIAN_SE, rel_se
