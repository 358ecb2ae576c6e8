"""Train integrity, in every mode: the fixes the crossing units get, the axles and section changes the
counting heads give → :class:`~console.analysis.integrity.monitor.IntegrityMonitor` → ``type: integrity``.

The fixes arrive placed on the track (with the brake-pipe pressure and
emergency status of units that report them: LoRa payload version 2) (:class:`~console.engine.crossings.CrossingFollow`),
with their units' own times: GNSS time, common to the head and the EOT unit
(the monitor allows ``clock_offset_s`` between them).  The monitor's clock is
the data's (the latest fix time), not the wall clock: a file followed from its
start is judged as it was recorded, and a unit goes stale while the other
reports on.  Axles and the counters' doubt come from the diagnostic logs and
the sensor and CAN frames in the order the section engine gets them.  A train's length is the layout's first
consist's (as the crossing units assume); its axle count only where the
layout names a single consist, so the counters' check never compares a train
with another train's consist.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from console.analysis.crossing.values import Fix
from console.analysis.events.detection import DetectionEvent
from console.analysis.integrity.monitor import IntegrityMonitor
from console.analysis.integrity.values import ConsistSpec, IntegrityEvent, IntegritySettings
from console.analysis.sections.state import Transition
from console.engine.sinks import Sink
from console.layout import Layout

if TYPE_CHECKING:
    from console.analysis.events.block import EventBlock

Emit = Callable[[dict[str, Any]], None]


class IntegrityFollow(Sink):
    """The monitor, live: a sink of the pipeline's detections and section changes (and the frame
    follower's), fed the placed fixes by the engine."""

    def __init__(
        self,
        layout: Layout,
        emit: Emit,
        settings: IntegritySettings | None = None,
        consists: Sequence[ConsistSpec] = (),
        keep: bool = False,
    ) -> None:
        """``consists``: the trains known before their first fix (a batch run's); ``keep``: every event is
        also kept, in :attr:`taken` (a batch run shows them all at the end)."""
        self.monitor = IntegrityMonitor(settings, layout)
        for c in consists:
            self.monitor.add_train(c)
        self.emit = emit
        self.taken: list[IntegrityEvent] | None = [] if keep else None
        consist = layout.consist()
        self.length_m = consist.length_m if consist else 100.0
        self.axle_count = len(consist.axles_m) if consist is not None and len(layout.consists) == 1 else None
        self.events = 0
        self.clock_ns: int | None = None  # the data's clock: the latest unit time seen

    def fix(self, f: Fix, t_unit_ns: int, brake_pipe_bar: float = math.nan, emergency: bool = False) -> None:
        """A placed fix; ``t_unit_ns`` its unit's own time (not moved by the crossing units' skew rule);
        the brake-pipe pressure and emergency status its report carried (LoRa version 2), if any."""
        self.clock_ns = t_unit_ns if self.clock_ns is None else max(self.clock_ns, t_unit_ns)
        self._train(f.train)
        self._out(
            self.monitor.fix(
                self.clock_ns, t_unit_ns, f.train, f.role, f.chainage_m, f.speed_mps, brake_pipe_bar, emergency
            )
        )

    def brake_pipe(self, train: str, role: str, t_unit_ns: int, bar: float, emergency: bool = False) -> None:
        """A unit's brake-pipe status without a fix placed on the track."""
        self.clock_ns = t_unit_ns if self.clock_ns is None else max(self.clock_ns, t_unit_ns)
        self._train(train)
        self._out(self.monitor.brake_pipe(self.clock_ns, t_unit_ns, train, role, bar, emergency))

    def _train(self, train: str) -> None:
        if train not in self.monitor.trains:
            # The layout's consist is a guess for any one train: its length is learnt from its fixes.
            self.monitor.add_train(ConsistSpec(train, self.length_m, self.axle_count, length_known=False))

    def detection(self, e: DetectionEvent) -> None:
        self._out(self.monitor.detection(e))

    def transition(self, tr: Transition) -> None:
        self._out(self.monitor.transition(tr))

    # -- as the pipeline's sink
    def detections(self, block: EventBlock) -> None:
        for e in block.events():  # per event: the monitor is a state machine
            self.detection(e)

    def transitions(self, rows: Sequence[Transition]) -> None:
        for tr in rows:
            self.transition(tr)

    def tick(self) -> None:
        if self.clock_ns is not None:
            self._out(self.monitor.tick(self.clock_ns))

    def _out(self, events: list[IntegrityEvent]) -> None:
        if self.taken is not None:
            self.taken += events
        for e in events:
            self.events += 1
            self.emit({"type": "integrity", **e.to_dict()})
