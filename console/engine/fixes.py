"""GNSS fixes → train integrity and the crossing units: the one stage every mode drives.

Live (``follow``, ``station --live``), the replay and the simulator's console
hand it each unit's report as it comes (:meth:`FixStage.take`); the batch
``crossing`` command and the report hand it their files' fixes, placed on the
track and in time order (:meth:`FixStage.placed`, :mod:`console.drivers.crossings`).
Per fix, in this order: the crossing units' ticks due before it (a recorded
fix), the integrity monitor's verdict (a train parted by this fix is held at
once by every unit), then the units' step.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from console.analysis.crossing.values import ControllerSettings, Fix, TrainSpec
from console.analysis.crossing_batch import crossing_settings, integrity_settings
from console.analysis.integrity.values import ConsistSpec, IntegritySettings
from console.engine.crossings import CrossingFollow
from console.engine.integrity import IntegrityFollow
from console.inputs.base import GnssFix
from console.layout import Layout

Emit = Callable[[dict[str, Any]], None]


class FixStage:
    """The crossing units (a layout with [[crossings]] or a [[track]]) and the integrity monitor (a [[track]])."""

    def __init__(
        self,
        layout: Layout,
        emit: Emit,
        *,
        settings: ControllerSettings | None = None,
        integrity: IntegritySettings | None = None,
        trains: Sequence[TrainSpec] = (),
        consists: Sequence[ConsistSpec] = (),
        batch: bool = False,
    ) -> None:
        """``settings`` / ``integrity``: the units' and the monitor's (default: the layout's); ``trains`` /
        ``consists``: the trains known before their first fix; ``batch``: every integrity event kept and no
        lead worked out per warning (a batch run shows whole timelines at the end)."""
        self.emit = emit
        placed = bool(layout.crossings) or len(layout.track) >= 2
        self.crossings = CrossingFollow(layout, emit, settings, trains, lead=not batch) if placed else None
        # The monitor's timing is the crossing units' (the same fixes, the same radio).
        timing = integrity or integrity_settings(
            self.crossings.settings if self.crossings else crossing_settings(layout)
        )
        self.integrity = (
            IntegrityFollow(layout, self._integrity_event, timing, consists, keep=batch)
            if len(layout.track) >= 2
            else None
        )

    def take(self, item: GnssFix, now_ns: int) -> None:
        """A unit's report, its clock judged against ``now_ns``."""
        if self.crossings is None:
            return
        fix = self.crossings.placer.place(item, now_ns)
        if fix is not None:
            self.placed(fix, item.t_fix_ns, item.brake_pipe_bar, item.emergency, item.recorded)
        elif self.integrity is not None and (item.emergency or not math.isnan(item.brake_pipe_bar)):
            # No place on the track (no fix, say), but the brake pipe's status stands on its own.
            train, role = self.crossings.placer.owner(item)
            self.integrity.brake_pipe(train, role, item.t_fix_ns, item.brake_pipe_bar, item.emergency)

    def placed(
        self,
        fix: Fix,
        t_unit_ns: int,
        brake_pipe_bar: float = math.nan,
        emergency: bool = False,
        recorded: bool = True,
    ) -> None:
        """A fix placed on the track; ``t_unit_ns``: its unit's own time."""
        assert self.crossings is not None
        if recorded:
            self.crossings.catch_up(fix.t_ns)
        # The monitor's verdict on this fix reaches the crossing units before they take it (a train parted
        # by it is held at once).
        if self.integrity is not None:
            self.integrity.fix(fix, t_unit_ns, brake_pipe_bar, emergency)
        self.crossings.step(fix)

    def _integrity_event(self, ev: dict[str, Any]) -> None:
        self.emit(ev)
        if ev["state"] == "parted" and self.crossings is not None:
            self.crossings.parted(ev["train"], ev["time_ns"], "; ".join(ev["evidence"]))
