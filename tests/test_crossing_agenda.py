"""A crossing unit evaluates only the trains a fix or a tick can change (the review of units45).

Live, every unknown device is a train: a fix used to re-evaluate every train the unit had ever
seen, so a run's cost grew with the square of the devices.  The unit now keeps an agenda: each
train is evaluated at its own fixes and at the instants time alone may change it (a unit going
stale, its warning coming due).  Its events must be exactly those of evaluating every train at
every fix and tick: a brute-force reference (the controller as it was) is kept here and both are
run on the same randomized multi-train runs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from console.analysis.crossing.bounds import source_bound
from console.analysis.crossing.clock import wake_until
from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.direction import update_direction
from console.analysis.crossing.release import check_release
from console.analysis.crossing.tail import check_off, note_tail, tail_past
from console.analysis.crossing.track import feed_device_filter, feed_train_filter
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, CrossingEvent, Fix, TrainSpec
from console.layout import LevelCrossing, load_layout
from console.sim.crossing_runs import random_conditions, simulate
from parsers.units import NS

LAYOUT = load_layout("example")


class EveryTrain(CrossingController):
    """The reference: every train evaluated at every fix and tick (the controller before the agenda)."""

    def step(self, fix: Fix) -> list[CrossingEvent]:
        tr = self.tracks.get(fix.train)
        if tr is None or not fix.valid or np.isnan(fix.chainage_m) or fix.role not in (HEAD, EOT):
            return self.tick(fix.t_ns)
        prev = tr.head if fix.role == HEAD else tr.eot
        if prev is not None and fix.t_fix_ns <= prev.t_fix_ns:
            return self.tick(fix.t_ns)
        ev = tr.head_ev if fix.role == HEAD else tr.eot_ev
        jumped_before = ev.rejected_since_last
        prev_kept = tr.kf_ok[fix.role]
        rep = ev.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps)
        aside = self.set_aside.setdefault((fix.train, fix.role), [])
        if rep is None:
            aside.append(fix.t_fix_ns)
            tr.doubt_ns[fix.role] = fix.t_fix_ns
            return self.tick(fix.t_ns)
        if rep.restarted and aside:
            aside.pop()
        tr.recent[fix.role].append(rep)
        if fix.role == HEAD:
            tr.head = rep
        else:
            tr.eot = rep
        feed_device_filter(tr, fix, rep, ev)
        update_direction(tr, fix)
        feed_train_filter(tr, self.s, fix, rep)
        tr.bounds.clear()
        kept = prev_kept and tr.kf_ok[fix.role]
        prev_eot = prev if fix.role == EOT and not jumped_before and kept else None
        past = note_tail(tr, self.crossing, self.s, fix, prev_eot, rep)
        out = self._off(fix.t_ns, tr, check_off(tr, self.crossing, self.s, past, fix))
        out += self._off(fix.t_ns, tr, check_release(tr, self.s, self.motion, self.horizon_s, fix))
        out += self._check_on(tr, fix.t_ns)
        out += self._alarms(tr, fix.t_ns)
        for other in self.tracks.values():
            if other is not tr:
                out += self._check_on(other, fix.t_ns) + self._alarms(other, fix.t_ns)
        return out

    def tick(self, t_ns: int) -> list[CrossingEvent]:
        out: list[CrossingEvent] = []
        for tr in self.tracks.values():
            out += self._check_on(tr, t_ns) + self._alarms(tr, t_ns)
        return out

    def next_onset_ns(self, now_ns: int) -> int | None:
        horizon_ns = int(self.horizon_s * NS)
        stale_ns = int(self.s.stale_after_s * NS)
        wake: list[int] = []
        for tr in self.tracks.values():
            for r in (tr.head, tr.eot):
                if r is not None:
                    wake.append(r.t_fix_ns + stale_ns)
            if not tr.warned and (a := self._approach(tr, now_ns)) is not None:
                wake.append(a[3].t_arrival_ns - horizon_ns)
        later = [t for t in wake if t > now_ns]
        return min(later) if later else None

    def next_change_ns(self) -> int | None:
        last = [r.t_fix_ns for tr in self.tracks.values() for r in (tr.head, tr.eot) if r is not None]
        if not last:
            return None
        t = max(last) + int(self.s.stale_after_s * NS)
        horizon_ns = int(self.horizon_s * NS)
        for tr in self.tracks.values():
            if not tr.warned and not tail_past(tr, self.crossing, self.s):
                due = [
                    b.t_arrival_ns - horizon_ns
                    for role in (HEAD, EOT, "train")
                    if (b := source_bound(tr, self.s, self.motion, role))
                ]
                t = max(t, max(due, default=t))
        return t


def _drive(ctl: CrossingController, fixes: list[Fix], partings: list[tuple[int, str]]) -> list[tuple]:
    """A live unit's clock over the fixes (in the order given, out of time order at times): its ticks
    every second, the wake-ups between them, the partings; what it says and when it would wake next."""
    said: list[tuple] = []
    step = NS
    t = fixes[0].t_ns
    told = sorted(partings)
    for f in fixes:
        if f.t_ns > t:
            settled = ctl.next_change_ns()
            while t + step < f.t_ns and (settled is None or t + step <= settled + 2 * step):
                _, evs = wake_until(ctl, t, t + step)
                said += evs
                t += step
                said += ctl.tick(t)
            _, evs = wake_until(ctl, t, f.t_ns)
            said += evs
        while told and told[0][0] <= f.t_ns:
            said += ctl.train_parted(told[0][1], told[0][0], "counters")
            told.pop(0)
        said += ctl.step(f)
        said.append(("next", ctl.next_onset_ns(f.t_ns), ctl.next_change_ns(), ctl.warning_on, ctl.alarm))
        t = max(t, f.t_ns)
    end = t + int((ctl.s.stale_after_s + 1.0) * NS)
    while t < end:
        _, evs = wake_until(ctl, t, t + step)
        said += evs
        t += step
        said += ctl.tick(t)
    return said


def _many_trains(
    crossing: LevelCrossing, rng: np.random.Generator, seed: int, settings: ControllerSettings
) -> tuple[list[TrainSpec], list[Fix], list[tuple[int, str]]]:
    """A few simulated trains, started at random offsets and merged in reception order, with now and
    then a fix received out of time order and a train told parted."""
    trains: list[TrainSpec] = []
    fixes: list[Fix] = []
    partings: list[tuple[int, str]] = []
    for j in range(int(rng.integers(2, 6))):
        cond = random_conditions(rng, seed=seed * 10 + j)
        run, _truth, train = simulate(LAYOUT, crossing, cond, settings)
        if not run:
            continue
        name = f"T{j}"
        shift = int(rng.uniform(0, 240) * NS)
        trains.append(TrainSpec(name, train.length_m))
        fixes += [dataclasses.replace(f, train=name, t_ns=f.t_ns + shift, t_fix_ns=f.t_fix_ns + shift) for f in run]
        if rng.random() < 0.3:
            partings.append((run[len(run) // 2].t_ns + shift, name))
    fixes.sort(key=lambda f: f.t_ns)
    for _ in range(int(rng.integers(0, 4))):  # a packet received late: before the previous one
        if len(fixes) > 3:
            i = int(rng.integers(1, len(fixes) - 1))
            fixes[i], fixes[i + 1] = fixes[i + 1], fixes[i]
    return trains, fixes, partings


@pytest.mark.parametrize("block", range(3))
def test_the_agenda_says_what_evaluating_every_train_says(block: int) -> None:
    rng = np.random.default_rng(45_000 + block)
    compared = 0
    for k in range(12):
        crossing = LAYOUT.crossings[k % len(LAYOUT.crossings)]
        settings = ControllerSettings(report_period_s=float(rng.uniform(1, 10)), line_speed_mps=25.0)
        trains, fixes, partings = _many_trains(crossing, rng, block * 100 + k, settings)
        if not fixes:
            continue
        got = _drive(CrossingController(crossing, trains, settings), fixes, partings)
        want = _drive(EveryTrain(crossing, trains, settings), fixes, partings)
        assert got == want, (block, k)
        compared += 1
    assert compared >= 10


def _idle_then_busy(idle: int, monkeypatch: pytest.MonkeyPatch) -> int:
    """Evaluations of a train (``_check_on``) over one train's 20 fixes, after ``idle`` devices each sent
    one fix, standing far from the crossing."""
    crossing = LAYOUT.crossings[0]
    ctl = CrossingController(crossing, [])
    t0 = 1_800_000_000 * NS
    for i in range(idle):
        ctl.add_train(TrainSpec(f"dev{i}", 100.0))
        ch = crossing.chainage_m - 1_500.0 - i % 300
        ctl.step(Fix(t0 + i * 1_000, t0 + i * 1_000, f"dev{i}", HEAD, ch, 0.0))
    ctl.add_train(TrainSpec("T", 100.0))
    calls = []
    real = CrossingController._check_on
    monkeypatch.setattr(CrossingController, "_check_on", lambda self, tr, t: calls.append(t) or real(self, tr, t))
    t1 = t0 + NS
    for k in range(20):
        t = t1 + k * NS // 10
        ctl.step(Fix(t, t, "T", HEAD, crossing.chainage_m + 2_000.0, 0.0))
        ctl.tick(t + 1)
    return len(calls)


def test_a_fix_costs_the_same_however_many_idle_units_were_heard(monkeypatch: pytest.MonkeyPatch) -> None:
    few = _idle_then_busy(10, monkeypatch)
    many = _idle_then_busy(400, monkeypatch)
    assert few == many  # evaluating every train per fix made it 400 · 40 against 10 · 40
    assert many <= 2 * 20


def test_the_agenda_does_not_grow_with_the_fixes() -> None:
    # Each fix leaves one entry for its train's next due instant (a unit going stale at most
    # stale_after_s on); older entries are dropped as they come due.
    crossing = LAYOUT.crossings[0]
    ctl = CrossingController(crossing, [TrainSpec("T", 100.0)])
    t0 = 1_800_000_000 * NS
    for k in range(600):
        t = t0 + k * NS
        ctl.step(Fix(t, t, "T", HEAD, crossing.chainage_m - 3_000.0, 0.0))
    assert sum(ctl._entry_ok(e) for e in ctl._due) == 1
    assert len(ctl._due) <= ctl.s.stale_after_s + 5
