"""Seed 001's ATO scenario: the run, its metrics beside the paper's, and the views."""

from __future__ import annotations

import io
import json
import math
import time

import numpy as np
import pytest
from rich.console import Console

from console.sim.ato import (
    PAPER_FIGURES,
    PAPER_ORDERINGS,
    SEED_001,
    STEADY_WINDOW_M,
    Driver,
    ScenarioResult,
    braking_target_speed,
    metrics,
    run_all,
    run_scenario,
)
from console.sim.control import CONTROLLER_NAMES, FUZZY_D_K, U_FULL, IdentifiedModel, fuzzy_interp
from console.sim.dynamics import LineProfile, TrainState, seed_001_train
from console.sinks.tables.ato_view import ato_json, ato_plot, ato_table


@pytest.fixture(scope="module")
def runs() -> list[ScenarioResult]:
    return run_all()


Figures = dict[tuple[str, str], dict[str, float | None]]


@pytest.fixture(scope="module")
def figures(runs: list[ScenarioResult]) -> Figures:
    """Metrics by (plant, controller); Fuzzy-D as printed is "fuzzy-d", the other reading "fuzzy-d/normalised"."""
    return {(r.plant, r.controller + ("/normalised" if r.reading == "normalised" else "")): metrics(r) for r in runs}


def test_paper_figures_are_as_published() -> None:
    # Seed 001 §4 (Tiem 2020), about its Figs. 15-16
    assert PAPER_FIGURES["pid"]["overshoot_pct"] == 9.7
    assert PAPER_FIGURES["pid"]["stop_error_m"] == 30.0
    assert PAPER_FIGURES["fuzzy"] == {
        "overshoot_pct": 0.2,
        "distance_to_target_m": 12.0,
        "steady_state_error_mps": 0.272,
        "stop_error_m": 4.5,
    }
    assert PAPER_FIGURES["fuzzy-d"]["steady_state_error_mps"] == 0.028
    assert PAPER_FIGURES["fuzzy-d"]["stop_error_m"] == 1.0


def test_braking_target_speed_is_the_speed_that_can_still_brake_to_the_point() -> None:
    assert braking_target_speed(100.0, 0.0, 1.125) == pytest.approx(15.0)
    assert braking_target_speed(100.0, 10.5, (15.0**2 - 10.5**2) / 200.0) == pytest.approx(15.0)
    assert braking_target_speed(-5.0, 10.5, 1.0) == 10.5


def test_target_speed_follows_the_seed_line() -> None:
    t = SEED_001.target_mps
    assert t(0.0) == 15.0
    assert t(899.0) == 15.0  # speed changes begin 100 m ahead of the curve
    assert t(950.0) == pytest.approx(math.sqrt(10.5**2 + (15.0**2 - 10.5**2) / 100.0 * 50.0))
    assert t(1000.0) == 10.5
    assert t(1579.0) == 10.5  # the tail is still in the curve
    assert t(1581.0) == 15.0
    assert t(1950.0) == pytest.approx(math.sqrt(2 * 1.125 * 50.0))
    assert t(2000.0) == 0.0


@pytest.mark.parametrize("plant", ["force", "linear"])
@pytest.mark.parametrize("name", CONTROLLER_NAMES)
def test_every_controller_ends_stopped_near_2000_m(runs: list[ScenarioResult], name: str, plant: str) -> None:
    r = next(r for r in runs if r.controller == name and r.plant == plant)
    assert r.reading == ("output-gain" if name == "fuzzy-d" else "")
    assert r.ended == "stopped"
    assert r.v_mps[-1] == 0.0
    assert abs(r.final_x_m - 2000.0) < 50.0
    assert np.all(np.diff(r.x_m) >= 0.0)


def _value(figs: Figures, plant: str, name: str, metric: str) -> float:
    v = figs[(plant, name)][metric]
    return math.inf if v is None else v


# Pairs (better, worse) where the seed claims an order, and what our model gives.
_PAIRS = [
    (plant, metric, order[i], order[i + 1])
    for plant in ("force", "linear")
    for metric, order in PAPER_ORDERINGS.items()
    for i in range(len(order) - 1)
]
# Orderings our honest model reverses, each with why (strict: an unexpected pass fails).
# Fuzzy-D here is the seed's eqs. 6-7 as printed (K multiplies SpeedT-scale output);
# under the normalised reading it ties with fuzzy (test_normalised_fuzzy_d_...).
_NOT_REPRODUCED = {
    ("force", "overshoot_pct", "fuzzy-d", "fuzzy"): (
        True,
        "SpeedT does not overshoot on our train at all (0 %); Fuzzy-D's limit cycle at 50 ms peaks 0.04 % over",
    ),
    ("linear", "overshoot_pct", "fuzzy-d", "fuzzy"): (
        True,
        "neither overshoots G(s) (0 % = 0 %): the seed's 0.2 % for SpeedT is not reproduced",
    ),
    ("force", "distance_to_target_m", "fuzzy", "pid"): (
        True,
        "the PID holds full traction until close; the rule (e PB, ė NB) → PS makes the fuzzy ease off early",
    ),
    ("linear", "overshoot_pct", "fuzzy", "pid"): (
        True,
        "under saturation with anti-windup the PID creeps up on 15 m/s from below on G(s): no overshoot",
    ),
    ("linear", "distance_to_target_m", "fuzzy", "pid"): (
        True,
        "without an integral the fuzzy settles 0.5 m/s short on G(s) and never comes within 2 %",
    ),
}


@pytest.mark.parametrize(
    ("plant", "metric", "better", "worse"),
    [
        pytest.param(
            *pair,
            marks=[pytest.mark.xfail(strict=True, reason=_NOT_REPRODUCED[pair][1])] if pair in _NOT_REPRODUCED else [],
            id="-".join(pair),
        )
        for pair in _PAIRS
    ],
)
def test_paper_ordering(figures: Figures, plant: str, metric: str, better: str, worse: str) -> None:
    assert _value(figures, plant, better, metric) < _value(figures, plant, worse, metric)


def test_normalised_fuzzy_d_and_fuzzy_differ_by_less_than_one_percent(figures: Figures) -> None:
    # K cancels under this reading: only K_D·ė (0.5 % of full effort per m/s²) is left
    for plant in ("force", "linear"):
        for metric in ("overshoot_pct", "steady_state_error_mps", "stop_error_m", "distance_to_target_m"):
            a, b = _value(figures, plant, "fuzzy", metric), _value(figures, plant, "fuzzy-d/normalised", metric)
            assert a == b or abs(a - b) <= 0.01 * max(abs(a), abs(b)) + 1e-6


def _steady_error(r: ScenarioResult) -> tuple[float, float]:
    """Mean speed error and its spread over the metrics' steady window (700-900 m)."""
    w = (r.x_m >= STEADY_WINDOW_M[0]) & (r.x_m < STEADY_WINDOW_M[1])
    e = r.target_mps[w] - r.v_mps[w]
    return float(e.mean()), float(e.std())


def test_steady_error_ratio_on_g_of_s_is_what_eq_6_implies(runs: list[ScenarioResult]) -> None:
    # Seed 001 eqs. 6-7 with ė = 0 at a steady state: SpeedT holds the speed with
    # U_FULL·f(e_F) and Fuzzy-D with K·U_FULL·f(e_D).  The seed's errors, 0.272 and
    # 0.028 m/s, are in ratio 9.7, close to K = 10.  Ours: the same relation, with
    # our rule surface f (steeper near 0 than at 0.5 m/s, so the ratio exceeds K).
    plant = IdentifiedModel()
    by = {(r.controller, r.reading): r for r in runs if r.plant == "linear"}
    e_f, spread_f = _steady_error(by[("fuzzy", "")])
    e_d, spread_d = _steady_error(by[("fuzzy-d", "output-gain")])
    assert spread_f < 1e-3 and spread_d < 1e-3  # settled, no oscillation
    # each holds its speed with the effort its equation gives (DC gain of G(s))
    u_f = U_FULL * fuzzy_interp(e_f, 0.0)
    u_d = FUZZY_D_K * U_FULL * fuzzy_interp(e_d, 0.0)
    assert u_f * plant.dc_speed_per_u == pytest.approx(15.0 - e_f, abs=0.01)
    assert u_d * plant.dc_speed_per_u == pytest.approx(15.0 - e_d, abs=0.01)
    # hence the ratio: K times the ratio of the surface's slopes at the two errors
    slope_ratio = (fuzzy_interp(e_d, 0.0) / e_d) / (fuzzy_interp(e_f, 0.0) / e_f)
    assert e_f / e_d == pytest.approx(FUZZY_D_K * slope_ratio * (15.0 - e_f) / (15.0 - e_d), rel=0.02)
    assert FUZZY_D_K / 2 < e_f / e_d < 2 * FUZZY_D_K  # the seed's 9.7 is within this; ours is 17
    # under the normalised reading K cancels: ratio 1
    e_n, _ = _steady_error(by[("fuzzy-d", "normalised")])
    assert e_f / e_n == pytest.approx(1.0, abs=0.01)


def test_fuzzy_d_as_printed_limit_cycles_on_the_force_model_at_50_ms_and_settles_at_20_ms() -> None:
    # Not a tuning: a measured property of the sampled loop with K = 10, shown in docs/ato.md.
    coarse = run_scenario("fuzzy-d", "force", dt_s=0.05)
    fine = run_scenario("fuzzy-d", "force", dt_s=0.02)
    w = (coarse.x_m >= STEADY_WINDOW_M[0]) & (coarse.x_m < STEADY_WINDOW_M[1])
    assert coarse.command[w].min() == -1.0 and coarse.command[w].max() == 1.0  # full braking to full traction
    e_fine, spread_fine = _steady_error(fine)
    assert spread_fine < 1e-3
    e_speedt, _ = _steady_error(run_scenario("fuzzy", "force", dt_s=0.02))
    assert FUZZY_D_K / 2 < e_speedt / e_fine < 2 * FUZZY_D_K


def test_metrics_read_overshoot_and_reach_from_the_first_stretch() -> None:
    x = np.linspace(0.0, 2000.0, 2001)
    v = np.full_like(x, 15.0)
    v[:100] = np.linspace(0.0, 14.0, 100)
    v[100:150] = 16.5  # 10 % over, reached at 100 m
    v[-1] = 0.0
    r = ScenarioResult("pid", "force", 0.05, x, x, v, np.full_like(x, 15.0), np.zeros_like(x), 2000.0, "stopped")
    m = metrics(r)
    assert m["overshoot_pct"] == pytest.approx(10.0)
    assert m["distance_to_target_m"] == 100.0
    assert m["steady_state_error_mps"] == 0.0
    assert m["stop_error_m"] == 0.0


def test_an_unknown_plant_is_refused() -> None:
    with pytest.raises(ValueError, match="force"):
        run_scenario("pid", plant="simulink")


def test_ato_json_has_our_figures_the_plant_and_the_papers(runs: list[ScenarioResult]) -> None:
    rows = ato_json(runs)
    assert len(rows) == 6  # one per controller and plant; Fuzzy-D's other reading inside its row
    keys = {
        "controller",
        "plant",
        "reading",
        "overshoot_pct",
        "distance_to_target_m",
        "steady_state_error_mps",
        "stop_error_m",
        "paper",
    }
    for row in rows:
        assert set(row) == (keys | {"other_readings"} if row["controller"] == "fuzzy-d" else keys)
        assert "wording" in row["paper"]
        if row["controller"] == "fuzzy-d":
            assert row["reading"] == "output-gain"
            (other,) = row["other_readings"]
            assert other["reading"] == "normalised" and set(other) == keys - {"controller", "plant", "paper"}
    json.dumps(rows, allow_nan=False)


def _render(renderable: object) -> str:
    buf = io.StringIO()
    Console(file=buf, width=80, color_system=None, force_terminal=False).print(renderable)
    return buf.getvalue()


def test_ato_table_fits_80_columns_and_shows_both_sources(runs: list[ScenarioResult]) -> None:
    out = _render(ato_table(runs))
    assert max(len(line) for line in out.splitlines()) <= 80
    assert "paper" in out and "force" in out and "linear" in out and "9.7" in out
    assert "K normalised" in out  # both readings of Fuzzy-D, beside the paper's row


def test_ato_plot_draws_every_controller_and_the_target_without_a_terminal(runs: list[ScenarioResult]) -> None:
    out = _render(ato_plot(runs, width=80, height=20))
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 80
    plot = "\n".join(lines[1:21])
    assert "P" in plot and ("F" in plot or "D" in plot or "*" in plot) and "·" in plot
    assert "2000" in out


def test_driver_and_one_dynamics_step_cost_well_under_50_microseconds() -> None:
    driver = Driver(seed_001_train(), "fuzzy-d")
    profile = SEED_001.profile
    state = TrainState(0.0, 0.0)
    n = 20_000
    # CPU time of this process, not wall time: the cost of the step, whatever else runs on the cores.
    t0 = time.process_time()
    for _ in range(n):
        state = driver.step(profile, state, SEED_001.target_mps(state.x_m % 1900.0), 0.05)
    per_step_us = (time.process_time() - t0) / n * 1e6
    assert per_step_us < 50.0  # measured about 12 µs


def test_driver_command_is_the_controllers() -> None:
    d = Driver(seed_001_train(), "pid")
    assert d.command(15.0, 0.0, 0.05) == 1.0
    assert isinstance(LineProfile(), LineProfile)
