"""The simulator's train_parting fault and what the console makes of it: the rear part brakes
to a stop with the EOT unit, the truth records it, the integrity monitor sees it, the section
behind stays occupied, and the crossing units hold their warnings for the rear part."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, Fix, TrainSpec
from console.analysis.integrity.values import PARTED, WHOLE, IntegrityEvent
from console.layout import load_layout
from console.live.simulated import SimulatedConsole
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from parsers.units import NS

TRACKSIDE = Path(sys.executable).with_name("trackside")
LAYOUT = load_layout("example")


def run_sim(
    faults: tuple[Fault, ...], until_s: float = 1500.0, seed: int = 1
) -> tuple[StationSim, SimulatedConsole, list[IntegrityEvent]]:
    """A run watched by the station's console; the integrity changes it told."""
    sim = StationSim(LAYOUT, SimConfig(seed=seed, faults=faults))
    events: list[IntegrityEvent] = []

    def keep(ev: dict) -> None:
        if ev["type"] == "integrity":
            events.append(
                IntegrityEvent(
                    ev["time_ns"], ev["train"], ev["state"], ev["previous"], (), tuple(ev["evidence"]), ev["rear_m"]
                )
            )

    console = SimulatedConsole(sim, keep)
    while sim.t_s < until_s:
        sim.step(0.5)
    sim.finish()
    return sim, console, events


def test_the_rear_half_parts_brakes_to_a_stop_and_the_console_sees_it() -> None:
    sim, console, events = run_sim((Fault("train_parting", "T2", 840.0),))
    (p,) = sim.truth_partings
    consist = next(t for t in sim.trains if t.id == "T2")
    assert p.train == "T2" and p.rear_axles == 4 and p.rear_first_axle == 4  # dmu2: 8 axles, the rear car
    assert p.t_rear_stopped_ns is not None and p.t_rear_stopped_ns > p.t_parting_ns
    assert consist.rear is not None and consist.rear.v_mps == 0.0
    # Braked on the force model from its speed: it stopped within what full service braking allows.
    assert abs(p.rear_stop_front_m - p.head_m) <= p.speed_mps**2 / (2 * 1.0) + 40.0  # type: ignore[operator]
    parted = [e for e in events if e.train == "T2" and e.state == PARTED]
    assert len(parted) == 1 and parted[0].t_ns > p.t_parting_ns
    delay_s = (parted[0].t_ns - p.t_parting_ns) / NS
    # The simulated units report the brake pipe (LoRa version 2): the EOT unit's emergency status at
    # once, the head's next report charged: within 2 report periods and the latency (the target).
    assert delay_s <= 2 * sim.period_s + sim.latency_s
    assert "rear brake pipe vented (emergency status" in parted[0].evidence[0]
    assert "front stayed charged" in parted[0].evidence[0] and parted[0].rear_m is not None
    # The EOT's last fix when the parting was seen: the rear part may still be braking to its stop.
    assert abs(parted[0].rear_m - p.rear_stop_tail_m) < 100  # type: ignore[operator]
    # The rear part stands in a section: the console keeps it occupied with the rear's axles.
    shown = console.engine.section_states()
    sid = next(s for s in shown if sim.true_count(s) == 4)
    assert shown[sid] == ("occupied", 4)
    assert not [e for e in events if e.train == "T1" and e.state != WHOLE]


def test_an_eot_loss_is_doubt_never_a_parting() -> None:
    sim, _console, events = run_sim((Fault("eot_loss", "T2", 700.0),))
    t2 = [e.state for e in events if e.train == "T2"]
    assert t2[:2] == [WHOLE, "doubtful"] and PARTED not in t2
    assert sim.truth_partings == []


def test_a_parted_train_holds_a_crossing_warning_for_its_rear_part() -> None:
    sim, console, _ = run_sim((Fault("train_parting", "T2", 600.0),), until_s=1200.0)
    (p,) = sim.truth_partings
    assert console.engine.crossings is not None
    ctl = console.engine.crossings.controllers[
        "12+940"
    ]  # T2 runs down: its head passes 12+940, its rear stops short of it
    assert p.rear_stop_tail_m is not None and p.rear_stop_tail_m > 12_940
    assert ctl.tracks["T2"].warned and ctl.warning_on
    alarms = [e.reason for e in ctl.events if e.train == "T2" and e.kind == "alarm"]
    assert any(a.startswith("train parted") and "held until the rear part is accounted for" in a for a in alarms)
    assert not [e for e in ctl.events if e.train == "T2" and e.kind == "off"]


def test_the_warning_ends_once_the_rear_part_is_past() -> None:
    """The controller's own rule: two EOT fixes past the crossing are the rear part accounted for."""
    crossing = LAYOUT.crossings[0]
    c = crossing.chainage_m
    ctl = CrossingController(crossing, [TrainSpec("T", 40.0)], ControllerSettings(report_period_s=2.0))
    t0 = 1_772_438_400 * NS

    def fix(t_s: float, role: str, x: float, v: float) -> list:
        return ctl.step(Fix(t0 + int((t_s + 0.3) * NS), t0 + int(t_s * NS), "T", role, x, v, 1 if v > 1 else 0))

    for t in range(0, 100, 2):
        fix(t, HEAD, c - 1000 + 15 * t, 15.0)
        fix(t + 1, EOT, c - 1040 + 15 * (t + 1) if t < 60 else c - 150.0, 15.0 if t < 60 else 0.0)
    assert ctl.tracks["T"].warned
    out = ctl.train_parted("T", t0 + 62 * NS, "EOT behind and slower")
    assert [e.kind for e in out] == ["alarm"] and "rear part" in out[0].reason
    assert ctl.train_parted("T", t0 + 63 * NS, "again") == []  # said once
    for t in range(100, 200, 2):  # the rear part stands 150 m short: nothing ends the warning
        fix(t, EOT, c - 150.0, 0.0)
        ctl.tick(t0 + t * NS)
    assert ctl.tracks["T"].warned
    for t in range(200, 240, 2):  # a rescue engine takes the rear part over the crossing
        fix(t, EOT, c - 150.0 + 5.0 * (t - 200), 5.0)
    assert not ctl.tracks["T"].warned and "past the crossing" in ctl.tracks["T"].reason_off


def test_simulate_writes_the_parting_into_the_truth(tmp_path: Path) -> None:
    out = tmp_path / "run"
    r = subprocess.run(
        [str(TRACKSIDE), "simulate", "-o", str(out), "--duration", "20m", "--fault", "train_parting:T2:14m", "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    (p,) = truth["partings"]
    assert p["train"] == "T2" and p["time"].startswith("2026-03-02T08:14:") and p["rear_axles"] == 4
    assert p["rear_stopped"] is not None and p["rear_stop_tail_m"] is not None
    assert {"kind": "train_parting", "target": "T2"}.items() <= truth["faults"][0].items()
    bad = subprocess.run(
        [str(TRACKSIDE), "simulate", "-o", str(tmp_path / "x"), "--fault", "train_parting:T2"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert bad.returncode == 2 and "train_parting" in bad.stderr and "Traceback" not in bad.stderr
