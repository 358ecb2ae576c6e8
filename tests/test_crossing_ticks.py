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

from console.analysis.crossing.controller import ControllerSettings, CrossingController, Fix, TrainSpec, run_controller
from console.layout import LevelCrossing, load_layout
from console.sim.crossing_runs import random_conditions, simulate
from parsers.units import NS

LAYOUT = load_layout("example")
YEAR_NS = 365 * 86_400 * NS


def _walk_every_tick(
    crossing: LevelCrossing, trains: Sequence[TrainSpec], fixes: Sequence[Fix], settings: ControllerSettings
) -> CrossingController:
    """The controller as it ran before: a tick every second between fixes, then the stale time's ticks."""
    ctl = CrossingController(crossing, trains, settings)
    ordered = sorted(fixes, key=lambda f: f.t_ns)
    t, step = ordered[0].t_ns, NS
    for f in ordered:
        while t + step < f.t_ns:
            t += step
            ctl.tick(t)
        ctl.step(f)
        t = f.t_ns
    end = t + int((ctl.s.stale_after_s + 1.0) * NS)
    while t < end:
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
