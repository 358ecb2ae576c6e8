"""How noisy one GNSS device's positions are, from its own fixes: a robust, conservative estimate.

The crossing unit's filter (:mod:`console.analysis.crossing.estimate`) must assume
the worst GNSS noise it may meet (σ 5 m) until the fixes prove a device does
better; most do (a receiver in the open: a metre or two), and the filter's
speed bound tightens with it.

**What the fixes prove.**  Through any four fixes of a train running at a
constant acceleration the third divided difference of the chainage is zero:
what is left is the noise, a known weighted sum of the four errors.  Each
new fix gives one such residual, normalized to one σ of white noise; a jerk
between the fixes (a brake applied, a stop) only makes it larger, so the
motion can inflate the estimate, never shrink it.

**Robust and conservative.**  σ is the median of the last residuals (a few
outliers, a jump the gate let through, do not move it) divided by the
half-normal median, raised by two standard errors of that median (below the
truth about one time in 13) and floored; it counts only after enough residuals
and never exceeds the worst case the caller gives.  Residuals of fixes that
follow one another closely are correlated if the receiver's error is (real
GNSS errors drift over seconds): the floor and the widening keep a margin
for that, and the tested property (the speed bound not below the truth on
≥ 99.9 % of fixes) is the judge.
"""

from __future__ import annotations

import math
import statistics

from console.analysis.window import Window
from parsers.units import NS

HALF_NORMAL_MEDIAN = 0.6744897501960817  # the median of |N(0, 1)|
# The relative standard error of the median-based σ, times √n: 1.17 for independent normal
# residuals; these overlap (three fixes of four shared with the next), which makes it ≈ 1.5
# (measured: tests/test_crossing_noise.py).
MEDIAN_SE = 1.5
WIDEN_SE = 2.0  # σ is raised by this many of those standard errors: below the truth ≈ 1 time in 13 (measured)


class NoiseEstimate:
    """Position noise (one σ, m) of one device from its accepted fixes."""

    def __init__(self, worst_m: float, floor_m: float = 0.5, samples: int = 25, min_samples: int = 6) -> None:
        self.worst_m = worst_m
        self.floor_m = floor_m
        self.min_samples = min_samples
        self._fixes: Window[tuple[float, float]] = Window(4)  # (t s, chainage m)
        self._resid: Window[float] = Window(samples)  # |residual| / σ-weight, per fix
        self._sigma_m = worst_m

    def restart(self) -> None:
        """The device's track started over (jumps): the fixes before it are no baseline for the next."""
        self._fixes.clear()

    def add(self, t_ns: int, chainage_m: float) -> None:
        f = self._fixes
        t = t_ns / NS
        if f and t <= f[-1][0]:
            return
        f.append((t, chainage_m))
        if len(f) < 4:
            return
        # The third divided difference: Σ wᵢ·xᵢ with wᵢ = 1 / Πⱼ≠ᵢ (tᵢ − tⱼ); over √Σwᵢ² it is one σ of
        # white noise (a constant acceleration leaves nothing).
        ts = [p[0] for p in f]
        w = [1.0 / math.prod(ts[i] - ts[j] for j in range(4) if j != i) for i in range(4)]
        norm = math.sqrt(sum(x * x for x in w))
        self._resid.append(abs(sum(wi * p[1] for wi, p in zip(w, f, strict=True))) / norm)
        self._update()

    def _update(self) -> None:
        n = len(self._resid)
        if n < self.min_samples:
            return
        sigma = statistics.median(self._resid) / HALF_NORMAL_MEDIAN * (1.0 + WIDEN_SE * MEDIAN_SE / math.sqrt(n))
        self._sigma_m = min(self.worst_m, max(self.floor_m, sigma))

    @property
    def sigma_m(self) -> float:
        """The σ to use now: the worst case until enough fixes prove better."""
        return self._sigma_m
