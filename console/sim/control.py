"""Speed controllers of seed 001 (Tiem 2020): PID, the fuzzy SpeedT and Fuzzy-D; and its identified plant G(s).

One scaling for all three
-------------------------
The seed's controllers compute ``u``, the input of its identified model
G(s) (eq. 4), in that model's own units: PID gains 2.774/0.214/4.088 act on
``u``; SpeedT's output is ``u``; Fuzzy-D is ``u = K·U_Fuzzy + K_D·ė`` with
K = 10 (eqs. 6-7).  Here ``u`` maps to the dynamics' command in [−1, 1] as
``command = u / U_FULL`` with ``U_FULL = 10``: the same 10 units of ``u``
mean full effort for every controller, and SpeedT's rule surface, whose
output is in [−1, 1], spans them (``u = U_FULL·f``).  On G(s), 10 units hold
21.9 m/s at steady state (DC gain 612/0.34/822.4 = 2.19 m/s per unit), so
the seed's 15 m/s needs u = 6.85 and is within reach.  Whatever exceeds
±U_FULL is clipped: the seed's Simulink model probably let ``u`` run free.

Fuzzy-D has two readings (:data:`FUZZY_D_READINGS`, ``docs/ato.md``).  As
printed, ``U_Fuzzy`` is the FLCT's output on SpeedT's scale (``U_FULL·f``)
and K multiplies it: ``"output-gain"``, the default.  The other reading,
``"normalised"``, takes the FLCT's output universe as [−1, 1] with K only
scaling it to the plant (``K·f``); K then cancels against ``U_FULL`` and
Fuzzy-D is SpeedT plus a tiny ``K_D·ė``.  Only the first gives the seed's
steady-state errors a ratio near K (0.272 / 0.028 = 9.7).

Speed error ``e = target − speed`` (positive: too slow), and ``ė`` its rate.
All three controllers take ``ė`` from one estimator, a backward difference
through a first-order filter of :data:`DERIVATIVE_FILTER_S`, started at zero
on the first sample so a standing start gives no kick.

The fuzzy rule base (seed Tables 1 and 2, identical)
----------------------------------------------------
Inputs ``e`` and ``ė``, five sets each (NB NS Z PS PB), output seven sets
(NB NM NS Z PS PM PB), Mamdani min–max with clipping, centroid
defuzzification.  The seed's membership figures (5, 6, 8, 9) are not in the
text we have, so the shapes are ours: symmetric triangles, evenly spaced on
normalised universes — inputs on [−1, 1] (centres −1, −½, 0, ½, 1, inputs
clipped, so NB and PB are shoulders), output on [−4/3, 4/3] (centres
−1, −⅔, …, 1, half-width ⅓, so the centroid reaches exactly ±1 when only
NB or PB fires).  The scaling factors put physical units on them:

* ``ė`` is normalised by 1 m/s² (:data:`FUZZY_DE_SCALE_MPS2`): with a steady
  target ė = −(train acceleration), and 1 m/s² is about the train's starting
  acceleration and service braking, so the universe spans what the train
  can do;
* ``e`` is normalised by 1 m/s (:data:`FUZZY_E_SCALE_MPS`, 3.6 km/h): PB/NB,
  full effort, at a speed error of a few km/h, the scale an ATO regulates
  speed to.  Neither factor is fitted to the seed's results.

Since the seed's membership functions for SpeedT and for Fuzzy-D's FLCT are
unknown to us, both use these same ones; under the ``"output-gain"`` reading
Fuzzy-D is then SpeedT with K times the effort plus ``K_D·ė`` (0.05 units of
``u`` per m/s², half a percent of full effort).

The rule surface is precomputed once on a 161 × 161 grid of the normalised
inputs and read by bilinear interpolation (pure float arithmetic, about a
microsecond); :func:`fuzzy_exact` evaluates the same rule base exactly
(piecewise-linear centroid with every breakpoint), vectorised with numpy.
The interpolated surface is within :data:`SURFACE_MAX_ERROR` of the exact one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike

from console.sim.dynamics import G_MPS2, LineProfile

U_FULL = 10.0  # units of G(s)'s input u that mean full traction (or, negative, full service braking)
DERIVATIVE_FILTER_S = 0.1  # time constant of the common ė filter

PID_KP = 2.774  # seed 001 eq. 5 (MATLAB's PID autotuner on G(s), per its ref [2])
PID_KI = 0.214
PID_KD = 4.088

FUZZY_D_K = 10.0  # seed 001 eq. 7
FUZZY_D_KD = 0.05
# What U_Fuzzy in eq. 6 is: the FLCT's output on SpeedT's scale, K then a gain on it (the
# equations as printed), or a normalised output that K only scales to the plant (K cancels).
FUZZY_D_READINGS = ("output-gain", "normalised")
FUZZY_D_READING = "output-gain"

FUZZY_E_SCALE_MPS = 1.0
FUZZY_DE_SCALE_MPS2 = 1.0

INPUT_SETS = ("NB", "NS", "Z", "PS", "PB")
OUTPUT_SETS = ("NB", "NM", "NS", "Z", "PS", "PM", "PB")

# Seed 001 Table 2 (= Table 1, SpeedT from its ref [3]): rows ė, columns e.
RULES: tuple[tuple[str, ...], ...] = (
    # e:  NB    NS    Z     PS    PB
    ("NB", "NB", "NM", "Z", "PS"),  # ė NB
    ("NB", "NB", "NS", "PS", "PM"),  # ė NS
    ("NB", "NM", "Z", "PM", "PB"),  # ė Z
    ("NM", "NS", "PS", "PB", "PB"),  # ė PS
    ("NS", "Z", "PM", "PB", "PB"),  # ė PB
)

INPUT_CENTRES = (-1.0, -0.5, 0.0, 0.5, 1.0)
INPUT_HALF_WIDTH = 0.5
OUTPUT_CENTRES = tuple((k - 3) / 3.0 for k in range(7))
OUTPUT_HALF_WIDTH = 1.0 / 3.0
OUTPUT_UNIVERSE = (-4.0 / 3.0, 4.0 / 3.0)

SURFACE_POINTS = 161
SURFACE_MAX_ERROR = 0.01  # bound on |interpolated − exact|, asserted by the tests

CONTROLLER_NAMES = ("pid", "fuzzy", "fuzzy-d")


def clip(x: float, lo: float = -1.0, hi: float = 1.0) -> float:
    return lo if x < lo else (hi if x > hi else x)


class Controller(Protocol):
    """A speed controller: target and measured speed in, a command in [−1, 1] out."""

    name: str

    def reset(self) -> None: ...

    def update(self, target_mps: float, speed_mps: float, dt_s: float) -> float: ...


class ErrorRate:
    """ė from successive errors: backward difference through a first-order low-pass of ``tf_s``."""

    __slots__ = ("prev", "rate", "tf_s")

    def __init__(self, tf_s: float = DERIVATIVE_FILTER_S) -> None:
        self.tf_s = tf_s
        self.prev: float | None = None
        self.rate = 0.0

    def reset(self) -> None:
        self.prev = None
        self.rate = 0.0

    def update(self, e: float, dt_s: float) -> float:
        if self.prev is not None and dt_s > 0.0:
            self.rate = (self.tf_s * self.rate + (e - self.prev)) / (self.tf_s + dt_s)
        self.prev = e
        return self.rate


class PID:
    """Seed 001's PID, ``u = kp·e + ki·∫e + kd·ė``, command = u / U_FULL clipped to [−1, 1].

    Anti-windup by conditional integration: while the output is saturated
    the integral is frozen if this step's error would push it further into
    saturation (it may still unwind).  Without it the integral gathered
    during the 0 → 15 m/s start would dominate every later transient.
    """

    name = "pid"

    def __init__(self, kp: float = PID_KP, ki: float = PID_KI, kd: float = PID_KD) -> None:
        self.kp, self.ki, self.kd = kp, ki, kd
        self.integral = 0.0
        self.rate = ErrorRate()

    def reset(self) -> None:
        self.integral = 0.0
        self.rate.reset()

    def update(self, target_mps: float, speed_mps: float, dt_s: float) -> float:
        e = target_mps - speed_mps
        de = self.rate.update(e, dt_s)
        candidate = self.integral + e * dt_s
        u = self.kp * e + self.ki * candidate + self.kd * de
        if abs(u) <= U_FULL or (u > 0.0) != (e > 0.0):
            self.integral = candidate
        else:
            u = self.kp * e + self.ki * self.integral + self.kd * de
        return clip(u / U_FULL)


# --- the fuzzy rule base ------------------------------------------------------------

_RULE_INDEX = np.array([[OUTPUT_SETS.index(r) for r in row] for row in RULES])  # [ė][e] → output set


def _input_memberships(x: np.ndarray) -> np.ndarray:
    """(N,) normalised inputs → (N, 5) memberships of NB..PB."""
    xc = np.clip(x, -1.0, 1.0)[:, None]
    return np.clip(1.0 - np.abs(xc - np.array(INPUT_CENTRES)) / INPUT_HALF_WIDTH, 0.0, 1.0)


def rule_strengths(e_n: ArrayLike, de_n: ArrayLike) -> np.ndarray:
    """(N, 7) clip levels of the output sets: max over rules of min(μ_e, μ_ė)."""
    me = _input_memberships(np.asarray(e_n, dtype=float))
    md = _input_memberships(np.asarray(de_n, dtype=float))
    fire = np.minimum(md[:, :, None], me[:, None, :])  # (N, ė, e)
    out = np.zeros((fire.shape[0], len(OUTPUT_SETS)))
    for k in range(len(OUTPUT_SETS)):
        mask = np.equal(_RULE_INDEX, k)
        out[:, k] = fire[:, mask].max(axis=1)
    return out


def _aggregate(y: np.ndarray, s: np.ndarray) -> np.ndarray:
    """μ(y) = max_k min(s_k, tri_k(y)); y (N, M), s (N, 7) → (N, M)."""
    c = np.array(OUTPUT_CENTRES)
    tri = np.clip(1.0 - np.abs(y[:, :, None] - c) / OUTPUT_HALF_WIDTH, 0.0, 1.0)  # (N, M, 7)
    return np.max(np.minimum(tri, s[:, None, :]), axis=2)


def _breakpoints(s: np.ndarray) -> np.ndarray:
    """Every abscissa where the aggregated output can bend, per point: (N, M) sorted."""
    h = OUTPUT_HALF_WIDTH
    c = np.array(OUTPUT_CENTRES)
    n = s.shape[0]
    cols = [np.broadcast_to(c + d, (n, 7)) for d in (-h, 0.0, h)]
    cols += [c - h * (1.0 - s), c + h * (1.0 - s)]  # clip corners
    left, right = c[:-1], s[:, :-1]
    s_next = s[:, 1:]
    cols += [
        np.broadcast_to(left + h / 2.0, (n, 6)),  # the two triangles cross
        left + h * right,  # clip level of k meets the rise of k+1
        left + h * (1.0 - s_next),  # clip level of k+1 meets the fall of k
    ]
    y = np.concatenate(cols, axis=1)
    return np.sort(np.clip(y, *OUTPUT_UNIVERSE), axis=1)


def fuzzy_exact(e_n: ArrayLike, de_n: ArrayLike) -> np.ndarray:
    """The rule base's crisp output for normalised inputs, exactly (the output is in [−1, 1]).

    The aggregated output set is piecewise linear between the points of
    :func:`_breakpoints`, so the centroid integrals are exact there.
    """
    e_arr = np.atleast_1d(np.asarray(e_n, dtype=float))
    de_arr = np.atleast_1d(np.asarray(de_n, dtype=float))
    s = rule_strengths(e_arr, de_arr)
    y = _breakpoints(s)
    mu = _aggregate(y, s)
    y1, y2, m1, m2 = y[:, :-1], y[:, 1:], mu[:, :-1], mu[:, 1:]
    dy = y2 - y1
    area = np.sum(dy * (m1 + m2) / 2.0, axis=1)
    moment = np.sum(dy / 6.0 * (m1 * (2.0 * y1 + y2) + m2 * (y1 + 2.0 * y2)), axis=1)
    out: np.ndarray = moment / area
    return out


@cache
def fuzzy_surface() -> tuple[tuple[float, ...], ...]:
    """The exact rule surface on a SURFACE_POINTS² grid over [−1, 1]², rows e, columns ė."""
    g = np.linspace(-1.0, 1.0, SURFACE_POINTS)
    ee, dd = np.meshgrid(g, g, indexing="ij")
    flat_e, flat_d = ee.ravel(), dd.ravel()
    vals = np.concatenate(
        [fuzzy_exact(flat_e[i : i + 4096], flat_d[i : i + 4096]) for i in range(0, flat_e.size, 4096)]
    )
    return tuple(tuple(float(v) for v in row) for row in vals.reshape(SURFACE_POINTS, SURFACE_POINTS))


def fuzzy_interp(e_n: float, de_n: float) -> float:
    """Bilinear read of :func:`fuzzy_surface` at normalised inputs (clipped to [−1, 1])."""
    s = fuzzy_surface()
    half = (SURFACE_POINTS - 1) / 2.0
    fx = (clip(e_n) + 1.0) * half
    fy = (clip(de_n) + 1.0) * half
    i = min(int(fx), SURFACE_POINTS - 2)
    j = min(int(fy), SURFACE_POINTS - 2)
    tx, ty = fx - i, fy - j
    r0, r1 = s[i], s[i + 1]
    return (1.0 - tx) * ((1.0 - ty) * r0[j] + ty * r0[j + 1]) + tx * ((1.0 - ty) * r1[j] + ty * r1[j + 1])


class Fuzzy:
    """The fuzzy SpeedT (seed 001 §3.2, from its ref [3]): ``u = U_FULL·f(e/E, ė/Ė)``, so command = f."""

    name = "fuzzy"

    def __init__(self, e_scale_mps: float = FUZZY_E_SCALE_MPS, de_scale_mps2: float = FUZZY_DE_SCALE_MPS2) -> None:
        self.e_scale = e_scale_mps
        self.de_scale = de_scale_mps2
        self.rate = ErrorRate()

    def reset(self) -> None:
        self.rate.reset()

    def update(self, target_mps: float, speed_mps: float, dt_s: float) -> float:
        e = target_mps - speed_mps
        de = self.rate.update(e, dt_s)
        return clip(fuzzy_interp(e / self.e_scale, de / self.de_scale))


class FuzzyD(Fuzzy):
    """Fuzzy-D (seed 001 eqs. 6-7): ``u = K·U_Fuzzy + K_D·ė`` with K = 10, K_D = 0.05; command = u / U_FULL.

    ``reading`` says what ``U_Fuzzy`` is (see :data:`FUZZY_D_READINGS`):

    * ``"output-gain"`` (default, the equations as printed): the FLCT's
      output on the same scale as SpeedT's, ``U_FULL·f``; K then multiplies
      the proportional action, so near a steady state Fuzzy-D's fuzzy gain
      is K times SpeedT's and its steady-state error about 1/K of it.
    * ``"normalised"``: the FLCT's output universe is [−1, 1] and K = 10
      only maps it onto the plant's full range, ``K·f``, which is what
      SpeedT already commands: K cancels and Fuzzy-D is SpeedT plus K_D·ė.
    """

    name = "fuzzy-d"

    def __init__(
        self,
        k: float = FUZZY_D_K,
        k_d: float = FUZZY_D_KD,
        e_scale_mps: float = FUZZY_E_SCALE_MPS,
        de_scale_mps2: float = FUZZY_DE_SCALE_MPS2,
        reading: str = FUZZY_D_READING,
    ) -> None:
        super().__init__(e_scale_mps, de_scale_mps2)
        if reading not in FUZZY_D_READINGS:
            raise ValueError(f"unknown Fuzzy-D reading {reading!r}: expected {' or '.join(FUZZY_D_READINGS)}")
        self.k, self.k_d, self.reading = k, k_d, reading
        # U_Fuzzy in units of u per unit of the rule surface's output f
        self._u_per_f = U_FULL if reading == "output-gain" else 1.0

    def update(self, target_mps: float, speed_mps: float, dt_s: float) -> float:
        e = target_mps - speed_mps
        de = self.rate.update(e, dt_s)
        u_fuzzy = self._u_per_f * fuzzy_interp(e / self.e_scale, de / self.de_scale)
        u = self.k * u_fuzzy + self.k_d * de
        return clip(u / U_FULL)


_FACTORIES: dict[str, Callable[[], Controller]] = {"pid": PID, "fuzzy": Fuzzy, "fuzzy-d": FuzzyD}


def make_controller(name: str, fuzzy_d_reading: str = FUZZY_D_READING) -> Controller:
    """A fresh controller by name: 'pid', 'fuzzy' (SpeedT) or 'fuzzy-d' (in ``fuzzy_d_reading``)."""
    if name.lower() == "fuzzy-d":
        return FuzzyD(reading=fuzzy_d_reading)
    try:
        return _FACTORIES[name.lower()]()
    except KeyError:
        raise ValueError(f"unknown controller {name!r}: expected one of {', '.join(CONTROLLER_NAMES)}") from None


# --- seed 001's identified plant G(s) --------------------------------------------------


@dataclass(frozen=True)
class IdentifiedModel:
    """G(s) = Gn(s)·G0(s) = 612/(s + 0.34) · 1/(8621 s + 822.4) (seed 001 eq. 4, identified in its ref [2]).

    Gn takes ``u`` to traction force ``w`` (N): ``ẇ = −0.34 w + 612 u``.
    G0 takes ``F = w − Fc`` to speed: ``8621 v̇ = F − 822.4 v``, so 8621 plays
    the part of a mass (kg) and 822.4 v of the running resistance; Fc is the
    additional (grade and curve) resistance of seed eq. 3.  Fc is given in
    N/kN, so it is turned into newtons with the weight of that 8621 kg:
    6 ‰ is 507 N, 4 % of the 12.3 kN that holds 15 m/s.
    """

    gain: float = 612.0
    pole_per_s: float = 0.34
    inertia_kg: float = 8621.0
    damping_n_per_mps: float = 822.4
    length_m: float = 80.0

    @property
    def dc_speed_per_u(self) -> float:
        """Steady speed per unit of u on level track (m/s)."""
        return self.gain / self.pole_per_s / self.damping_n_per_mps

    @property
    def weight_kn(self) -> float:
        return self.inertia_kg * G_MPS2 / 1000.0


class IdentifiedState(NamedTuple):
    x_m: float
    v_mps: float
    traction_n: float  # Gn's output w


def identified_step(
    model: IdentifiedModel,
    profile: LineProfile,
    state: IdentifiedState,
    command: float,
    dt_s: float,
) -> IdentifiedState:
    """One RK4 step of G(s) with ``u = U_FULL·command`` held; speed clamped at 0 like the force model."""
    u = U_FULL * clip(command)
    m, c, p, g = model.inertia_kg, model.damping_n_per_mps, model.pole_per_s, model.gain
    w_kn, length = model.weight_kn, model.length_m

    def deriv(x: float, v: float, w: float) -> tuple[float, float, float]:
        fc = w_kn * profile.additional_resistance_n_per_kn(x, length)
        a = (w - fc - c * v) / m
        if v <= 0.0 and a < 0.0:
            a = 0.0
        return v, a, -p * w + g * u

    x0, v0, w0 = state
    k1 = deriv(x0, v0, w0)
    k2 = deriv(x0 + 0.5 * dt_s * k1[0], max(v0 + 0.5 * dt_s * k1[1], 0.0), w0 + 0.5 * dt_s * k1[2])
    k3 = deriv(x0 + 0.5 * dt_s * k2[0], max(v0 + 0.5 * dt_s * k2[1], 0.0), w0 + 0.5 * dt_s * k2[2])
    k4 = deriv(x0 + dt_s * k3[0], max(v0 + dt_s * k3[1], 0.0), w0 + dt_s * k3[2])
    x1 = x0 + dt_s * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]) / 6.0
    v1 = v0 + dt_s * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]) / 6.0
    w1 = w0 + dt_s * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]) / 6.0
    if v1 < 0.0:
        t_stop = dt_s * v0 / (v0 - v1) if v0 > 0.0 else 0.0
        return IdentifiedState(x0 + 0.5 * v0 * t_stop, 0.0, w1)
    return IdentifiedState(x1, v1, w1)


def step_response(
    controller: Controller, step_mps: float = 1.0, duration_s: float = 120.0, dt_s: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """Times and speeds of a speed step on G(s) alone, from rest on level track.

    The target is already ``step_mps`` at the first sample, so the controller
    sees no derivative kick: as if ė were taken from the measured speed.
    """
    plant = IdentifiedModel()
    profile = LineProfile()
    controller.reset()
    state = IdentifiedState(0.0, 0.0, 0.0)
    n = round(duration_s / dt_s)
    v = np.zeros(n + 1)
    for i in range(n):
        state = identified_step(plant, profile, state, controller.update(step_mps, state.v_mps, dt_s), dt_s)
        v[i + 1] = state.v_mps
    return np.arange(n + 1) * dt_s, v


def step_response_overshoot_pct(controller: Controller, step_mps: float = 1.0, duration_s: float = 120.0) -> float:
    """Overshoot (%) of :func:`step_response`: the linear loop's own figure (small steps stay unsaturated)."""
    _, v = step_response(controller, step_mps, duration_s)
    return max(0.0, 100.0 * (float(v.max()) - step_mps) / step_mps)
