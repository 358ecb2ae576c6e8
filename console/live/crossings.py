"""GNSS fixes arriving live (gpsd, LoRaWAN) → the crossing units' warnings.

Each fix is placed on the layout's track and handed to every crossing's
:class:`~console.analysis.crossing.CrossingController`, the same unit the
batch ``crossing`` command and the simulator run.  Time passes through
:meth:`CrossingFollow.tick`, so a unit that goes silent becomes stale and
the warning stays on (the controller's rule: off only on fresh evidence).

Clocks: a fix carries the unit's own time.  Units' clocks can be off; the
console's clock is the reference.  Per device the smallest observed delay
(reception − measurement) estimates its clock offset; measurement times are
moved by that offset and never put after their reception, so a unit whose
clock runs ahead cannot make old positions look fresh.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

from console.analysis.crossing import EOT, HEAD, ControllerSettings, CrossingController, CrossingEvent, Fix, TrainSpec
from console.analysis.crossing_batch import OFF_TRACK_M
from console.analysis.crossing_timeline import timeline
from console.analysis.geo import TrackProjector
from console.analysis.timefmt import iso
from console.inputs.base import GnssFix
from console.layout import Layout
from parsers.units import NS

Emit = Callable[[dict[str, Any]], None]
SKEW_TOLERANCE_S = 2.0  # offsets below this are radio and processing delay, not a wrong clock
RECENT_FIXES = 512  # per train: enough to find its head's arrival when the warning goes off


class CrossingFollow:
    def __init__(self, layout: Layout, emit: Emit, settings: ControllerSettings | None = None) -> None:
        self.layout = layout
        self.emit = emit
        self.settings = settings or ControllerSettings()
        self.proj = TrackProjector(layout.track) if len(layout.track) >= 2 else None
        self.controllers = {c.code: CrossingController(c, [], self.settings) for c in layout.crossings}
        consist = layout.consist()
        self.default_length_m = consist.length_m if consist else 100.0
        self.skew_ns: dict[str, int] = {}
        self.last: dict[tuple[str, str], Fix] = {}
        self.recent: dict[str, deque[Fix]] = {}  # each train's last fixes, for the lead of its warnings
        self.off_track = 0
        self.fixes = 0
        self.events = 0

    def owner(self, f: GnssFix) -> tuple[str, str]:
        """(train, role): the unit says so (LoRa payload), or its name does (<train>-head / -eot)."""
        if f.role in (HEAD, EOT):
            if f.train:
                return f.train, f.role
            # A device export with a role column and no train one: the name still says whose it is.
            suffix = f"-{f.role}"
            return (f.device[: -len(suffix)] if f.device.endswith(suffix) else f.device), f.role
        for role in (HEAD, EOT):
            if f.device.endswith(f"-{role}"):
                return f.device[: -len(role) - 1], role
        return f.device, HEAD

    def fix(self, f: GnssFix, now_ns: int) -> Fix | None:
        """Place a fix on the track and run the crossing units on it; the placed fix (None: not placeable)."""
        if self.proj is None or math.isnan(f.lat_deg) or math.isnan(f.lon_deg):
            return None
        delay = now_ns - f.t_fix_ns
        best = self.skew_ns.get(f.device)
        self.skew_ns[f.device] = delay if best is None else min(best, delay)
        offset = self.skew_ns[f.device]
        t_fix = f.t_fix_ns + offset if abs(offset) > SKEW_TOLERANCE_S * NS else f.t_fix_ns
        t_fix = min(t_fix, now_ns)
        p = self.proj.project(f.lat_deg, f.lon_deg)
        if float(p.offset_m[0]) > OFF_TRACK_M:
            self.off_track += 1
            return None
        train, role = self.owner(f)
        chainage = float(p.chainage_m[0])
        hint = 0
        if not (math.isnan(f.course_deg) or math.isnan(f.speed_mps)) and f.speed_mps >= 1.0:
            diff = (f.course_deg - self.proj.bearing_deg(chainage) + 540.0) % 360.0 - 180.0
            hint = 1 if abs(diff) < 60 else -1 if abs(diff) > 120 else 0
        fix = Fix(now_ns, t_fix, train, role, chainage, f.speed_mps, hint)
        self.fixes += 1
        self.last[(train, role)] = fix
        self.recent.setdefault(train, deque(maxlen=RECENT_FIXES)).append(fix)
        for ctl in self.controllers.values():
            ctl.add_train(TrainSpec(train, self.default_length_m))
            self._out(ctl, ctl.step(fix))
        return fix

    def parted(self, train: str, t_ns: int, evidence: str) -> None:
        """The integrity monitor saw ``train`` parted: every unit holds its warning for the rear part."""
        for ctl in self.controllers.values():
            self._out(ctl, ctl.train_parted(train, t_ns, evidence))

    def tick(self, now_ns: int) -> None:
        for ctl in self.controllers.values():
            self._out(ctl, ctl.tick(now_ns))

    def _out(self, ctl: CrossingController, events: list[CrossingEvent]) -> None:
        for e in events:
            self.events += 1
            ev: dict[str, Any] = {
                "type": "crossing",
                "crossing": e.crossing,
                "train": e.train,
                "kind": e.kind,
                "reason": e.reason,
                "time_ns": e.t_ns,
                "time": iso(e.t_ns),
            }
            if e.kind == "off":
                ev |= self._lead(ctl, e.train)
            self.emit(ev)

    def _lead(self, ctl: CrossingController, train: str) -> dict[str, Any]:
        """The warning that just went off: its lead (head arrival − on), as the batch timeline computes it."""
        rows = [r for r in timeline(ctl, list(self.recent.get(train, ()))) if r.train == train]
        lead = rows[0].lead_s if rows else None
        if lead is None:
            return {"lead_s": None, "warning_time_s": ctl.crossing.warning_time_s, "late": None}
        return {
            "lead_s": round(lead, 3),
            "warning_time_s": rows[0].warning_time_s,
            "late": rows[0].late_by_s is not None,
        }

    def warnings_on(self) -> dict[str, bool]:
        return {code: ctl.warning_on for code, ctl in self.controllers.items()}
