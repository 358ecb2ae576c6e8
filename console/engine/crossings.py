"""GNSS fixes → the crossing units' warnings, in every mode (live, the replay, the simulator's console, batch).

Each fix is placed on the layout's track and handed to every crossing's
:class:`~console.analysis.crossing.controller.CrossingController`.  The batch
``crossing`` command and the report feed it the fixes of their files, placed
and in time order (:mod:`console.drivers.crossings`).  Time passes through
:meth:`CrossingFollow.tick`, so a unit that goes silent becomes stale and
the warning stays on (the controller's rule: off only on fresh evidence).

Clocks: a fix carries the unit's own time.  Units' clocks can be off; the
console's clock is the reference.  Per device the smallest observed delay
(reception − measurement) estimates its clock offset; measurement times are
moved by that offset and never put after their reception, so a unit whose
clock runs ahead cannot make old positions look fresh.

A *recorded* fix (read from a file, or the simulator's) is judged by its own
time, and the units' clock ticks every tick step after each fix, before the
next one, until nothing a tick does can change (as
:func:`~console.analysis.crossing.clock.run_controller` ticks one unit).  The
ticks after the latest fix are made as the recordings' clock is known to
have passed them (:meth:`CrossingFollow.advance`), and all of them at the
end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from console.analysis.crossing.clock import wake_until
from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.timeline import timeline
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, CrossingEvent, Fix, TrainSpec
from console.analysis.crossing_batch import OFF_TRACK_M, crossing_settings
from console.analysis.geo import TrackProjector
from console.analysis.timefmt import iso
from console.analysis.window import Window
from console.inputs.base import GnssFix
from console.layout import Layout
from parsers.units import NS

Emit = Callable[[dict[str, Any]], None]
SKEW_TOLERANCE_S = 2.0  # offsets below this are radio and processing delay, not a wrong clock
# A unit's time this far from the console's is a broken clock (a receiver without its almanac, a week
# rollover), not a skew to learn: taken as skew, one such report would age every later fix of the unit.
MAX_CLOCK_OFF_S = 86_400.0
RECENT_FIXES = 512  # per train: enough to find its head's arrival when the warning goes off


class _Ticks:
    """A unit's ticks after its latest fix, as the batch run makes them: every tick step from the fix,
    until one tick past the time after which no tick changes anything (:meth:`next_change_ns`)."""

    def __init__(self, ctl: CrossingController) -> None:
        self.ctl = ctl
        self.step_ns = max(1, int(ctl.s.tick_s * NS))
        self.from_ns: int | None = None  # the latest fix's time
        self.k = 1  # the next tick: from_ns + k·step
        self.settled: int | None = None
        self.done_ns: int | None = None  # the latest tick made: a fix out of time order never ticks back

    def after_fix(self, t_ns: int) -> None:
        self.from_ns, self.k, self.settled = t_ns, 1, self.ctl.next_change_ns()
        if self.done_ns is not None and self.done_ns >= t_ns:
            self.k = (self.done_ns - t_ns) // self.step_ns + 1

    def upto(self, t_ns: int, before: bool) -> list[CrossingEvent]:
        """The ticks at or before ``t_ns`` (strictly before when ``before``: a fix at that time comes next),
        and the instants between them when something falls due (:meth:`CrossingController.next_onset_ns`)."""
        out: list[CrossingEvent] = []
        if self.from_ns is None or self.settled is None:
            return out
        end_ns = t_ns if before else t_ns + 1  # wake-ups strictly before this
        while True:
            t = self.from_ns + self.k * self.step_ns
            stop = t > t_ns or (before and t == t_ns) or t > self.settled + 2 * self.step_ns
            out += self._wake(min(t, end_ns) if stop else t)
            if stop:
                return out
            out += self.ctl.tick(t)
            self.done_ns = t
            self.k += 1

    def _wake(self, to_ns: int) -> list[CrossingEvent]:
        """The unit's clock at each instant before ``to_ns``, after the latest fix and tick, when something
        falls due: a warning comes on at the instant it is due, not a tick before."""
        assert self.from_ns is not None
        start = self.from_ns if self.done_ns is None else max(self.from_ns, self.done_ns)
        self.done_ns, out = wake_until(self.ctl, start, to_ns)
        return out


class TrackPlacer:
    """A unit's report → a fix on the layout's track, its clock judged (every mode: batch places its files'
    fixes with it too).  Fixes more than OFF_TRACK_M from the track, or stamped more than MAX_CLOCK_OFF_S
    from the console's clock, are set aside and counted."""

    def __init__(self, layout: Layout) -> None:
        self.proj = TrackProjector(layout.track) if len(layout.track) >= 2 else None
        self.skew_ns: dict[str, int] = {}
        self.off_track = 0
        self.bad_clock = 0

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

    def place(self, f: GnssFix, now_ns: int) -> Fix | None:
        """A fix on the track, its clock judged (None: not placeable, counted as off the track if so)."""
        if self.proj is None or math.isnan(f.lat_deg) or math.isnan(f.lon_deg):
            return None
        delay = now_ns - f.t_fix_ns
        if abs(delay) > MAX_CLOCK_OFF_S * NS:
            self.bad_clock += 1
            return None
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
        return Fix(now_ns, t_fix, train, role, chainage, f.speed_mps, hint)


class CrossingFollow:
    def __init__(
        self,
        layout: Layout,
        emit: Emit,
        settings: ControllerSettings | None = None,
        trains: Sequence[TrainSpec] = (),
        lead: bool = True,
    ) -> None:
        """``trains``: the trains known before their first fix (a batch run's, paired and with their lengths);
        others are learnt from their fixes.  ``lead``: a warning going off is emitted with its lead (a batch
        run, which works out every timeline from all the fixes at the end, does without)."""
        self.layout = layout
        self.emit = emit
        self.settings = settings or crossing_settings(layout)
        self.lead = lead
        self.placer = TrackPlacer(layout)
        self.controllers = {c.code: CrossingController(c, trains, self.settings) for c in layout.crossings}
        self._ticks = {code: _Ticks(ctl) for code, ctl in self.controllers.items()}
        consist = layout.consist()
        self.default_length_m = consist.length_m if consist else 100.0
        self.last: dict[tuple[str, str], Fix] = {}
        self.recent: dict[str, Window[Fix]] = {}  # each train's last fixes, for the lead of its warnings
        self.fixes = 0
        self.events = 0

    def catch_up(self, t_ns: int) -> None:
        """A recorded fix at ``t_ns`` comes next: the ticks before it (the batch run's)."""
        for code, ticks in self._ticks.items():
            self._out(self.controllers[code], ticks.upto(t_ns, before=True))

    def step(self, fix: Fix) -> None:
        """Run the crossing units on a placed fix."""
        self.fixes += 1
        self.last[(fix.train, fix.role)] = fix
        self.recent.setdefault(fix.train, Window(RECENT_FIXES)).append(fix)
        for code, ctl in self.controllers.items():
            ctl.add_train(TrainSpec(fix.train, self.default_length_m))
            self._out(ctl, ctl.step(fix))
            self._ticks[code].after_fix(fix.t_ns)

    def advance(self, t_ns: int) -> None:
        """The recordings' clock has passed ``t_ns`` (no recorded fix still to come is earlier or at it): the
        units' ticks up to then."""
        for code, ticks in self._ticks.items():
            self._out(self.controllers[code], ticks.upto(t_ns, before=False))

    def parted(self, train: str, t_ns: int, evidence: str) -> None:
        """The integrity monitor saw ``train`` parted: every unit holds its warning for the rear part."""
        for ctl in self.controllers.values():
            self._out(ctl, ctl.train_parted(train, t_ns, evidence))

    def tick(self, now_ns: int) -> None:
        for ctl in self.controllers.values():
            self._out(ctl, ctl.tick(now_ns))

    def next_wake_ns(self, now_ns: int) -> int | None:
        """When a live console must tick the units next, besides its steady ticks: the first instant after
        ``now_ns`` at which a warning falls due or a unit goes stale (None: nothing pending)."""
        wake = [w for ctl in self.controllers.values() if (w := ctl.next_onset_ns(now_ns)) is not None]
        return min(wake) if wake else None

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
            if e.kind == "off" and self.lead:
                ev |= self._lead(ctl, e.train, e.t_ns)
            self.emit(ev)

    def _lead(self, ctl: CrossingController, train: str, off_ns: int) -> dict[str, Any]:
        """The warning that just went off at ``off_ns``: its lead (head arrival − on), as the batch timeline
        computes it (its pass's row; none for a warning released before the train arrived)."""
        row = next(
            (r for r in timeline(ctl, list(self.recent.get(train, ()))) if r.train == train and r.t_off_ns == off_ns),
            None,
        )
        lead = row.lead_s if row is not None else None
        if row is None or lead is None:
            return {"lead_s": None, "warning_time_s": ctl.crossing.warning_time_s, "late": None}
        return {"lead_s": round(lead, 3), "warning_time_s": row.warning_time_s, "late": row.late_by_s is not None}

    def warnings_on(self) -> dict[str, bool]:
        return {code: ctl.warning_on for code, ctl in self.controllers.items()}
