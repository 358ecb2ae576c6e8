"""Train dynamics: named forces, their signs, and the integrator's measured accuracy."""

from __future__ import annotations

import math
from itertools import pairwise

import pytest

from console.sim.dynamics import (
    G_MPS2,
    EffortCurve,
    LineProfile,
    Segment,
    TrainState,
    forces,
    measure_integrator,
    seed_001_train,
    step,
)

TRAIN = seed_001_train()
LEVEL = LineProfile()
# Seed 001 §4's line: +6 ‰ 200–400 m, curve R = 500 m 1000–1500 m with −6 ‰ 1100–1300 m.
SEED_LINE = LineProfile(
    [
        Segment(200.0, 400.0, grade_permille=6.0),
        Segment(1000.0, 1100.0, radius_m=500.0),
        Segment(1100.0, 1300.0, grade_permille=-6.0, radius_m=500.0),
        Segment(1300.0, 1500.0, radius_m=500.0),
    ]
)


def test_rk4_at_a_tenth_of_a_second_stays_within_a_centimetre_of_a_millisecond_reference() -> None:
    err = measure_integrator(TRAIN, SEED_LINE, dt_s=0.1, reference_dt_s=0.001)
    # measured: 0.3 mm and 0.0026 m/s (the speed error is at the final stop)
    assert err.max_position_error_m < 0.01
    assert err.max_speed_error_mps < 0.01


def test_euler_at_the_same_step_is_orders_of_magnitude_worse() -> None:
    rk4 = measure_integrator(TRAIN, SEED_LINE, dt_s=0.1)
    euler = measure_integrator(TRAIN, SEED_LINE, dt_s=0.1, method="euler")
    assert euler.max_position_error_m > 100 * rk4.max_position_error_m


def test_total_force_is_the_sum_of_the_named_terms() -> None:
    f = forces(TRAIN, SEED_LINE, 1250.0, 10.0, 0.4)
    assert f.total_n == pytest.approx(f.traction_n + f.braking_n + f.basic_n + f.grade_n + f.curve_n)


def test_uphill_slows_the_train_and_downhill_pulls_it() -> None:
    up = forces(TRAIN, SEED_LINE, 350.0, 10.0, 0.0)  # whole train on +6 ‰
    down = forces(TRAIN, SEED_LINE, 1250.0, 10.0, 0.0)  # whole train on −6 ‰
    assert up.grade_n == pytest.approx(-6.0 * TRAIN.weight_kn)
    assert down.grade_n == pytest.approx(+6.0 * TRAIN.weight_kn)
    assert up.total_n < forces(TRAIN, LEVEL, 350.0, 10.0, 0.0).total_n


def test_curve_resistance_is_600_over_r_newtons_per_kilonewton() -> None:
    f = forces(TRAIN, SEED_LINE, 1090.0, 10.0, 0.0)  # whole train in the R = 500 m curve
    assert f.curve_n == pytest.approx(-600.0 / 500.0 * TRAIN.weight_kn)
    assert forces(TRAIN, SEED_LINE, 800.0, 10.0, 0.0).curve_n == 0.0


def test_grade_and_curve_act_on_the_part_of_the_train_that_is_on_them() -> None:
    half_in = forces(TRAIN, SEED_LINE, 1040.0, 10.0, 0.0)  # 40 of 80 m in the curve
    assert half_in.curve_n == pytest.approx(-0.5 * 1.2 * TRAIN.weight_kn)
    assert SEED_LINE.mean_grade_permille(240.0, 80.0) == pytest.approx(3.0)


def test_basic_resistance_reads_the_seed_davis_terms_as_newtons_per_kilonewton_at_speed_in_mps() -> None:
    f = forces(TRAIN, LEVEL, 0.0, 15.0, 0.0)
    w0 = 2.965 + 0.23 * 15.0 + 0.005 * 15.0**2  # 7.54 N/kN
    assert f.basic_n == pytest.approx(-w0 * TRAIN.mass_kg * G_MPS2 / 1000.0)


def test_traction_is_constant_force_to_the_base_speed_then_constant_power() -> None:
    curve = EffortCurve(max_force_n=100_000.0, base_speed_mps=10.0)
    assert curve.force_n(5.0) == 100_000.0
    assert curve.force_n(20.0) == pytest.approx(50_000.0)
    assert forces(TRAIN, LEVEL, 0.0, 20.0, 1.0).traction_n == pytest.approx(TRAIN.traction.power_w / 20.0)


def test_command_beyond_the_unit_range_is_clipped() -> None:
    assert forces(TRAIN, LEVEL, 0.0, 5.0, 3.0).traction_n == forces(TRAIN, LEVEL, 0.0, 5.0, 1.0).traction_n
    assert forces(TRAIN, LEVEL, 0.0, 5.0, -3.0).braking_n == forces(TRAIN, LEVEL, 0.0, 5.0, -1.0).braking_n


def test_full_service_braking_never_exceeds_the_max_service_deceleration() -> None:
    f = forces(TRAIN, LEVEL, 0.0, 5.0, -1.0)
    assert -f.braking_n / TRAIN.effective_mass_kg == pytest.approx(TRAIN.max_service_decel_mps2)


def test_braking_stops_the_train_and_never_reverses_it() -> None:
    state = TrainState(0.0, 3.0)
    xs = [state.x_m]
    for _ in range(200):
        state = step(TRAIN, SEED_LINE, state, -1.0, 0.1)
        assert state.v_mps >= 0.0
        xs.append(state.x_m)
    assert state.v_mps == 0.0
    assert all(b >= a for a, b in pairwise(xs))
    # about v²/2a at 1.2 m/s² plus resistance
    assert xs[-1] == pytest.approx(3.0**2 / (2 * 1.2), rel=0.1)


def test_a_braked_train_stays_stopped_on_a_falling_grade() -> None:
    state = TrainState(1250.0, 0.0)
    for _ in range(50):
        state = step(TRAIN, SEED_LINE, state, -0.5, 0.1)
    assert state == TrainState(1250.0, 0.0)


def test_resistance_alone_does_not_start_a_standing_train_on_the_level() -> None:
    assert step(TRAIN, LEVEL, TrainState(0.0, 0.0), 0.0, 0.1) == TrainState(0.0, 0.0)


def test_an_unknown_integration_method_is_refused() -> None:
    with pytest.raises(ValueError, match="rk4"):
        step(TRAIN, LEVEL, TrainState(0.0, 1.0), 0.0, 0.1, method="midpoint")  # type: ignore[arg-type]


def test_overlapping_segments_are_refused_with_both_named() -> None:
    with pytest.raises(ValueError, match="overlap"):
        LineProfile([Segment(0.0, 100.0, 1.0), Segment(50.0, 150.0, 2.0)])


def test_profile_reads_grade_and_radius_at_a_point() -> None:
    assert SEED_LINE.grade_permille(300.0) == 6.0
    assert SEED_LINE.grade_permille(500.0) == 0.0
    assert SEED_LINE.radius_m(1200.0) == pytest.approx(500.0)
    assert math.isinf(SEED_LINE.radius_m(1600.0))
