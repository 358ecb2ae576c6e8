"""The simulator's station console: the one live engine, fed what the simulated devices report.

Each step of the simulated line (:class:`~console.sim.station.StationSim`)
hands its reports to the console attached to it.  They reach the live engine
(:class:`~console.live.engine.LiveEngine`) the way ``trackside follow`` of the
run's written files would hand them on:

* the heads' records as the lines ``diagnostic.log`` holds (the one formatter,
  :mod:`console.sim.diag_lines`), a block per step, only when there are lines;
  a head without power writes none, so its loss is what the console finds
  from the silence (the layout's ``[devices]`` power gap), and a dead channel
  is what its records show (axles seen by one system only);
* the fixes the radio delivered, each when it arrives, as recorded fixes of
  the units named as the written files name them, with the values the device
  stream (``gnss_devices.csv``) holds, and the brake-pipe pressure and
  emergency status their LoRa uplinks carry (payload version 2, what
  ``simulate --mqtt`` publishes; the written files have no place for them).

The engine's clock is the simulation's.  Fixes are judged by their own time
(recorded), and the crossing units' clock ticks as far as the radio's delay
allows (no fix still to come was measured before ``now - latency``).  The
console's settings are those ``follow --layout layout.toml`` takes from the
run's written layout (:func:`~console.sim.devices.with_devices`): so the
console shows what ``follow`` and the batch commands find in the run's files
(``tests/test_one_engine.py``, route e).  A simulated line starts empty: its
sections start clear (``sections --initial clear``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from console.analysis.crossing.values import CrossingEvent
from console.analysis.sections.state import SectionState
from console.inputs.base import GnssFix, LineBlock
from console.live.engine import LiveEngine
from console.sim.diag_lines import (
    Row,
    device_ids,
    health_register_rows,
    heartbeat_rows,
    identity_rows,
    in_order_lines,
    wheel_rows,
)
from console.sim.gnss_rows import as_written, unit_name
from console.sim.line_values import SentFix, StepResult
from console.sim.station import StationSim
from parsers.units import NS

Emit = Callable[[dict[str, Any]], None]
DIAG_SOURCE = "sim:diagnostic.log"  # the followed log the lines stand for
GNSS_SOURCE = "sim:gnss_devices.csv"
INITIAL = SectionState.CLEAR  # a simulated line starts empty


class SimulatedConsole:
    """The live engine watching a simulated line (attached to it: every step's reports reach it)."""

    def __init__(self, sim: StationSim, emit: Emit | None = None) -> None:
        self.sim = sim
        self.layout = sim.console_layout
        self._emit = emit
        self.engine = LiveEngine(self.layout, self._on_event, clock=lambda: sim.now_ns, initial=INITIAL)
        self._ids = device_ids(self.layout)
        self._latency_ns = int(sim.latency_s * NS)
        self._next_line = 1
        self._later: list[Row] = []  # rows after the step's end (a head's health round spreads over ms)
        self._pending = identity_rows(self.layout, sim.cfg.start_ns)  # each device's dump at the run's start
        sim.attach(self)

    def _on_event(self, ev: dict[str, Any]) -> None:
        if self._emit is not None:
            self._emit(ev)

    # -- fed by the simulated line ---------------------------------------------------
    def take(self, step: StepResult) -> None:
        # In the order the log's writer puts records of one time: dumps, status, wheels, health registers.
        rows = self._pending + heartbeat_rows(step.heartbeats)
        rows += wheel_rows((r.t_ns, r.head, r.channel, r.value) for r in step.records)
        rows += self._later + health_register_rows(step.health, self.layout)
        self._pending = []
        # A row after the step's end waits for the next step's rows: the log holds them all in time order.
        self._later = [r for r in rows if r[0] > step.t_ns]
        now = [r for r in rows if r[0] <= step.t_ns]
        if now:
            lines = in_order_lines(now, self._ids)
            data = ("\n".join(lines) + "\n").encode("utf-8")
            self.engine.handle(LineBlock(DIAG_SOURCE, DIAG_SOURCE, self._next_line, data, time.monotonic()))
            self._next_line += len(lines)
        # The heads are wired to the station: every record made before the step's end is in; what they
        # show is decided now, not when a later record (a heartbeat away on a quiet line) comes.
        self.engine.diag.advance(step.t_ns)
        for f in step.received:
            self.engine.handle(received_fix(f))
        # No fix still to come was measured before now less the radio's delay: the units' clock runs to there.
        self.engine.tick(recorded_until_ns=step.t_ns - self._latency_ns)

    def finish(self) -> None:
        if self._later or self._pending:
            lines = in_order_lines(self._pending + self._later, self._ids)
            data = ("\n".join(lines) + "\n").encode("utf-8")
            self.engine.handle(LineBlock(DIAG_SOURCE, DIAG_SOURCE, self._next_line, data, time.monotonic()))
            self._next_line += len(lines)
            self._pending, self._later = [], []
        self.engine.finish()

    # -- what the console shows ------------------------------------------------------
    def section_states(self) -> dict[str, str]:
        shown = self.engine.section_states()
        return {s.id: shown[s.id][0] if s.id in shown else str(INITIAL) for s in self.layout.sections}

    def crossing_events(self) -> dict[str, list[CrossingEvent]]:
        cf = self.engine.crossings
        return {} if cf is None else {code: ctl.events for code, ctl in cf.controllers.items()}

    def reset(self, section: str) -> None:
        """The operator asks to reset ``section`` now (decided in time order: a ``reset`` event)."""
        self.engine.diag.reset(section, self.sim.now_ns)


def received_fix(f: SentFix) -> GnssFix:
    """A delivered fix as the console gets it from the device stream: the unit's name and the written values,
    judged by its own (measurement) time; with the brake pipe its uplink carried."""
    w = as_written(f)
    return GnssFix(
        GNSS_SOURCE,
        unit_name(f),
        w.t_ns,
        w.lat,
        w.lon,
        w.speed_mps,
        w.course_deg,
        time.monotonic(),
        role=f.role,
        recorded=True,
        brake_pipe_bar=f.brake_pipe_bar,
        emergency=f.emergency,
    )
