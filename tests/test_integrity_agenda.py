"""The integrity monitor evaluates only the trains a fix or a tick can change (the review of units45).

Live, every unknown device is a train: each fix used to judge every train the monitor had ever
followed.  The monitor now keeps an agenda: a train is judged at its own evidence, at the instants
its units turn stale, and at every fix and tick while a counters' check of it is open.  Its events
must be exactly those of judging every train every time: a brute-force reference (the monitor's
evaluation as it was) is kept here and both are run on the same merged multi-train runs.
"""

from __future__ import annotations

import numpy as np
import pytest

from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.integrity.monitor import IntegrityMonitor
from console.analysis.integrity.values import ConsistSpec, IntegrityEvent, IntegritySettings
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState
from console.sim.integrity_runs import START_NS, line_layout, make_train, random_conditions, simulate
from parsers.units import NS

LAYOUT = line_layout()


class EveryTrain(IntegrityMonitor):
    """The reference: every train judged at every fix and tick (the monitor before the agenda)."""

    def _evaluate(self, now: int) -> list[IntegrityEvent]:
        out: list[IntegrityEvent] = []
        for tr in self.trains.values():
            self._run_checks(tr, now)
            out += self._settle(tr, now)
        return out


def _merged(rng: np.random.Generator, seed: int) -> tuple[list[ConsistSpec], list[tuple], list[tuple[int, str]]]:
    """A few simulated runs (parted trains, whole ones, EOT losses), each its own train, started at random
    offsets and merged in reception order; now and then the operator resets a train."""
    specs: list[ConsistSpec] = []
    items: list[tuple] = []
    resets: list[tuple[int, str]] = []
    for j in range(int(rng.integers(2, 5))):
        cond = random_conditions(rng, seed * 10 + j)
        cond = cond.__class__(**{**cond.__dict__, "duration_s": min(cond.duration_s, 900.0)})
        res = simulate(LAYOUT, cond, monitor=False)  # the inputs: both monitors are driven below
        name = f"T{j}"
        train = make_train(cond.consist)
        specs.append(ConsistSpec(name, train.length_m, len(train.axles_m), length_known=bool(rng.random() < 0.7)))
        shift = int(rng.uniform(0, 300) * NS)
        # Every time in an item (the fix's, the measurement's, the axle's) is its second field.
        items += [(rx + shift, kind, name, cond.direction, (a, b + shift, *c)) for rx, kind, (a, b, *c) in res.items]
        if rng.random() < 0.3 and res.items:
            resets.append((res.items[len(res.items) // 2][0] + shift, name))
    items.sort(key=lambda x: (x[0], x[1]))
    return specs, items, resets


def _drive(mon: IntegrityMonitor, specs: list[ConsistSpec], items: list[tuple], resets: list[tuple[int, str]]) -> list:
    """The console's inputs one by one, a tick every second between them; what the monitor says."""
    for spec in specs[: len(specs) // 2]:  # some known before their first fix, the others learnt
        mon.add_train(spec)
    engine = SectionEngine(LAYOUT, initial=SectionState.CLEAR, start_ns=START_NS)
    said: list = []
    told = sorted(resets)
    t = items[0][0]
    for rx, kind, name, direction, item in items:
        while t + NS < rx:
            t += NS
            said += mon.tick(t)
        while told and told[0][0] <= rx:
            said += mon.reset(told[0][1], told[0][0])
            told.pop(0)
        if name not in mon.trains:
            mon.add_train(next(s for s in specs if s.train == name))
        if kind == 0:
            role, t_fix, ch, v = item
            said += mon.fix(rx, t_fix, name, role, ch, v)
        elif kind == 2:
            role, t_meas, bar, alarm = item
            said += mon.brake_pipe(rx, t_meas, name, role, bar, emergency=alarm > 0)
        else:
            e = DetectionEvent(item[1], EventKind.AXLE, item[0], direction, source="harness")
            said += mon.detection(e)
            for tr in engine.step(e):
                said += mon.transition(tr)
        said.append((mon.now_ns, tuple(mon.state(s.train) for s in specs)))
    for k in range(1, 200):
        said += mon.tick(t + k * NS)
    return said


@pytest.mark.parametrize("block", range(3))
def test_the_agenda_says_what_judging_every_train_says(block: int) -> None:
    rng = np.random.default_rng(4_500 + block)
    kinds: set[str] = set()
    for k in range(4):
        specs, items, resets = _merged(rng, block * 100 + k)
        settings = IntegritySettings(report_period_s=float(rng.choice([1.0, 5.0, 10.0])))
        got = _drive(IntegrityMonitor(settings, LAYOUT), specs, items, resets)
        want = _drive(EveryTrain(settings, LAYOUT), specs, items, resets)
        assert got == want, (block, k)
        kinds |= {e.state for e in want if isinstance(e, IntegrityEvent)}
    assert {"whole", "doubtful"} <= kinds


def test_a_fix_judges_the_same_trains_however_many_idle_units_were_heard(monkeypatch: pytest.MonkeyPatch) -> None:
    def judged(idle: int) -> int:
        mon = IntegrityMonitor(IntegritySettings(), LAYOUT)
        t0 = START_NS
        for i in range(idle):
            mon.add_train(ConsistSpec(f"dev{i}", 100.0))
            mon.fix(t0 + i, t0 + i, f"dev{i}", "head", 1_000.0 + i, 10.0)
        mon.add_train(ConsistSpec("T", 100.0))
        calls = []
        real = IntegrityMonitor._settle
        monkeypatch.setattr(IntegrityMonitor, "_settle", lambda self, tr, now: calls.append(now) or real(self, tr, now))
        for k in range(20):
            t = t0 + NS + k * NS // 10
            mon.fix(t, t, "T", "head", 5_000.0 + k, 10.0)
            mon.tick(t + 1)
        monkeypatch.setattr(IntegrityMonitor, "_settle", real)
        return len(calls)

    assert judged(10) == judged(400) <= 20  # judging every train made it 400 · 40 against 10 · 40
