"""Longitudinal train motion: named forces, one equation of motion, a fixed-step integrator.

The equation of motion lives in :func:`forces` and nowhere else (OSRD's
``TrainPhysicsIntegrator`` is the model)::

    m·ρ·dv/dt = F_traction + F_braking + F_basic + F_grade + F_curve

with ``ρ`` the rotating-mass factor.  Every term is a signed force along the
direction of travel: traction is ≥ 0, the others are ≤ 0 except the grade term
on a falling grade.  :func:`step` integrates it with RK4 (or Euler, for the
integrator measurement) and never lets braking or resistance reverse the
train: the speed is clamped at zero and the train stays stopped.

Units of seed 001 (Tiem 2020, eqs. 2–3)
---------------------------------------
The seed gives basic resistance ``w0 = a + b·v + c·v²`` with "a = 2.965 N,
b = 0.23 N·s/m, c = 0.005 N·s²/m²" and additional resistance
``wj = i + 600/R`` (i the grade, R the curve radius).  Lower-case ``w`` is the
Chinese traction-calculation convention (the seed's refs [2, 3]) for a
*specific* resistance, newtons per kilonewton of train weight: ``i`` in ‰
is literally i N/kN of grade force.  Read ``w0`` the same way, with ``v`` in
m/s as the stated units say:

* literally in newtons, w0(15 m/s) = 7.5 N for a whole train, nothing;
* in N/kN with v in km/h, w0(54 km/h) = 30 N/kN, several times what a metro
  train meets;
* in N/kN with v in m/s, w0(15 m/s) = 7.5 N/kN, high-ish but plausible for a
  metro train in tunnels.

So :class:`TrainModel` keeps the Davis coefficients as specific resistance
(N/kN, v in m/s) and multiplies by the weight.  We could not check the
seed's source for them ([7], Alnuman et al. 2018).

Curve resistance
----------------
The seed uses ``600/R`` N/kN (R in m), the form of Chinese traction
calculation and of the seed's refs [2, 3]; :data:`CURVE_RESISTANCE_K_N_PER_KN_M`
holds the 600.  Other rules give more at R = 500 m: Röckl's formula (German
practice), ``650/(R − 55)`` for R ≥ 300 m and ``500/(R − 30)`` below, gives
1.46 N/kN against 600/R's 1.20; the ``700/R`` often quoted for Soviet/Russian
practice gives 1.40, ``800/R`` 1.60.  We confirmed Röckl's form in several
public implementations; we did not trace a primary source for 700/R or 800/R,
so they are only the spread of the usual rules, not citations.  The
difference is small against grade resistance (6 N/kN on the seed's ±6 ‰).

Grade and curve resistance act on the whole train: both are averaged over its
length (head at ``x``, tail at ``x − length``).  That is the seed's eq. 3 in
general form (its ``L_r/L_c`` factor for a curve shorter than the train; the
printed condition ``R > L_c`` must mean the curve length) and it makes the
forces continuous in position, which RK4 likes.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import Literal, NamedTuple

G_MPS2 = 9.81
CURVE_RESISTANCE_K_N_PER_KN_M = 600.0  # seed 001 eq. 3: w_r = 600/R N/kN

Method = Literal["rk4", "euler"]


@dataclass(frozen=True)
class EffortCurve:
    """Maximum force against speed: constant force up to ``base_speed_mps``, then constant power.

    The seed's traction and electric-brake characteristics (its Figs. 1–2,
    not in the text we have) have this classic shape.
    """

    max_force_n: float
    base_speed_mps: float

    @property
    def power_w(self) -> float:
        """The constant power above the base speed."""
        return self.max_force_n * self.base_speed_mps

    def force_n(self, v_mps: float) -> float:
        """Available force at speed ``v_mps`` (m/s)."""
        if v_mps <= self.base_speed_mps:
            return self.max_force_n
        return self.max_force_n * self.base_speed_mps / v_mps


@dataclass(frozen=True)
class TrainModel:
    """A train as the integrator sees it.

    The Davis coefficients are specific resistance, N per kN of weight, with
    ``v`` in m/s (see the module docstring for why the seed's are read so).
    """

    mass_kg: float
    rotating_mass_factor: float
    length_m: float
    davis_a_n_per_kn: float
    davis_b_n_per_kn_per_mps: float
    davis_c_n_per_kn_per_mps2: float
    traction: EffortCurve
    braking: EffortCurve
    max_service_decel_mps2: float

    @property
    def weight_kn(self) -> float:
        return self.mass_kg * G_MPS2 / 1000.0

    @property
    def effective_mass_kg(self) -> float:
        """Mass plus the rotating masses' inertia: what the net force accelerates."""
        return self.mass_kg * self.rotating_mass_factor

    def basic_resistance_n(self, v_mps: float) -> float:
        """Davis running resistance in newtons (a magnitude, ≥ 0)."""
        w = self.davis_a_n_per_kn + v_mps * (self.davis_b_n_per_kn_per_mps + v_mps * self.davis_c_n_per_kn_per_mps2)
        return w * self.weight_kn

    def traction_available_n(self, v_mps: float) -> float:
        return self.traction.force_n(v_mps)

    def braking_available_n(self, v_mps: float) -> float:
        """Service braking force, capped so braking alone never exceeds the max service deceleration."""
        return min(self.braking.force_n(v_mps), self.effective_mass_kg * self.max_service_decel_mps2)


def seed_001_train() -> TrainModel:
    """The seed's 4-car metro train, filled in where the text is silent.

    From the seed: 4 cars, 2 of them motored, 190 kW traction motors, 80 m
    long (its scenario), Davis a, b, c.  "Two motor cars with 04 motors" is
    read as four per motor car (two motored bogies each), 1520 kW in all;
    four in all would halve the power.  Our choices: 160 t (40 t a car, about
    a loaded B-type metro car), ρ = 1.06, 170 kN starting effort (about
    1 m/s²), so the base speed is 8.9 m/s (32 km/h); blended service brake
    constant up to 60 km/h, and 1.2 m/s² max service deceleration, the top
    of the usual 1.0–1.2 m/s² metro range, because the seed's stop curve
    (15 m/s to 0 in 100 m) asks 1.125 m/s².
    """
    mass_kg = 160_000.0
    rho = 1.06
    decel = 1.2
    return TrainModel(
        mass_kg=mass_kg,
        rotating_mass_factor=rho,
        length_m=80.0,
        davis_a_n_per_kn=2.965,
        davis_b_n_per_kn_per_mps=0.23,
        davis_c_n_per_kn_per_mps2=0.005,
        traction=EffortCurve(max_force_n=170_000.0, base_speed_mps=8 * 190_000.0 / 170_000.0),
        braking=EffortCurve(max_force_n=mass_kg * rho * decel, base_speed_mps=60 / 3.6),
        max_service_decel_mps2=decel,
    )


def scaled_train(length_m: float) -> TrainModel:
    """Seed 001's train model scaled to a train of ``length_m``: about 2 t per metre, effort in proportion
    (the simulator's consists, and a parted train's rear part)."""
    base = seed_001_train()
    k = length_m / base.length_m
    return replace(
        base,
        mass_kg=base.mass_kg * k,
        length_m=length_m,
        traction=EffortCurve(base.traction.max_force_n * k, base.traction.base_speed_mps),
        braking=EffortCurve(base.braking.max_force_n * k, base.braking.base_speed_mps),
    )


@dataclass(frozen=True)
class Segment:
    """A stretch of line with one grade (‰, + uphill in the running direction) and one radius (m)."""

    start_m: float
    end_m: float
    grade_permille: float = 0.0
    radius_m: float = math.inf


class _Piecewise:
    """A piecewise-constant function of position (zero outside) and its running integral."""

    __slots__ = ("cum", "values", "xs")

    def __init__(self, pieces: list[tuple[float, float, float]]) -> None:
        edges = sorted({p for a, b, _ in pieces for p in (a, b)})
        self.xs: list[float] = edges
        self.values: list[float] = []
        for a, b in pairwise(edges):
            mid = 0.5 * (a + b)
            self.values.append(sum(v for s, e, v in pieces if s <= mid < e))
        self.values.append(0.0)  # beyond the last edge
        self.cum: list[float] = [0.0]
        for i in range(len(edges) - 1):
            self.cum.append(self.cum[-1] + self.values[i] * (edges[i + 1] - edges[i]))

    def at(self, x: float) -> float:
        i = bisect_right(self.xs, x) - 1
        return 0.0 if i < 0 else self.values[i]

    def integral(self, x: float) -> float:
        """∫ from −∞ to x."""
        i = bisect_right(self.xs, x) - 1
        if i < 0:
            return 0.0
        return self.cum[i] + self.values[i] * (x - self.xs[i])

    def mean(self, x_head: float, length_m: float) -> float:
        """Mean over [x_head − length_m, x_head]: what a train of that length feels."""
        if length_m <= 0.0:
            return self.at(x_head)
        return (self.integral(x_head) - self.integral(x_head - length_m)) / length_m


class LineProfile:
    """Grade and curvature along the line, from piecewise segments; level straight track elsewhere.

    Segments must not overlap.  Positions are chainages in metres along the
    running direction.
    """

    def __init__(self, segments: Iterable[Segment] = ()) -> None:
        self.segments: tuple[Segment, ...] = tuple(sorted(segments, key=lambda s: s.start_m))
        for s in self.segments:
            if not s.end_m > s.start_m:
                raise ValueError(f"segment {s}: end_m must be greater than start_m")
            if not s.radius_m > 0.0:
                raise ValueError(f"segment {s}: radius_m must be positive (inf on straight track)")
        for a, b in pairwise(self.segments):
            if b.start_m < a.end_m:
                raise ValueError(f"segments overlap: {a} and {b}")
        self._grade = _Piecewise([(s.start_m, s.end_m, s.grade_permille) for s in self.segments])
        self._curv = _Piecewise([(s.start_m, s.end_m, 1.0 / s.radius_m) for s in self.segments])

    def grade_permille(self, x_m: float) -> float:
        return self._grade.at(x_m)

    def radius_m(self, x_m: float) -> float:
        k = self._curv.at(x_m)
        return math.inf if k == 0.0 else 1.0 / k

    def mean_grade_permille(self, x_head_m: float, length_m: float) -> float:
        """Grade averaged over a train of ``length_m`` whose head is at ``x_head_m``."""
        return self._grade.mean(x_head_m, length_m)

    def mean_curvature_per_m(self, x_head_m: float, length_m: float) -> float:
        """1/R averaged over the train (0 on straight track)."""
        return self._curv.mean(x_head_m, length_m)

    def additional_resistance_n_per_kn(self, x_head_m: float, length_m: float) -> float:
        """Seed 001 eq. 3 without tunnels: i + 600/R, averaged over the train (N/kN)."""
        return self.mean_grade_permille(x_head_m, length_m) + CURVE_RESISTANCE_K_N_PER_KN_M * self.mean_curvature_per_m(
            x_head_m, length_m
        )


# The simulator's line: layouts carry no grades or curves yet.
LEVEL_LINE = LineProfile()


class NamedForces(NamedTuple):
    """The forces on the train in newtons, each signed along the direction of travel."""

    traction_n: float
    braking_n: float
    basic_n: float
    grade_n: float
    curve_n: float
    total_n: float


class TrainState(NamedTuple):
    x_m: float  # head chainage
    v_mps: float  # speed, ≥ 0


def _force_parts_n(
    model: TrainModel, profile: LineProfile, x_m: float, v_mps: float, command: float
) -> tuple[float, float, float, float, float]:
    """Traction, braking, basic, grade and curve forces (N): ``forces`` names them, the integrator sums them."""
    c = -1.0 if command < -1.0 else (1.0 if command > 1.0 else command)
    v = v_mps if v_mps > 0.0 else 0.0
    traction = c * model.traction_available_n(v) if c > 0.0 else 0.0
    braking = c * model.braking_available_n(v) if c < 0.0 else 0.0
    basic = -model.basic_resistance_n(v)
    if not profile.segments:
        # Level straight track (the simulator's line): the means below are 0, so these are -0.0 exactly.
        return traction, braking, basic, -0.0, -0.0
    w_kn = model.weight_kn
    grade = -w_kn * profile._grade.mean(x_m, model.length_m)
    curve = -w_kn * CURVE_RESISTANCE_K_N_PER_KN_M * profile._curv.mean(x_m, model.length_m)
    return traction, braking, basic, grade, curve


def forces(model: TrainModel, profile: LineProfile, x_m: float, v_mps: float, command: float) -> NamedForces:
    """The equation of motion's right-hand side at head position ``x_m`` and speed ``v_mps``.

    ``command`` in [−1, 1]: positive is that fraction of the traction available
    at this speed, negative that fraction of the service braking.  At a
    standstill a negative total means the train is held (brakes and starting
    resistance are reactions: they cannot pull it backwards).
    """
    traction, braking, basic, grade, curve = _force_parts_n(model, profile, x_m, v_mps, command)
    return NamedForces(traction, braking, basic, grade, curve, traction + braking + basic + grade + curve)


def _accel(model: TrainModel, profile: LineProfile, x: float, v: float, command: float) -> float:
    # The sum in forces' order, without building its named tuple (4 calls a step, the simulator's hot path).
    traction, braking, basic, grade, curve = _force_parts_n(model, profile, x, v, command)
    a = (traction + braking + basic + grade + curve) / model.effective_mass_kg
    if v <= 0.0 and a < 0.0:
        return 0.0  # held: resistance and brakes never reverse the train
    return a


def step(
    model: TrainModel,
    profile: LineProfile,
    state: TrainState,
    command: float,
    dt_s: float,
    method: Method = "rk4",
) -> TrainState:
    """Advance one fixed step with ``command`` held over it.

    If the speed would cross zero within the step the train stops there: the
    stopping time is interpolated linearly on speed and the distance taken at
    constant deceleration, so it stops (v = 0), never reverses.
    """
    x0, v0 = state
    if method == "rk4":
        k1v = _accel(model, profile, x0, v0, command)
        k1x = v0
        v2 = v0 + 0.5 * dt_s * k1v
        k2v = _accel(model, profile, x0 + 0.5 * dt_s * k1x, max(v2, 0.0), command)
        k2x = max(v2, 0.0)
        v3 = v0 + 0.5 * dt_s * k2v
        k3v = _accel(model, profile, x0 + 0.5 * dt_s * k2x, max(v3, 0.0), command)
        k3x = max(v3, 0.0)
        v4 = v0 + dt_s * k3v
        k4v = _accel(model, profile, x0 + dt_s * k3x, max(v4, 0.0), command)
        k4x = max(v4, 0.0)
        v1 = v0 + dt_s * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
        x1 = x0 + dt_s * (k1x + 2.0 * k2x + 2.0 * k3x + k4x) / 6.0
    elif method == "euler":
        a = _accel(model, profile, x0, v0, command)
        v1 = v0 + dt_s * a
        x1 = x0 + dt_s * v0
    else:
        raise ValueError(f"unknown integration method {method!r}: expected 'rk4' or 'euler'")
    if v1 < 0.0:
        t_stop = dt_s * v0 / (v0 - v1) if v0 > 0.0 else 0.0
        return TrainState(x0 + 0.5 * v0 * t_stop, 0.0)
    return TrainState(x1, v1)


# --- measuring the integrator ---------------------------------------------------

Drive = Callable[[float], float]  # time (s) → command


def default_drive(t_s: float) -> float:
    """Full traction for 40 s, coast 20 s, then 60 % service braking to a stop."""
    if t_s < 40.0:
        return 1.0
    if t_s < 60.0:
        return 0.0
    return -0.6


class IntegratorError(NamedTuple):
    max_position_error_m: float
    max_speed_error_mps: float
    dt_s: float
    reference_dt_s: float
    method: str


def run_drive(
    model: TrainModel,
    profile: LineProfile,
    drive: Drive,
    duration_s: float,
    dt_s: float,
    method: Method = "rk4",
    sample_every_s: float | None = None,
) -> list[TrainState]:
    """Run an open-loop drive (command as a function of time) and sample the state every ``sample_every_s``."""
    every = sample_every_s if sample_every_s is not None else dt_s
    per_sample = round(every / dt_s)
    n = round(duration_s / dt_s)
    state = TrainState(0.0, 0.0)
    out = [state]
    for i in range(n):
        state = step(model, profile, state, drive(i * dt_s), dt_s, method)
        if (i + 1) % per_sample == 0:
            out.append(state)
    return out


def measure_integrator(
    model: TrainModel,
    profile: LineProfile,
    drive: Drive = default_drive,
    duration_s: float = 120.0,
    dt_s: float = 0.1,
    reference_dt_s: float = 0.001,
    method: Method = "rk4",
) -> IntegratorError:
    """Max position and speed differences between a ``dt_s`` run and a fine-step RK4 reference.

    Both runs see the same drive, whose command changes only on multiples of
    ``dt_s``, and are compared at every coarse step.
    """
    coarse = run_drive(model, profile, drive, duration_s, dt_s, method)
    fine = run_drive(model, profile, drive, duration_s, reference_dt_s, "rk4", sample_every_s=dt_s)
    n = min(len(coarse), len(fine))
    dx = max(abs(coarse[i].x_m - fine[i].x_m) for i in range(n))
    dv = max(abs(coarse[i].v_mps - fine[i].v_mps) for i in range(n))
    return IntegratorError(dx, dv, dt_s, reference_dt_s, method)
