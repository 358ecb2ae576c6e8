"""Speed controllers of seed 001 and its identified plant G(s)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from console.sim.control import (
    FUZZY_D_K,
    FUZZY_D_KD,
    INPUT_CENTRES,
    INPUT_SETS,
    OUTPUT_CENTRES,
    OUTPUT_SETS,
    PID,
    RULES,
    SURFACE_MAX_ERROR,
    U_FULL,
    Fuzzy,
    FuzzyD,
    IdentifiedModel,
    IdentifiedState,
    fuzzy_exact,
    fuzzy_interp,
    identified_step,
    make_controller,
    step_response,
)
from console.sim.dynamics import LineProfile

RNG = np.random.default_rng(2020)


def test_rule_table_is_seed_001_table_2() -> None:
    # Seed 001 Table 2 (rows ė, columns e), spot checks of every row
    assert RULES[0] == ("NB", "NB", "NM", "Z", "PS")
    assert RULES[2] == ("NB", "NM", "Z", "PM", "PB")
    assert RULES[4] == ("NS", "Z", "PM", "PB", "PB")
    # and the table is odd: swapping signs of e and ė negates the output
    neg = {"NB": "PB", "NM": "PM", "NS": "PS", "Z": "Z", "PS": "NS", "PM": "NM", "PB": "NB"}
    for i in range(5):
        for j in range(5):
            assert RULES[4 - i][4 - j] == neg[RULES[i][j]]


def test_surface_is_zero_at_rest_and_full_at_the_corners() -> None:
    assert fuzzy_exact(0.0, 0.0)[0] == pytest.approx(0.0, abs=1e-12)
    assert fuzzy_exact(1.0, 0.0)[0] == pytest.approx(1.0)
    assert fuzzy_exact(-1.0, -1.0)[0] == pytest.approx(-1.0)
    # beyond the universe the inputs saturate
    assert fuzzy_interp(5.0, 0.0) == pytest.approx(1.0)


def _skfuzzy_system(output_step: float) -> Any:
    fuzz = pytest.importorskip("skfuzzy")
    ctrl = pytest.importorskip("skfuzzy.control")
    ui = np.linspace(-1.0, 1.0, 401)
    uo = np.linspace(-4 / 3, 4 / 3, round((8 / 3) / output_step) + 1)
    e, de = ctrl.Antecedent(ui, "e"), ctrl.Antecedent(ui, "de")
    u = ctrl.Consequent(uo, "u", defuzzify_method="centroid")
    for name, c in zip(INPUT_SETS, INPUT_CENTRES, strict=True):
        e[name] = fuzz.trimf(ui, [c - 0.5, c, c + 0.5])
        de[name] = fuzz.trimf(ui, [c - 0.5, c, c + 0.5])
    for name, c in zip(OUTPUT_SETS, OUTPUT_CENTRES, strict=True):
        u[name] = fuzz.trimf(uo, [c - 1 / 3, c, c + 1 / 3])
    rules = [ctrl.Rule(e[INPUT_SETS[j]] & de[INPUT_SETS[i]], u[RULES[i][j]]) for i in range(5) for j in range(5)]
    return ctrl.ControlSystemSimulation(ctrl.ControlSystem(rules))


def _skfuzzy_eval(sim: Any, e: float, de: float) -> float:
    sim.input["e"] = e
    sim.input["de"] = de
    sim.compute()
    return float(sim.output["u"])


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # inside scikit-fuzzy
def test_exact_rule_base_agrees_with_scikit_fuzzy_on_the_same_rules() -> None:
    # scikit-fuzzy samples the output universe (here every 0.001) and misses the
    # odd bend between samples; its result converges on ours as the step squared.
    sim = _skfuzzy_system(output_step=0.001)
    e, de = RNG.uniform(-1, 1, 80), RNG.uniform(-1, 1, 80)
    ours = fuzzy_exact(e, de)
    theirs = np.array([_skfuzzy_eval(sim, a, b) for a, b in zip(e, de, strict=True)])
    assert np.max(np.abs(ours - theirs)) < 1e-5  # measured 1.6e-6


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_interpolated_surface_is_within_its_stated_error_of_scikit_fuzzy() -> None:
    sim = _skfuzzy_system(output_step=0.001)
    e, de = RNG.uniform(-1, 1, 80), RNG.uniform(-1, 1, 80)
    theirs = np.array([_skfuzzy_eval(sim, a, b) for a, b in zip(e, de, strict=True)])
    ours = np.array([fuzzy_interp(a, b) for a, b in zip(e, de, strict=True)])
    assert np.max(np.abs(ours - theirs)) < SURFACE_MAX_ERROR


def test_interpolated_surface_is_within_its_stated_error_of_the_exact_one() -> None:
    e, de = RNG.uniform(-1.2, 1.2, 20_000), RNG.uniform(-1.2, 1.2, 20_000)
    exact = fuzzy_exact(e, de)
    interp = np.array([fuzzy_interp(a, b) for a, b in zip(e, de, strict=True)])
    assert np.max(np.abs(exact - interp)) < SURFACE_MAX_ERROR  # measured 0.004


def test_fuzzy_controller_runs_thousands_of_steps_a_second() -> None:
    ctl = Fuzzy()
    n = 20_000
    t0 = time.process_time()  # CPU time: the controller's cost, whatever else runs on the cores
    for i in range(n):
        ctl.update(15.0, 10.0 + (i % 100) * 0.05, 0.05)
    assert n / (time.process_time() - t0) > 5_000


def test_pid_step_on_the_identified_model_overshoots_about_ten_percent_and_settles() -> None:
    # Seed 001 §4: "độ quá điều chỉnh 9,7%" for its PID (eq. 5) on G(s) (eq. 4).
    # Our unsaturated 1 m/s step, no derivative kick: 9.5 %.  With the kick of an
    # ideal PID the continuous-time loop overshoots only 3.1 %.
    _, v = step_response(PID(), step_mps=1.0, duration_s=200.0)
    overshoot = 100.0 * (v.max() - 1.0)
    assert 8.5 < overshoot < 10.5
    assert v[-1] == pytest.approx(1.0, abs=1e-3)  # the integral leaves no steady-state error


def test_pid_freezes_its_integral_while_saturated() -> None:
    pid = PID()
    for _ in range(100):
        assert pid.update(15.0, 0.0, 0.05) == 1.0
    assert pid.integral == 0.0
    pid.update(15.0, 14.9, 0.05)  # out of saturation: integrates again
    assert pid.integral > 0.0


def test_fuzzy_d_as_printed_multiplies_speedt_effort_by_k_and_adds_k_d_times_the_error_rate() -> None:
    # Seed 001 eq. 7: u = 10·U_Fuzzy + 0.05·ė, U_Fuzzy on SpeedT's scale (u = U_FULL·f)
    plain, fd = Fuzzy(), FuzzyD()
    assert fd.reading == "output-gain"
    for ctl in (plain, fd):
        ctl.update(15.0, 14.99, 0.05)
    a, b = plain.update(15.0, 14.995, 0.05), fd.update(15.0, 14.995, 0.05)
    assert abs(a) < 0.1  # small enough that K·a stays unsaturated
    assert b == pytest.approx(FUZZY_D_K * a + FUZZY_D_KD * fd.rate.rate / U_FULL)


def test_fuzzy_d_saturates_where_k_times_speedt_would_exceed_full_effort() -> None:
    fd = FuzzyD()
    fd.update(15.0, 14.0, 0.05)
    assert fd.update(15.0, 14.0, 0.05) == 1.0  # SpeedT gives 0.67 here; 6.7 of full effort is clipped


def test_fuzzy_d_normalised_reading_is_speedt_plus_k_d_times_the_error_rate() -> None:
    plain, fd = Fuzzy(), FuzzyD(reading="normalised")
    for ctl in (plain, fd):
        ctl.update(15.0, 14.0, 0.05)
    a, b = plain.update(15.0, 14.2, 0.05), fd.update(15.0, 14.2, 0.05)
    assert b - a == pytest.approx(0.05 * fd.rate.rate / U_FULL)


def test_an_unknown_fuzzy_d_reading_is_refused() -> None:
    with pytest.raises(ValueError, match="output-gain or normalised"):
        FuzzyD(reading="scaled")
    assert isinstance(make_controller("fuzzy-d", "normalised"), FuzzyD)


@pytest.mark.parametrize("name", ["pid", "fuzzy", "fuzzy-d"])
def test_every_controller_commands_within_the_unit_range(name: str) -> None:
    ctl = make_controller(name)
    for target, speed in [(15.0, 0.0), (0.0, 15.0), (10.0, 10.0), (15.0, 30.0), (0.0, 0.0)]:
        assert -1.0 <= ctl.update(target, speed, 0.05) <= 1.0


def test_an_unknown_controller_name_is_refused_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match="pid, fuzzy, fuzzy-d"):
        make_controller("mpc")


def test_identified_model_holds_its_dc_gain() -> None:
    # G(0) = 612 / 0.34 / 822.4 = 2.189 m/s per unit of u; command 0.5 is u = 5
    plant, state = IdentifiedModel(), IdentifiedState(0.0, 0.0, 0.0)
    for _ in range(3000):
        state = identified_step(plant, LineProfile(), state, 0.5, 0.1)
    assert state.v_mps == pytest.approx(5.0 * plant.dc_speed_per_u, rel=1e-4)


def test_identified_model_stops_rather_than_reverses() -> None:
    state = IdentifiedState(0.0, 2.0, 0.0)
    for _ in range(600):
        state = identified_step(IdentifiedModel(), LineProfile(), state, -1.0, 0.05)
        assert state.v_mps >= 0.0
    assert state.v_mps == 0.0
