"""Batch crossings: a table of GNSS fixes → the one crossing and integrity stage → timelines.

``trackside crossing`` and the report (files or the archive) read their fixes
into a table; here they are paired into trains (:mod:`console.analysis.crossing_batch`),
placed on the track as live places a unit's report, and fed in time order to
:class:`~console.engine.fixes.FixStage`, the stage ``follow``, the replay and the
simulator's console run; its units' clock is run out at the end.  What only a
batch run can give is worked out afterwards from all the fixes: each warning's
timeline (the lead, the spare split in hindsight).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from console.analysis.crossing.timeline import TimelineRow, timeline
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, CrossingEvent, TrainSpec
from console.analysis.crossing_batch import (
    CrossingRun,
    TrainDevices,
    crossing_settings,
    integrity_settings,
    pair_trains,
    undated_fixes,
    unit_fixes,
)
from console.analysis.integrity.values import ConsistSpec
from console.engine.crossings import TrackPlacer
from console.engine.fixes import FixStage
from console.inputs.base import GnssFix
from console.layout import Layout
from parsers.units import ALL_TIME


def run_crossings(
    fixes: pd.DataFrame,
    layout: Layout,
    trains: Sequence[TrainDevices] = (),
    settings: ControllerSettings | None = None,
    report_period_s: float | None = None,
) -> CrossingRun:
    """Every crossing of the layout, every train: timelines, events and each train's integrity."""
    consist = layout.consist()
    chosen, unassigned = pair_trains(fixes, trains, consist.length_m if consist else 100.0)
    if len(layout.track) < 2:
        raise ValueError(f"{layout.source}: the layout has no [[track]] polyline to place fixes on")
    placer = TrackPlacer(layout)  # as live places a unit's report
    placed = [p for f in _reports(unit_fixes(fixes, chosen)) if (p := placer.place(f, f.t_fix_ns)) is not None]
    off = placer.off_track
    s = settings or ControllerSettings(line_speed_mps=layout.line_speed_mps)
    if report_period_s is None and layout.gnss_report_period_s is None and placed:
        # The devices' own report period: the median gap between a device's fixes.
        # One pass over the fixes (a scan per train and role was quadratic in the trains).
        times: dict[tuple[str, str], list[int]] = defaultdict(list)
        for f in placed:
            times[(f.train, f.role)].append(f.t_fix_ns)
        gaps = [
            float(g) / 1e9
            for tr in chosen
            for role in (HEAD, EOT)
            for g in np.diff(np.sort(np.asarray(times.get((tr.train, role), []), dtype=np.int64)))
        ]
        report_period_s = float(np.median(gaps)) if gaps else s.report_period_s
    s = crossing_settings(layout, report_period_s, s)
    stage = FixStage(
        layout,
        _unused,
        settings=s,
        integrity=integrity_settings(s),
        trains=[TrainSpec(t.train, t.length_m) for t in chosen],
        consists=[ConsistSpec(t.train, t.length_m, length_known=t.length_given) for t in chosen],
        batch=True,
    )
    assert stage.crossings is not None and stage.integrity is not None  # the layout has a [[track]]
    for f in placed:  # in time order (unit_fixes); per fix: the units are state machines
        stage.placed(f, f.t_fix_ns)
    stage.crossings.advance(int(ALL_TIME))  # the recordings end: every tick the units' clocks still owe
    rows: list[TimelineRow] = []
    events: list[CrossingEvent] = []
    jumps = 0
    for ctl in stage.crossings.controllers.values():  # the layout's order
        rows += timeline(ctl, placed, s)
        events += ctl.events
        jumps = ctl.position_jumps  # every unit sees the same fixes and sets aside the same ones
    events.sort(key=lambda e: e.t_ns)
    integrity = stage.integrity.taken or []
    return CrossingRun(rows, events, list(chosen), off, unassigned, jumps, integrity, undated_fixes(fixes, chosen))


def _reports(sel: pd.DataFrame) -> list[GnssFix]:
    """The table's fixes as the units' recorded reports (one object per fix: a file holds a few per second)."""
    cols = ("device", "t_ns", "lat", "lon", "speed_mps", "course_deg", "role", "train")
    return [
        GnssFix("file", dev, int(t), float(lat), float(lon), float(v), float(c), 0.0, role, train, recorded=True)
        for dev, t, lat, lon, v, c, role, train in zip(*(sel[c].to_numpy() for c in cols), strict=True)
    ]


def _unused(_event: dict[str, Any]) -> None:
    """The stage's events as JSON lines: a batch run takes its results from the units at the end."""
