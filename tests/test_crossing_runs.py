"""The crossing controller against ground truth over randomized runs (issues 4 and "Real data first" §3).

Fixes at 2.5 Hz, at 0.1 Hz or every 1-10 s, GNSS noise σ up to 5 m, packet
loss up to 30 %, radio latency, head or EOT unit failures, trains up to
35 m/s (faster than the line speed the unit is told), half the exports
without a speed column, half the runs with position jumps; trains that run
through, crawl, stop before the crossing, or stop with their tail still on
the road.

CI runs 400 runs (about 6 s).  The full sweep the issue asks for:
``TRACKSIDE_CROSSING_RUNS=3000 python -m pytest tests/test_crossing_runs.py``.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from console.layout import load_layout
from console.sim.crossing_runs import RunConditions, many_runs, one_run, summary

LAYOUT = load_layout("example")
RUNS = int(os.environ.get("TRACKSIDE_CROSSING_RUNS", "400"))


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
    assert all(r.jumps_set_aside == 0 for c, r in results if c.jump_rate == 0)


def test_only_a_failed_eot_holds_the_warning_on(results: list) -> None:
    held = [c for c, r in results if r.held]
    assert held and all(c.eot_fails_at_s is not None for c in held)
    # ... and every run whose EOT failed before the tail cleared raises an alarm.
    assert all(r.alarms > 0 for c, r in results if r.held)


def test_fixed_time_baseline_would_open_too_early_where_trains_stop_on_the_road(results: list) -> None:
    early = [c.scenario for c, r in results if r.baseline_early_s]
    assert early and "stop_on_crossing" in early


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
