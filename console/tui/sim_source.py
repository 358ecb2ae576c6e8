"""The station view over the simulated line: the simulator's console, the one live engine, shown as it goes.

:class:`SimSource` steps the simulated line (:class:`~console.sim.station.StationSim`);
its console (:class:`~console.live.simulated.SimulatedConsole`) is the live
engine that ``follow`` and ``station --live`` drive, fed what the simulated
devices report.  The view shows that engine's events, as the live view shows
them (:func:`~console.tui.live_source.event_entry`): sections from its section
engine, crossings from its crossing units, trains from the fixes they got.
The simulator's world (which trains are on the line, their next stop, the
truth) is the simulator's alone.

An operator's reset is a request, decided in time order with the detections
(as ``sections --reset`` decides it): its verdict, accepted or refused with
the reason, reaches the log once the console has read past its time.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

from console.analysis.crossing.controller import CrossingController
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import Transition
from console.layout import Layout
from console.live.simulated import INITIAL, SimulatedConsole
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.tui.live_source import take_events
from console.tui.model import LogEntry, TrainView
from console.tui.sources import reported_train

STEP_S = 0.5  # the simulator's step in the view


class SimSource:
    """The live simulator as a view source; also takes the operator's actions."""

    mode = "sim"

    def __init__(self, layout: Layout, seed: int = 1, config: SimConfig | None = None) -> None:
        # The station view starts with a train close by, so a new user sees movement at once.
        self.sim = StationSim(layout, config or SimConfig(seed=seed, first_train_s=5.0))
        self.layout = layout
        self._events: list[dict[str, Any]] = []
        self.console = SimulatedConsole(self.sim, self._events.append)
        live = self.console.engine
        # The pipeline makes its section engine at the first detection; until then every section is as a
        # simulated line starts: clear.
        self._placeholder = SectionEngine(self.console.layout, initial=INITIAL, start_ns=self.sim.now_ns)
        self.engine: SectionEngine = self._placeholder
        self.crossings: dict[str, CrossingController] = live.crossings.controllers if live.crossings else {}
        self._counts: Counter[str] = Counter()
        self.pending_trains = 0  # added by the operator, waiting for the entry to clear

    @property
    def now_ns(self) -> int:
        return self.sim.now_ns

    def advance(self, seconds: float) -> tuple[list[Transition], list[LogEntry]]:
        entries: list[LogEntry] = []
        left = seconds
        while left > 1e-9:
            dt = min(STEP_S, left)
            self.sim.step(dt)  # the console attached to the line takes the step's reports
            left -= dt
            entries += self._release_pending()
        self.engine = self.console.engine.diag.sections or self._placeholder
        transitions, released = take_events(self._events, self._counts, self.now_ns)
        return transitions, entries + released

    def trains(self, truth: bool = False) -> list[TrainView]:
        """The trains on the line, placed where their units' fixes that reached the console put them."""
        live = self.console.engine
        cf = live.crossings
        out = []
        platforms = self.layout.platforms
        for t in self.sim.active:
            nxt = "–"
            if t.dwell_until_s is not None:
                nxt = "dwelling"
            elif t.stops:
                nxt = next((p.station for p in platforms if p.from_m - 20 <= t.stops[0] <= p.to_m + 20), "stop")
            view = reported_train(
                t.id,
                t.consist.length_m,
                cf.last.get((t.id, "head")) if cf is not None else None,
                cf.last.get((t.id, "eot")) if cf is not None else None,
                self.sim.now_ns,
                nxt,
                t.controller,
                t.x_m if truth else None,
                live.integrity.monitor.state(t.id) if live.integrity is not None else None,
            )
            if view is not None:
                out.append(view)
        return out

    def true_count(self, section_id: str) -> int | None:
        return self.sim.true_count(section_id)

    def head_counts(self) -> dict[str, int]:
        return dict(self._counts)

    # -- operator actions ---------------------------------------------------
    def reset(self, section_id: str) -> None:
        """Ask to reset ``section_id`` now: the verdict reaches the log as the console reads past it."""
        self.console.reset(section_id)

    def inject(self, kind: str, target: str, duration_s: float | None = None, channel: int = 2) -> None:
        start = self.sim.t_s
        end = start + duration_s if duration_s is not None else float("inf")
        if kind == "isolated_pulse":
            start, end = start + 0.1, start + 0.1
        self.sim.inject(Fault(kind, target, start, end, channel))

    def add_train(self) -> str:
        """Queue a train; it enters, behind the others, as soon as the entry is clear."""
        self.pending_trains += 1
        entered = self._release_pending()
        if entered:
            return entered[0].text
        return f"train queued ({self.pending_trains} waiting for the entry to clear)"

    def _release_pending(self) -> list[LogEntry]:
        if not self.pending_trains:
            return []
        d = self.sim.next_direction()
        if not self.sim.entry_clear(d):
            return []
        tr = self.sim.add_train(direction=d)
        if tr is None:
            return []
        self.pending_trains -= 1
        side = "from the down end" if d > 0 else "from the up end"
        return [LogEntry(self.sim.now_ns, "info", f"train {tr.id} added by the operator, entering {side}")]
