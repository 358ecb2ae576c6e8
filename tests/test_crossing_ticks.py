"""Between fixes the crossing unit's clock ticks; once every device is stale, ticks are skipped, exactly.

The controller's ticks stop one tick after every device's last fix has gone
stale (nothing a tick does can change after that until the next fix), so a
damaged date years after the other fixes no longer means a tick per second
of those years (the long fuzz run found ``crossing`` running for minutes on
one such input).  Randomized simulated runs, with fixes cut out to leave
long gaps and the last ones moved hours or years later, give the events a
walk over every tick gives.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import pytest

from console.analysis.crossing.clock import run_controller, wake_until
from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.values import ControllerSettings, Fix, TrainSpec
from console.layout import LevelCrossing, load_layout
from console.sim.crossing_runs import random_conditions, simulate
from parsers.units import NS

LAYOUT = load_layout("example")
YEAR_NS = 365 * 86_400 * NS


def _walk_every_tick(
    crossing: LevelCrossing, trains: Sequence[TrainSpec], fixes: Sequence[Fix], settings: ControllerSettings
) -> CrossingController:
    """The controller's clock walked without skipping: a tick every second between fixes, then the stale
    time's ticks; and, before each, the instants something falls due (a warning comes on at its instant)."""
    ctl = CrossingController(crossing, trains, settings)
    ordered = sorted(fixes, key=lambda f: f.t_ns)
    t, step = ordered[0].t_ns, NS
    for f in ordered:
        while t + step < f.t_ns:
            wake_until(ctl, t, t + step)
            t += step
            ctl.tick(t)
        wake_until(ctl, t, f.t_ns)
        ctl.step(f)
        t = f.t_ns
    end = t + int((ctl.s.stale_after_s + 1.0) * NS)
    while t < end:
        wake_until(ctl, t, t + step)
        t += step
        ctl.tick(t)
    return ctl


def _damaged(fixes: list[Fix], rng: np.random.Generator) -> list[Fix]:
    """Fixes with a stretch cut out (a gap of tens of seconds to minutes) and, in some runs, the last
    few moved later by minutes to hours (a clock jump, a damaged date)."""
    out = list(fixes)
    if len(out) > 10 and rng.random() < 0.7:
        a = int(rng.integers(1, len(out) - 5))
        b = min(len(out) - 1, a + int(rng.integers(3, 60)))
        del out[a:b]
    if len(out) > 5 and rng.random() < 0.5:
        shift = int(rng.choice([120, 3_600, 86_400])) * NS
        k = len(out) - int(rng.integers(1, 4))
        out[k:] = [dataclasses.replace(f, t_ns=f.t_ns + shift, t_fix_ns=f.t_fix_ns + shift) for f in out[k:]]
    return out


@pytest.mark.parametrize("block", range(4))
def test_skipped_ticks_give_the_events_of_every_tick(block: int) -> None:
    rng = np.random.default_rng(7_000 + block)
    compared = 0
    for k in range(40):
        crossing = LAYOUT.crossings[k % len(LAYOUT.crossings)]
        cond = random_conditions(rng, seed=block * 1_000 + k)
        settings = ControllerSettings(
            report_period_s=cond.period_s, latency_s=2 * cond.latency_s + 0.5, line_speed_mps=25.0, accel_mps2=0.5
        )
        fixes, _truth, train = simulate(LAYOUT, crossing, cond, settings)
        if not fixes:
            continue
        fixes = _damaged(list(fixes), rng)
        got = run_controller(crossing, [train], fixes, settings)
        want = _walk_every_tick(crossing, [train], fixes, settings)
        assert got.events == want.events, (block, k, cond)
        assert got.alarm == want.alarm
        compared += 1
    assert compared >= 30


def test_a_fix_dated_years_later_costs_the_stale_time_not_the_years(monkeypatch: pytest.MonkeyPatch) -> None:
    crossing = LAYOUT.crossings[0]
    rng = np.random.default_rng(3)
    cond = random_conditions(rng, seed=3)
    settings = ControllerSettings(report_period_s=cond.period_s, line_speed_mps=25.0)
    fixes, _truth, train = simulate(LAYOUT, crossing, cond, settings)
    fixes = list(fixes)
    last = fixes[-1]
    fixes.append(dataclasses.replace(last, t_ns=last.t_ns + 30 * YEAR_NS, t_fix_ns=last.t_fix_ns + 30 * YEAR_NS))
    ticks = []
    real_tick = CrossingController.tick
    monkeypatch.setattr(CrossingController, "tick", lambda self, t: ticks.append(t) or real_tick(self, t))
    ctl = run_controller(crossing, [train], fixes, settings)
    span_s = (fixes[-1].t_ns - fixes[0].t_ns) / NS
    assert span_s > 29 * 365 * 86_400
    assert len(ticks) < 200_000  # a tick per second of the span would be about 10⁹
    assert ctl.events  # the run itself was analysed


def test_a_warning_comes_on_at_the_instant_it_is_due_not_a_tick_before() -> None:
    # The unit's clock wakes when a warning falls due (next_onset_ns), so a warning that comes on by
    # extrapolation between fixes does so with its earliest arrival exactly the horizon away: on a
    # steady tick it would come anywhere up to a tick early (or, without the tick in the horizon, late).
    rng = np.random.default_rng(11)
    checked = 0
    for k in range(60):
        crossing = LAYOUT.crossings[k % len(LAYOUT.crossings)]
        cond = random_conditions(rng, seed=90_000 + k)
        settings = ControllerSettings(
            report_period_s=cond.period_s, latency_s=2 * cond.latency_s + 0.5, line_speed_mps=25.0, accel_mps2=0.5
        )
        fixes, _truth, train = simulate(LAYOUT, crossing, cond, settings)
        if not fixes:
            continue
        ctl = run_controller(crossing, [train], fixes, settings)
        onset = ctl.tracks[train.train].onset
        received = {f.t_ns for f in fixes}
        ons = [e for e in ctl.events if e.kind == "on"]
        if onset is None or not ons or ons[-1].t_ns in received or not ons[-1].reason.startswith("ETA"):
            continue
        assert onset.t_ns == ons[-1].t_ns
        assert abs(onset.eta_s - ctl.horizon_s) < 1e-6, (k, cond, onset)
        checked += 1
    assert checked >= 10
