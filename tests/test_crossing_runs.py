"""The crossing controller against ground truth over randomized runs (issues 4 and "Real data first" §3).

Fixes at 2.5 Hz, at 0.1 Hz or every 1-10 s, GNSS noise σ up to 5 m, packet
loss up to 30 %, radio latency, head or EOT unit failures, trains up to
35 m/s (faster than the line speed the unit is told), half the exports
without a speed column, half the runs with position jumps; trains that run
through, crawl, stop before the crossing, or stop with their tail still on
the road.

Each run is also judged against an oracle (issue 25): the unit's own bounds
on the true motion, on at the last safe moment; what the unit warns earlier
is the avoidable spare (benchmarks/crossing_spare.py prints it by case).

CI runs 300 runs (about 20 s of CPU: each run filters every fix).  The full
sweep the issues ask for:
``TRACKSIDE_CROSSING_RUNS=3000 python -m pytest tests/test_crossing_runs.py``.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from console.layout import load_layout
from console.sim.crossing_runs import SCENARIOS, RunConditions, many_runs, one_run, spare_table, summary

LAYOUT = load_layout("example")
RUNS = int(os.environ.get("TRACKSIDE_CROSSING_RUNS", "300"))


@pytest.fixture(scope="module")
def results() -> list:
    return many_runs(LAYOUT, RUNS, seed=2026)


def test_the_sweep_covers_no_speed_jumps_and_both_fix_rates(results: list) -> None:
    s = summary(results)
    for key in ("runs_without_speed", "runs_with_jumps", "runs_at_2_5_hz", "runs_at_0_1_hz"):
        assert s[key] >= RUNS // 5, key


def test_no_safety_violation(results: list) -> None:
    bad = [(c, r.violation) for c, r in results if r.violation]
    assert bad == []


def test_no_late_warning(results: list) -> None:
    # A lead shorter than the crossing's warning time is a violation of its own (late_by_s).
    late = [(c, r.late_by_s) for c, r in results if r.late_by_s is not None]
    assert late == []
    s = summary(results)
    assert s["min_lead_minus_warning_time_s"] is not None and s["min_lead_minus_warning_time_s"] >= 0


def test_excess_warning_is_about_two_fix_periods(results: list) -> None:
    # Off needs two EOT fixes past the crossing (one jump cannot open the road): the
    # road stays closed about one fix period longer than issue 4's single-fix target.
    excess = [r.excess_s - 2 * c.period_s for c, r in results if r.excess_s is not None]
    assert float(np.median(excess)) <= 5.0


def test_jumps_are_set_aside_and_clean_runs_lose_no_fix(results: list) -> None:
    s = summary(results)
    assert s["jumps_sent"] and s["jumps_set_aside"]
    # A clean run loses no fix, or very nearly: the plausibility gate allows 2 × 15 m of noise
    # between two fixes, which Gaussian noise of σ 5 m exceeds about once in 3·10⁶ pairs (a
    # 3000-run sweep met it once: a fix 36 m from one 0.46 s before, at σ 4.8 m).
    clean = [r for c, r in results if c.jump_rate == 0]
    assert sum(r.jumps_set_aside > 0 for r in clean) <= len(clean) // 1000


def test_only_a_failed_eot_holds_the_warning_on(results: list) -> None:
    held = [c for c, r in results if r.held]
    assert held and all(c.eot_fails_at_s is not None for c in held)
    # ... and every run whose EOT failed before the tail cleared raises an alarm.
    assert all(r.alarms > 0 for c, r in results if r.held)


def test_fixed_time_baseline_would_open_too_early_where_trains_stop_on_the_road(results: list) -> None:
    early = [c.scenario for c, r in results if r.baseline_early_s]
    assert early and "stop_on_crossing" in early


def test_the_truth_keeps_to_the_units_bounds_so_the_oracle_is_never_late(results: list) -> None:
    # The oracle applies the unit's bounds to the true motion: on the harness's trains (no faster
    # acceleration, no departure above the line speed) it is never late, so the avoidable spare
    # (the oracle's onset − the unit's) measures doubt, not a harness that breaks the bounds.
    physics = [r.physics_s for _, r in results if r.physics_s is not None]
    assert len(physics) > 0.9 * RUNS and min(physics) >= 0.0
    assert all(r.fix_oracle_lead_s is None or r.fix_oracle_lead_s >= r.warning_time_s for _, r in results)
    # So is the exact-positions yardstick: its speed bound from the true positions holds on these trains, up to
    # the truth's own integration: in 0.2 s Euler steps (speed first, then position) the positions
    # run half a step ahead of a motion that keeps to the acceleration bound, so up to 0.1 s of lead.
    exact = [r.exact_lead_s - r.warning_time_s for _, r in results if r.exact_lead_s is not None]
    assert len(exact) > 0.9 * RUNS and min(exact) >= -0.1


def test_the_exact_positions_yardstick_is_the_fix_time_oracle_where_the_speed_is_reported(results: list) -> None:
    # The same knowledge (the true state at each fix) where the export reports the speed; without
    # it, the yardstick bounds the speed from positions and warns earlier: that is what no speed costs.
    with_speed = [(r.exact_lead_s, r.fix_oracle_lead_s) for c, r in results if c.speed_reported and r.exact_lead_s]
    assert with_speed and all(a == b for a, b in with_speed)
    without = [(r.exact_lead_s, r.fix_oracle_lead_s) for c, r in results if not c.speed_reported and r.exact_lead_s]
    assert without and sum(a > b + 1.0 for a, b in without if b is not None) > len(without) // 4


def test_the_avoidable_spare_is_measured_by_scenario_and_fix_rate(results: list) -> None:
    rows = {r.case: r for r in spare_table(results)}
    for case in ("all runs", "no speed", "fixes 0.1 Hz", *(f"scenario {sc}" for sc in SCENARIOS)):
        assert rows[case].runs > 0 and rows[case].median_s is not None, case
    # Warned no later than the oracle in every run (the bounds held where it mattered) ...
    assert all(r.avoidable_s is None or r.avoidable_s >= -0.5 for _, r in results)
    # ... and the hindsight physics `trackside crossing` shows is close to the true one.
    assert summary(results)["median_abs_error_hindsight_physics_s"] < 2.0


def test_a_released_road_stays_open_a_while(results: list) -> None:
    # A release needs the road open 10 s at least by the bound, and until the next fix is due: no
    # barriers up for a few seconds only (a fix can bring the bound a little nearer: rarely).
    s = summary(results)
    assert s["runs_released"] and s["runs_reopened_under_10s"] <= len(results) // 1000
    assert all(r.min_open_s is None or r.min_open_s >= 5.0 for _, r in results)


# Runs where a release came on again within seconds (found on seed 777001, before the release needed the
# head's own filter settled and, at an EOT fix, a head unit reporting on time).
REOPENED = [
    # A brake unsettled the head's track; the train's filter, settled again a fix sooner, released.
    (
        "12+940",
        RunConditions(
            10.0,
            4.82,
            0.2797,
            0.307,
            None,
            None,
            "stop_far",
            15.91,
            1,
            300.0,
            77700100009,
            speed_reported=False,
            jump_rate=0.0165,
        ),
    ),
    # The head unit fell silent after one fix; an EOT fix released, then the head went stale.
    (
        "11+850",
        RunConditions(10.0, 0.466, 0.0091, 1.436, 8.99, None, "stop_far", 5.58, 1, 28.6, 77700100836, jump_rate=0.0278),
    ),
    # A head fix that jumped 1.9 km, then an EOT fix released on the train's filter.
    (
        "11+850",
        RunConditions(
            0.4,
            1.4983538438944848,
            0.01759579021625792,
            0.42497525786867163,
            31.4296029238321,
            None,
            "stop_on_crossing",
            25.381075305813027,
            -1,
            28.6,
            77700101508,
            jump_rate=0.023041672117800022,
        ),
    ),
]


@pytest.mark.parametrize(("code", "cond"), REOPENED)
def test_a_release_is_not_undone_within_seconds(code: str, cond: RunConditions) -> None:
    crossing = next(c for c in LAYOUT.crossings if c.code == code)
    v = one_run(LAYOUT, crossing, cond)
    assert v.violation is None
    assert v.min_open_s is None or v.min_open_s >= 10.0, v.min_open_s


# Trains standing before the crossing while position jumps the filters took tilted their EOT's medians: one witness,
# after another had disagreed, reversed the direction; the standing EOT then read as past the crossing and the
# warning ended; the train moved on and was warned 26 s (42.8 s) late.  Found by benchmarks/crossing_spare.py
# --seed 4848 (run 162) and a scan of seed 4849 (run 147).
REVERSED_BY_ONE_WITNESS = [
    (
        "11+850",
        RunConditions(
            5.54793335407794,
            1.5626899985455711,
            0.07637294542897839,
            0.9984206366417865,
            None,
            None,
            "stop_before",
            18.87717564791994,
            1,
            300.0,
            484800162,
            jump_rate=0.044315065374846085,
        ),
    ),
    (
        "12+940",
        RunConditions(
            10.0,
            0.9408909760803602,
            0.1770631906230405,
            1.1126822070384246,
            None,
            None,
            "stop_before",
            20.116978050035996,
            -1,
            300.0,
            484900147,
            jump_rate=0.024365285903535757,
        ),
    ),
]


@pytest.mark.parametrize(("code", "cond"), REVERSED_BY_ONE_WITNESS)
def test_a_standing_train_is_not_turned_round_by_one_witness(code: str, cond: RunConditions) -> None:
    crossing = next(c for c in LAYOUT.crossings if c.code == code)
    v = one_run(LAYOUT, crossing, cond)
    assert v.violation is None and v.late_by_s is None
    assert v.lead_s is not None and v.lead_s >= crossing.warning_time_s


# One EOT fix is no proof that the tail is past, nor is a standing EOT "moving away".  The first: the EOT's first
# fix jumped 262 m past the crossing, its next (true) one was set aside against it, and the unit failed; the
# train, approaching, was never warned (seed 4851, run 761).  The second: a head unit lost at 5.5 s, the EOT's
# filter swayed by jumps set the direction wrong, and the EOT standing on the road's near side with the train
# stopped across it was "108 m past and moving away": the road opened (seed 4852, run 1149, with the direction
# rule of f4b6fac alone; the moving-away rule stops it).
TAIL_NOT_PROVEN_PAST = [
    RunConditions(
        10.0,
        0.15044446396983546,
        0.11009571175531162,
        1.4965731701675278,
        None,
        28.861096363052518,
        "crawl",
        9.126810749499974,
        -1,
        28.6,
        485100761,
        jump_rate=0.027176221292551886,
    ),
    RunConditions(
        10.0,
        4.279514761326261,
        0.2830572355045878,
        0.35658154638634276,
        5.544941293026007,
        None,
        "stop_on_crossing",
        29.486457782462345,
        1,
        300.0,
        485201149,
        speed_reported=False,
        jump_rate=0.03172908849272808,
    ),
]


@pytest.mark.parametrize("cond", TAIL_NOT_PROVEN_PAST)
def test_the_tail_is_past_only_on_two_eot_fixes_moving_away(cond: RunConditions) -> None:
    crossing = next(c for c in LAYOUT.crossings if c.code == "12+940")
    v = one_run(LAYOUT, crossing, cond)
    assert v.violation is None and v.late_by_s is None
    assert v.lead_s is not None and v.lead_s >= crossing.warning_time_s


def test_lost_head_unit_falls_back_to_eot_plus_length() -> None:
    cond = RunConditions(
        period_s=2.6,
        noise_m=0.5,
        loss=0.1,
        head_fails_at_s=20.0,
        scenario="through",
        speed_mps=15.0,
        direction=-1,
        length_m=40.0,
        seed=12,
    )
    v = one_run(LAYOUT, LAYOUT.crossings[0], cond)
    assert v.violation is None and v.lead_s is not None and v.lead_s >= 70
    assert v.alarms >= 1


def test_stopped_train_near_the_crossing_keeps_it_warned() -> None:
    cond = RunConditions(period_s=5.0, noise_m=3.0, scenario="stop_before", speed_mps=12.0, length_m=120.0, seed=3)
    v = one_run(LAYOUT, LAYOUT.crossings[0], cond)
    assert v.violation is None and v.excess_s is not None


def test_a_train_braking_to_a_far_stop_stands_there_and_leaves_no_faster_than_the_line_speed() -> None:
    # Seed 610061, run 1632 of the 3,000-run sweep: braking from 28.8 m/s in 0.2 s steps left 0.16 m/s a few
    # centimetres short of the stop; the step that crept past it was not taken as the stop, and the train
    # ran on at its cruising speed, above the 25 m/s a train leaving a stop may reach: a late warning
    # (4.6 s short of 70 s) that was the harness breaking the unit's bounds.
    cond = RunConditions(
        period_s=10.0,
        noise_m=4.312141517530633,
        loss=0.23945686568123542,
        latency_s=0.9449579852335691,
        scenario="stop_far",
        speed_mps=28.83860370881344,
        direction=-1,
        length_m=40.0,
        seed=61006101632,
        run_past_m=600.0,
        speed_reported=False,
    )
    v = one_run(LAYOUT, LAYOUT.crossings[1632 % len(LAYOUT.crossings)], cond)
    assert v.violation is None and v.late_by_s is None
    assert v.physics_s is not None and v.physics_s >= 0.0  # the oracle, on the true motion, is in time


@pytest.mark.parametrize("period_s", [0.4, 10.0])
def test_a_121_kmh_train_without_speed_is_warned_in_time(period_s: float) -> None:
    # The case: 121 km/h (33.6 m/s), no speed column, a 70 s crossing; the unit is told 25 m/s.
    cond = RunConditions(period_s=period_s, noise_m=3.0, speed_mps=121 / 3.6, speed_reported=False, seed=8)
    v = one_run(LAYOUT, LAYOUT.crossings[0], cond)
    assert v.violation is None and v.late_by_s is None
    assert v.lead_s is not None and v.lead_s >= 70


def test_summary_of_a_clean_sweep() -> None:
    res = many_runs(LAYOUT, 20, seed=5)
    s = summary(res)
    assert s["runs"] == 20 and s["violations"] == 0 and s["late_warnings"] == 0
    assert np.isfinite(s["median_lead_s"])  # type: ignore[arg-type]
