"""Train integrity against ground truth over randomized runs (issue "Train integrity").

One train per run on a 250 km line with counting heads every 1.2–3 km:
fixes at 0.1, 0.2, 0.5, 1 or 2.5 Hz, GNSS noise σ up to 5 m, Doppler speed
noise, packet loss up to 30 %, radio latency, units' clock offsets, position
jumps in half the runs; half the runs part (the rear part brakes to a stop on
the force model), the others run whole for 20–60 minutes, some losing their
EOT unit for good.  The monitor is the console's own, fed every fix, axle and
section change in the order the console receives them.  In 70 % of the runs
the units also report the brake pipe (the EOT its emergency status at once).

CI runs 60 runs (about 20 s).  The full sweep the issue asks for, on a seed
the rules were not tuned on:
``TRACKSIDE_INTEGRITY_RUNS=6000 python -m pytest tests/test_integrity_runs.py``.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from console.sim.integrity_runs import RATES_HZ, Verdict, many_runs, summary

RUNS = int(os.environ.get("TRACKSIDE_INTEGRITY_RUNS", "60"))
SEED = 2026  # the rules were worked out on seeds 1, 3, 5 and 11


@pytest.fixture(scope="module")
def verdicts() -> list[Verdict]:
    return many_runs(RUNS, SEED)


def test_the_sweep_covers_every_fix_rate_partings_whole_trains_and_eot_loss(verdicts: list[Verdict]) -> None:
    kinds = {v.kind for v in verdicts}
    assert kinds == {"parted", "whole", "eot_loss"}
    rates = {round(1 / v.period_s, 3) for v in verdicts if v.kind == "parted"}
    assert rates == {round(hz, 3) for hz in RATES_HZ}


def test_no_parting_is_missed(verdicts: list[Verdict]) -> None:
    parted = [v for v in verdicts if v.kind == "parted"]
    assert parted and not any(v.missed for v in parted)
    assert all(v.detected_s is not None and v.detected_s >= 0 for v in parted)


def test_no_whole_train_is_seen_parted(verdicts: list[Verdict]) -> None:
    # The target is at most 1 per 1,000 train-hours: none at all in these hours.
    s = summary(verdicts)
    assert s["false_parted"] == 0
    assert s["whole_train_hours"] > RUNS / 4  # type: ignore[operator]


def test_eot_loss_is_reported_as_doubt_never_as_parted(verdicts: list[Verdict]) -> None:
    lost = [v for v in verdicts if v.kind == "eot_loss"]
    assert lost and all(v.eot_loss_doubt and not v.false_parted for v in lost)


def test_detection_time_by_fix_rate(verdicts: list[Verdict]) -> None:
    """The median detection is within the issue's 2 report periods + latency plus 4 s: the
    time a rear part braking at about 1 m/s² takes to fall a speed allowance behind the head
    (a floor no fix rate removes; the note has the figures)."""
    for hz in RATES_HZ:
        sel = [v for v in verdicts if v.kind == "parted" and abs(v.period_s - 1 / hz) < 1e-9]
        if not sel:
            continue
        late = [v.detected_s - 2 * v.period_s for v in sel if v.detected_s is not None]
        assert float(np.median(late)) <= 2.0 + 4.0, hz  # latency ≤ 2 s in these runs


def test_the_sweep_has_units_with_and_without_the_brake_pipe(verdicts: list[Verdict]) -> None:
    parted = [v for v in verdicts if v.kind == "parted"]
    assert any(v.brake_pipe for v in parted) and any(not v.brake_pipe for v in parted)
    # Whole trains with the brake pipe (their emergency stops vent it at both ends) are among the
    # hours in which no train was seen parted (test_no_whole_train_is_seen_parted).
    assert any(v.brake_pipe and v.kind == "whole" for v in verdicts)


def test_with_the_brake_pipe_the_median_parting_is_seen_within_the_target(verdicts: list[Verdict]) -> None:
    """2 report periods + latency: the EOT unit's emergency status comes at once, the head's next
    report says the front stayed charged.  (The share within target, by fix rate, is in the note.)"""
    bp = [v for v in verdicts if v.kind == "parted" and v.brake_pipe and v.detected_s is not None]
    late = [v.detected_s - 2 * v.period_s for v in bp if v.detected_s is not None]
    assert float(np.median(late)) <= 0.2  # latency ≥ 0.2 s in these runs
    gnss = [v.detected_s for v in verdicts if v.kind == "parted" and not v.brake_pipe and v.detected_s is not None]
    assert float(np.median([v.detected_s for v in bp if v.detected_s is not None])) < float(np.median(gnss))
