"""Speed, jumps and direction from a device's own fixes ("Real data first" §3).

A fix without speed is doubt, not standstill; successive fixes bound the
speed from above; position jumps are set aside and counted; one jump can
neither reverse the train nor open the road.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.evidence import ASSUMED, ESTIMATED, REPORTED, DeviceEvidence, EvidenceLimits
from console.analysis.crossing.timeline import timeline
from console.analysis.crossing.values import ControllerSettings, Fix, TrainSpec
from console.layout import load_layout

NS = 10**9
S = ControllerSettings()
LIMITS = EvidenceLimits(S.noise_m, S.accel_mps2, S.jump_accel_mps2, S.max_speed_mps, S.speed_window_s)
CROSSING = load_layout("example").crossings[0]  # 11+850, 70 s
C = CROSSING.chainage_m


def _feed(ev: DeviceEvidence, times_s: np.ndarray, chainage_m: np.ndarray, speed_mps: float = math.nan) -> list:
    return [ev.offer(int(t * NS), float(x), speed_mps) for t, x in zip(times_s, chainage_m, strict=True)]


def test_a_single_fix_without_speed_is_the_worst_case_not_a_standstill() -> None:
    (rep,) = _feed(DeviceEvidence(LIMITS), np.array([0.0]), np.array([1000.0]))
    assert rep.speed_basis == ASSUMED and rep.speed_hi_mps == S.max_speed_mps


def test_speed_of_a_121_kmh_train_is_bounded_from_jittery_fixes_at_2_5_hz() -> None:
    rng = np.random.default_rng(1)
    v = 121 / 3.6
    t = np.arange(0, 30, 0.4)
    reps = _feed(DeviceEvidence(LIMITS), t, v * t + rng.normal(0, 5, len(t)))
    last = reps[-1]
    assert last.speed_basis == ESTIMATED
    assert v <= last.speed_hi_mps <= v + 7  # never below the truth, a few m/s above it


@settings(max_examples=60, deadline=None)
@given(
    v0=st.floats(0, 40),
    accel=st.floats(-1.2, S.accel_mps2),
    period_s=st.sampled_from([0.4, 1.0, 2.5, 10.0]),
    seed=st.integers(0, 2**31),
)
def test_the_speed_bound_never_falls_below_the_true_speed(v0: float, accel: float, period_s: float, seed: int) -> None:
    # Any train that accelerates at most as the unit assumes, fixes within the noise allowance.
    rng = np.random.default_rng(seed)
    t = np.arange(0, 60, period_s)
    v = np.clip(v0 + accel * t, 0.0, 40.0)  # below the most any train runs (max_speed_mps)
    x = np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 * np.diff(t))])
    noisy = x + rng.uniform(-S.noise_m, S.noise_m, len(t))
    for rep, v_true in zip(_feed(DeviceEvidence(LIMITS), t, noisy), v, strict=True):
        assert rep is not None and rep.speed_hi_mps >= v_true - 1e-9


def test_positions_that_stay_put_prove_a_slow_train() -> None:
    t = np.arange(0, 30, 1.0)
    reps = _feed(DeviceEvidence(LIMITS), t, np.full(len(t), 500.0) + np.sin(t) * 3)
    assert reps[-1].speed_hi_mps < 6.0
    # A reported standstill is taken (with its small error allowance).
    (rep,) = _feed(DeviceEvidence(LIMITS), np.array([0.0]), np.array([500.0]), 0.0)
    assert rep.speed_basis == REPORTED and rep.speed_hi_mps == LIMITS.speed_error_mps


def test_a_reported_zero_on_a_moving_train_is_raised_to_what_the_positions_prove() -> None:
    t = np.arange(0, 20, 1.0)
    reps = _feed(DeviceEvidence(LIMITS), t, 20.0 * t, 0.0)
    assert reps[-1].speed_hi_mps > 10.0


def test_a_position_jump_is_set_aside_counted_and_does_not_refresh_the_device() -> None:
    ev = DeviceEvidence(LIMITS)
    _feed(ev, np.arange(0, 10, 1.0), 20.0 * np.arange(0, 10, 1.0), 20.0)
    last = ev.last
    assert ev.offer(10 * NS, 180.0 + 2000.0, 20.0) is None
    assert ev.jumps == 1 and ev.last is last
    assert ev.offer(11 * NS, 220.0, 20.0) is not None  # the track goes on


def test_two_agreeing_fixes_away_from_a_wild_first_fix_restart_the_track() -> None:
    ev = DeviceEvidence(LIMITS)
    ev.offer(0, 5000.0, math.nan)  # wild first fix
    assert ev.offer(1 * NS, 0.0, math.nan) is None
    rep = ev.offer(2 * NS, 20.0, math.nan)
    assert rep is not None and rep.restarted and ev.jumps == 0 and ev.restarts == 1


def test_one_jump_does_not_reverse_the_direction() -> None:
    ev = DeviceEvidence(LIMITS)
    t = np.arange(0, 40, 8.0)
    _feed(ev, t, 3.0 * t)  # crawling up the line
    ev.offer(48 * NS, 3.0 * 40 - 240.0, math.nan)  # 240 m back: plausible after 8 s at the bound
    assert ev.direction() in (0, 1)


def _controller() -> CrossingController:
    return CrossingController(CROSSING, [TrainSpec("T", 100.0)])


def test_a_no_speed_head_fix_2_5_km_out_warns_at_once() -> None:
    # At 121 km/h 2.5 km is 74 s: the first fix without speed must count as fast.
    ctl = _controller()
    events = ctl.step(Fix(0, 0, "T", "head", C - 2500, math.nan, 1))
    assert events[0].kind == "on" and "most a train runs" in events[0].reason


def test_one_eot_fix_past_the_crossing_does_not_end_the_warning() -> None:
    ctl = _controller()
    fixes = [Fix(k * NS, k * NS, "T", "head", C - 1500 + 10.0 * k, 10.0, 1) for k in range(0, 150, 5)]
    fixes += [Fix(k * NS + 1, k * NS + 1, "T", "eot", C - 1600 + 10.0 * k, 10.0, 1) for k in range(0, 150, 5)]
    fixes.sort(key=lambda f: f.t_ns)
    for f in fixes:
        ctl.step(f)
    assert ctl.warning_on
    # The tail is 100 m before the crossing at 150 s; a fix 60 m past it is a plausible jump.
    ctl.step(Fix(155 * NS, 155 * NS, "T", "eot", C + 60, 10.0, 1))
    assert ctl.warning_on
    # Two fixes past it, moving on: now it is evidence.
    ctl.step(Fix(175 * NS, 175 * NS, "T", "eot", C + 150, 10.0, 1))
    ctl.step(Fix(180 * NS, 180 * NS, "T", "eot", C + 200, 10.0, 1))
    assert not ctl.warning_on


def test_a_warning_shorter_than_the_warning_time_is_a_late_violation_listed_first() -> None:
    # Telemetry that begins 40 s before the head arrives: the warning can only be late.
    ctl = _controller()
    fixes = []
    for k in range(0, 80, 2):
        head = C - 800 + 20.0 * k
        fixes += [
            Fix(k * NS, k * NS, "T", "head", head, 20.0, 1),
            Fix(k * NS + 1, k * NS + 1, "T", "eot", head - 100, 20.0, 1),
        ]
    for f in fixes:
        ctl.step(f)
    (row,) = timeline(ctl, fixes)
    assert row.late_by_s is not None and 25 < row.late_by_s <= 31
    assert row.violations[0].startswith("late warning")
    assert "telemetry begins only" in row.late_cause
    assert row.to_dict()["late_by_s"] == round(row.late_by_s, 3)
