"""Where a GNSS device is and how fast it runs, with the uncertainty: one Kalman filter per device.

The crossing unit's worst-case bounds (:mod:`console.analysis.crossing.evidence`)
need no model, but they are loose: from positions alone, the speed is known
only to ``2·noise / Δt + a·Δt / 2`` (several m/s), and a first fix without
speed is the fastest train there is.  A filter does better, and says how
much better:

* **State**: chainage, speed and acceleration along the track (a
  constant-acceleration model whose acceleration wanders as white jerk: trains
  brake, coast and accelerate in steps of a few tenths of a m/s²; Bar-Shalom,
  Li and Kirubarajan, Wiley 2001).  Fixes come at any interval; the filter
  predicts over each gap.
* **Measurements**: each fix's chainage (σ: the GNSS noise), and its Doppler
  speed where the export has one and the direction is known.  The noise is
  the worst case (5 m) until the device's own fixes prove it quieter
  (:mod:`console.analysis.crossing.noise`, a robust and widened estimate);
  the gate keeps the worst case, a brake between sparse fixes is no jump.
* **Upper bounds**: estimate + ``k·σ`` (k = 3.3: one-sided 99.95 % for
  Gaussian errors), the property the tests check on randomized runs against
  the truth: not below the true speed on ≥ 99.9 % of fixes.
* **Doubt stays doubt**: a fix further from the prediction than ``gate``
  standard deviations is set aside (a position jump; with the filter
  settled, a jump of 50 m is ten of them); two set-aside fixes that agree
  with each other restart the filter (the track was wrong).  The estimate is
  *settled* only after several fixes in a row inside the prediction: until
  then the caller keeps the model-free bounds beside it, and nothing is
  released on it.

The filter's predict and update are written out for the three states (this
runs for every fix; numpy's 3 × 3 arrays cost more than the arithmetic); the
tests compare them with filterpy's (Labbe, filterpy 2.0), as they compare the
hindsight smoother (:func:`console.analysis.crossing.spare.smoothed_motion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from console.analysis.crossing.noise import NoiseEstimate
from console.analysis.window import Window
from parsers.units import NS

# (p00, p01, p02, p11, p12, p22): the symmetric 3 × 3 covariance of (chainage, speed, acceleration).
Cov = tuple[float, float, float, float, float, float]
State = tuple[float, float, float]


def predict_ca(x: State, p: Cov, dt: float, jerk_psd: float) -> tuple[State, Cov]:
    """The constant-acceleration model over ``dt`` s with white jerk of spectral density ``jerk_psd``:
    ``F·x`` and ``F·P·Fᵀ + Q``, written out (3 × 3 with numpy costs more than the arithmetic: this
    runs for every fix).  The same numbers as filterpy's ``predict`` with ``Q_continuous_white_noise``
    (tests/test_crossing_estimate.py compares them)."""
    h = 0.5 * dt * dt
    x0, v, a = x
    p00, p01, p02, p11, p12, p22 = p
    r00, r01, r02 = p00 + dt * p01 + h * p02, p01 + dt * p11 + h * p12, p02 + dt * p12 + h * p22
    r11, r12 = p11 + dt * p12, p12 + dt * p22
    q = jerk_psd
    d2 = dt * dt
    d3 = d2 * dt
    return (x0 + dt * v + h * a, v + dt * a, a), (
        r00 + dt * r01 + h * r02 + q * d3 * d2 / 20.0,
        r01 + dt * r02 + q * d2 * d2 / 8.0,
        r02 + q * d3 / 6.0,
        r11 + dt * r12 + q * d3 / 3.0,
        r12 + q * d2 / 2.0,
        p22 + q * dt,
    )


def update_position(x: State, p: Cov, z: float, r: float) -> tuple[State, Cov]:
    """Kalman update with a measured chainage ``z`` of variance ``r``."""
    p00, p01, p02, p11, p12, p22 = p
    s = p00 + r
    k0, k1, k2 = p00 / s, p01 / s, p02 / s
    nu = z - x[0]
    return (x[0] + k0 * nu, x[1] + k1 * nu, x[2] + k2 * nu), (
        p00 - k0 * p00,
        p01 - k0 * p01,
        p02 - k0 * p02,
        p11 - k1 * p01,
        p12 - k1 * p02,
        p22 - k2 * p02,
    )


def update_speed(x: State, p: Cov, z: float, r: float) -> tuple[State, Cov]:
    """Kalman update with a measured speed ``z`` (signed along the track) of variance ``r``."""
    p00, p01, p02, p11, p12, p22 = p
    s = p11 + r
    k0, k1, k2 = p01 / s, p11 / s, p12 / s
    nu = z - x[1]
    return (x[0] + k0 * nu, x[1] + k1 * nu, x[2] + k2 * nu), (
        p00 - k0 * p01,
        p01 - k0 * p11,
        p02 - k0 * p12,
        p11 - k1 * p11,
        p12 - k1 * p12,
        p22 - k2 * p12,
    )


@dataclass(frozen=True)
class FilterLimits:
    position_sigma_m: float  # GNSS noise along the track, one σ: the worst case (the gate keeps it)
    speed_sigma_mps: float  # a reported (Doppler) speed's error, one σ
    jerk_psd: float  # how fast the acceleration may change: white jerk, m²/s⁵
    max_speed_mps: float  # no train runs faster (the speed prior before any evidence)
    accel_sigma_mps2: float = 0.5  # the acceleration prior: trains brake and accelerate at ≲ 1 m/s²
    gate_sigma: float = 5.0  # a fix further than this from the prediction is set aside
    k_sigma: float = 3.3  # bounds: estimate ± k·σ
    settle_fixes: int = 4  # fixes in a row inside 3 σ of the prediction before the estimate is settled
    adaptive_noise: bool = True  # the update uses the noise the device's own fixes prove (never above the worst)


@dataclass(frozen=True)
class MotionEstimate:
    """The filter's state at its last accepted fix."""

    t_ns: int  # that fix's measurement time
    chainage_m: float
    speed_mps: float  # signed: > 0 towards increasing chainage
    accel_mps2: float
    sigma_m: float
    sigma_speed_mps: float
    fixes: int  # accepted since the filter (re)started
    settled: bool  # several fixes in a row agreed with the prediction, none set aside among them
    k_sigma: float

    def chainage_hi_m(self, direction: int) -> float:
        """The furthest the device can be in ``direction`` (±1) at ``t_ns``."""
        return self.chainage_m + direction * self.k_sigma * self.sigma_m

    def speed_hi_mps(self, direction: int) -> float:
        """The fastest it can run in ``direction`` (±1; 0: either way) at ``t_ns`` (≥ 0)."""
        v = abs(self.speed_mps) if direction == 0 else direction * self.speed_mps
        return max(0.0, v + self.k_sigma * self.sigma_speed_mps)


class MotionFilter:
    """Chainage, speed and acceleration of one device from its fixes (in measurement order)."""

    def __init__(self, limits: FilterLimits) -> None:
        self.lim = limits
        self.x: State | None = None
        self.P: Cov | None = None
        self.t_ns = 0
        self.fixes = 0
        self.rejected = 0  # fixes set aside by the gate, in all
        self.restarts = 0
        self._agree: Window[bool] = Window(limits.settle_fixes)
        self._pending: tuple[int, float, float, int, float, float | None] | None = None  # the last set-aside fix
        self.noise = NoiseEstimate(limits.position_sigma_m)
        # The estimate of the state as it stands: read many times between fixes (every wake of the unit, both
        # roles' bounds); made again after each change of the state (None: not made yet).
        self._estimate: MotionEstimate | None = None

    @property
    def noise_sigma_m(self) -> float:
        """The position noise (one σ) the filter uses for this device's fixes now."""
        return self.noise.sigma_m if self.lim.adaptive_noise else self.lim.position_sigma_m

    def reset(self) -> None:
        self.x = self.P = None
        self._estimate = None
        self.fixes = 0
        self._agree.clear()
        self._pending = None
        self.noise.restart()

    def _start(
        self,
        t_ns: int,
        chainage_m: float,
        speed_mps: float,
        direction: int,
        extra_var: float = 0.0,
        sigma_m: float | None = None,
    ) -> None:
        lim = self.lim
        v0, sv = 0.0, lim.max_speed_mps / math.sqrt(3.0)  # uniform over ± the fastest train
        if direction and not math.isnan(speed_mps):
            v0, sv = direction * speed_mps, 3 * lim.speed_sigma_mps
        self.x = (chainage_m, v0, 0.0)
        sigma = self.noise_sigma_m if sigma_m is None else sigma_m
        self.P = (sigma**2 + extra_var, 0.0, 0.0, sv * sv, 0.0, lim.accel_sigma_mps2**2)
        if sigma_m is None:
            self.noise.add(t_ns, chainage_m)
        self.t_ns = t_ns
        self.fixes = 1
        self._agree.clear()
        self._pending = None
        self._estimate = None

    def _predicted(self, t_ns: int) -> tuple[State, Cov]:
        assert self.x is not None and self.P is not None
        dt = (t_ns - self.t_ns) / NS
        if dt <= 0:
            return self.x, self.P
        return predict_ca(self.x, self.P, dt, self.lim.jerk_psd)

    def offer(
        self,
        t_ns: int,
        chainage_m: float,
        speed_mps: float = math.nan,
        direction: int = 0,
        extra_var: float = 0.0,
        sigma_m: float | None = None,
    ) -> bool:
        """Take a fix (True) or set it aside as inconsistent with the track so far (False).

        ``speed_mps``: the reported speed (NaN: none), used with ``direction`` (±1) only.
        ``extra_var``: variance to add to the fix's own (m²; a position carried over from another
        device of the train).  ``sigma_m``: the fix's noise as its own device's filter knows it
        (None: this filter's device, its own estimate)."""
        lim = self.lim
        if self.x is None:
            self._start(t_ns, chainage_m, speed_mps, direction, extra_var, sigma_m)
            return True
        if t_ns < self.t_ns:
            return False  # older than the state: not usable here
        x, P = self._predicted(t_ns)
        # The gate and the agreement test keep the worst-case noise: a brake's onset between sparse
        # fixes strays further from the prediction than a quiet receiver's noise, and is no jump.
        s = P[0] + lim.position_sigma_m**2 + extra_var
        nu = chainage_m - x[0]
        if nu * nu > lim.gate_sigma**2 * s:
            return self._set_aside(t_ns, chainage_m, speed_mps, direction, extra_var, sigma_m)
        sigma = self.noise_sigma_m if sigma_m is None else sigma_m
        x, P = update_position(x, P, chainage_m, sigma**2 + extra_var)
        if sigma_m is None:
            self.noise.add(t_ns, chainage_m)
        if direction and not math.isnan(speed_mps):
            rv = lim.speed_sigma_mps**2
            nu_v = direction * speed_mps - x[1]
            # A speed far from what the positions say (a frozen 0.0 on a moving train) is not used;
            # 2 m/s of slack: the model overshoots when a braking train stops dead.
            if abs(nu_v) <= lim.gate_sigma * math.sqrt(P[3] + rv) + 2.0:
                x, P = update_speed(x, P, direction * speed_mps, rv)
        self.x, self.P, self.t_ns = x, P, t_ns
        self.fixes += 1
        self._agree.append(nu * nu <= 9.0 * s)
        self._pending = None
        self._estimate = None
        return True

    def _set_aside(
        self, t_ns: int, chainage_m: float, speed_mps: float, direction: int, extra_var: float, sigma_m: float | None
    ) -> bool:
        self.rejected += 1
        self._agree.clear()
        self._estimate = None  # no longer settled
        pending, self._pending = self._pending, (t_ns, chainage_m, speed_mps, direction, extra_var, sigma_m)
        if pending is not None:
            dt = (t_ns - pending[0]) / NS
            reach = self.lim.max_speed_mps * dt + 2 * self.lim.gate_sigma * self.lim.position_sigma_m
            if dt > 0 and abs(chainage_m - pending[1]) <= reach:
                # Two set-aside fixes agree with each other: the track so far was wrong. Start over.
                self.restarts += 1
                self.noise.restart()
                self._start(*pending)
                self.offer(t_ns, chainage_m, speed_mps, direction, extra_var, sigma_m)
                return True
        return False

    @property
    def estimate(self) -> MotionEstimate | None:
        if self._estimate is not None:
            return self._estimate
        if self.x is None or self.P is None:
            return None
        agree = self._agree
        settled = len(agree) == agree.maxlen and all(agree) and self.fixes > len(agree)
        self._estimate = MotionEstimate(
            self.t_ns,
            self.x[0],
            self.x[1],
            self.x[2],
            math.sqrt(max(0.0, self.P[0])),
            math.sqrt(max(0.0, self.P[3])),
            self.fixes,
            settled,
            self.lim.k_sigma,
        )
        return self._estimate

    def speed_at(self, t_ns: int) -> tuple[float, float] | None:
        """(speed, σ) predicted to ``t_ns`` (a witness for the other device of the same train)."""
        if self.x is None or self.P is None:
            return None
        x, P = self._predicted(t_ns) if t_ns >= self.t_ns else (self.x, self.P)
        return x[1], math.sqrt(max(0.0, P[3]))
