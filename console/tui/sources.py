"""Sources for the station view: a replay of real logs (the simulator's is :mod:`console.tui.sim_source`)."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from console.analysis.crossing import ControllerSettings, CrossingController, CrossingEvent, Fix, TrainSpec
from console.analysis.events import DetectionEvent, EventKind
from console.analysis.integrity import PARTED, ConsistSpec, IntegrityEvent, IntegrityMonitor
from console.analysis.section_state import SectionState, Transition
from console.analysis.sections import SectionEngine
from console.layout import Layout
from console.tui.model import LogEntry, TrainView
from parsers.units import NS

if TYPE_CHECKING:
    import pandas as pd

NOTABLE = {
    EventKind.SINGLE_CHANNEL: "warning",
    EventKind.INTERFERENCE: "warning",
    EventKind.ACCIDENTAL: "info",
    EventKind.CHANNEL_FAULT: "critical",
    EventKind.POWER_LOSS: "critical",
    EventKind.POWER_RESTORED: "info",
    EventKind.COUNT_ERROR: "warning",
}


def _crossing_entries(events: Sequence[CrossingEvent]) -> list[LogEntry]:
    out = []
    for e in events:
        sev = "warning" if e.kind == "alarm" else "info"
        verb = {"on": "warning ON", "off": "road given back", "alarm": "ALARM"}.get(e.kind, e.kind)
        out.append(LogEntry(e.t_ns, sev, f"crossing {e.crossing} {verb} (train {e.train}): {e.reason}"))
    return out


INTEGRITY_SEVERITY = {"whole": "info", "doubtful": "warning", PARTED: "critical"}


def integrity_entry(t_ns: int, train: str, state: str, evidence: Sequence[str]) -> LogEntry:
    """A train's integrity change as the event log shows it, with its evidence."""
    return LogEntry(t_ns, INTEGRITY_SEVERITY.get(state, "warning"), f"train {train} {state}: {'; '.join(evidence)}")


def _integrity_entries(events: Sequence[IntegrityEvent]) -> list[LogEntry]:
    return [integrity_entry(e.t_ns, e.train, e.state, e.evidence) for e in events]


def _detection_entries(events: Sequence[DetectionEvent]) -> list[LogEntry]:
    out = []
    for e in events:
        sev = NOTABLE.get(e.kind)
        if sev is not None:
            ch = f" Sys{e.channel}" if e.channel else ""
            out.append(
                LogEntry(e.time_ns, sev, f"head {e.head}{ch}: {e.kind.value.replace('_', ' ')} {e.detail}".strip())
            )
    return out


QUIET_SKIP_S = 300.0  # a replay skips quiet stretches longer than this
LEAD_IN_S = 10  # and resumes this long before the next record


def _span(seconds: float) -> str:
    d, rest = divmod(int(seconds), 86400)
    h, rest = divmod(rest, 3600)
    m = rest // 60
    return (f"{d} d " if d else "") + (f"{h} h " if h or d else "") + f"{m} min"


STALE_S = ControllerSettings().stale_after_s  # the crossing units' own rule for a silent unit
GONE_S = 120.0  # a replayed train not heard for this long has left the line


def reported_train(
    train: str,
    length_m: float,
    head: Fix | None,
    eot: Fix | None,
    now_ns: int,
    next_stop: str = "–",
    controller: str = "–",
    true_head_m: float | None = None,
    integrity: str | None = None,
) -> TrainView | None:
    """A train as the console knows it: from the last head and EOT fixes that reached it.

    A missing end is placed a train length from the other, so the diagram still
    shows the train; the ages tell the panel which end is only inferred."""
    ref = head or eot
    if ref is None:
        return None
    d = ref.direction_hint or (head.direction_hint if head else 0) or 1

    def now_at(f: Fix) -> float:
        # Dead reckoning from a fresh fix, so the diagram moves between reports;
        # a stale unit's train stays where it was last heard.
        age_s = (now_ns - f.t_fix_ns) / NS
        v = f.speed_mps if f.speed_mps == f.speed_mps else 0.0
        return f.chainage_m + (d * v * age_s if 0 < age_s <= STALE_S else 0.0)

    head_m = now_at(head) if head else now_at(ref) + d * length_m
    tail_m = now_at(eot) if eot else head_m - d * length_m
    v = ref.speed_mps if ref.speed_mps == ref.speed_mps else 0.0
    return TrainView(
        train,
        head_m,
        tail_m,
        d,
        v * 3.6,
        next_stop,
        controller,
        head_age_s=(now_ns - head.t_fix_ns) / NS if head else None,
        eot_age_s=(now_ns - eot.t_fix_ns) / NS if eot else None,
        true_head_m=true_head_m,
        integrity=integrity,
    )


class ReplaySource:
    """Parsed real logs played back: diagnostic records through the section engine,
    telemetry through the crossing units, at any speed, with jumps in time."""

    mode = "replay"

    def __init__(self, paths: Sequence[Path], layout: Layout) -> None:
        from console.analysis.diag_events import DiagEventSettings
        from console.drivers.batch import read_diag
        from console.engine.pipeline import PipelineSettings
        from console.engine.sinks import EventList

        diag = [p for p in paths if _is_diag(p)]
        other = [p for p in paths if p not in diag]
        kept = EventList()
        if diag:
            read_diag(diag, PipelineSettings(events=DiagEventSettings(), layout=layout), kept)
        events = kept.events
        frame = None
        if other and len(layout.track) >= 2:
            from parsers.gnss_files import parse_gnss

            frame, _report, _states = parse_gnss(other)
        self._setup(layout, events, frame)

    @classmethod
    def from_parts(cls, layout: Layout, events: list[DetectionEvent], fixes: pd.DataFrame | None) -> ReplaySource:
        """A replay of detection events and a GNSS fix table already at hand (the archive's history)."""
        source = cls.__new__(cls)
        source._setup(layout, events, fixes)
        return source

    def _setup(self, layout: Layout, events: list[DetectionEvent], frame: pd.DataFrame | None) -> None:
        from console.analysis.crossing_batch import pair_trains, to_fixes

        self.layout = layout
        self.events = sorted(events, key=lambda e: e.time_ns)
        self.fixes: list[Fix] = []
        self.train_specs: list[TrainSpec] = []
        # The axle count is known only where the layout names a single consist.
        self._axles = len(layout.consists[0].axles_m) if len(layout.consists) == 1 else None
        if frame is not None and len(frame) and len(layout.track) >= 2:
            consist = layout.consist()
            trains, _ = pair_trains(frame, (), consist.length_m if consist else 100.0)
            self.fixes, _ = to_fixes(frame, layout, trains)
            self.fixes.sort(key=lambda f: f.t_ns)
            self.train_specs = [TrainSpec(t.train, t.length_m) for t in trains]
        times = [e.time_ns for e in self.events] + [f.t_ns for f in self.fixes]
        if not times:
            raise ValueError("nothing to replay: no wheel-sensor records and no placeable GNSS fixes")
        self.start_ns, self.end_ns = min(times) - NS, max(times) + NS
        self._rebuild(self.start_ns)

    def _rebuild(self, t_ns: int) -> None:
        self._now = t_ns
        self.engine = SectionEngine(self.layout, initial=SectionState.PREPARATORY, start_ns=t_ns)
        self.crossings = {c.code: CrossingController(c, self.train_specs) for c in self.layout.crossings}
        self.integrity = IntegrityMonitor(layout=self.layout)
        for spec in self.train_specs:
            self.integrity.add_train(ConsistSpec(spec.train, spec.length_m, self._axles, length_known=False))
        self._i_event = self._i_fix = 0
        self._counts: Counter[str] = Counter()
        self._last: dict[tuple[str, str], Fix] = {}

    @property
    def now_ns(self) -> int:
        return self._now

    def advance(self, seconds: float, skip_quiet: bool = True) -> tuple[list[Transition], list[LogEntry]]:
        transitions: list[Transition] = []
        entries: list[LogEntry] = self._skip_quiet() if skip_quiet else []
        target = min(self.end_ns, self._now + int(seconds * NS))
        while self._i_event < len(self.events) and self.events[self._i_event].time_ns <= target:
            e = self.events[self._i_event]
            self._i_event += 1
            changes = self.engine.step(e)
            transitions += changes
            entries += _detection_entries([e])
            entries += _integrity_entries(self.integrity.detection(e))
            for change in changes:
                entries += _integrity_entries(self.integrity.transition(change))
            if e.kind is EventKind.AXLE:
                self._counts[e.head] += 1
        while self._i_fix < len(self.fixes) and self.fixes[self._i_fix].t_ns <= target:
            f = self.fixes[self._i_fix]
            self._i_fix += 1
            self._last[(f.train, f.role)] = f
            for ctl in self.crossings.values():
                entries += _crossing_entries(ctl.step(f))
            entries += self._integrity(
                self.integrity.fix(f.t_ns, f.t_fix_ns, f.train, f.role, f.chainage_m, f.speed_mps)
            )
        for ctl in self.crossings.values():
            entries += _crossing_entries(ctl.tick(target))
        entries += self._integrity(self.integrity.tick(target))
        self._now = target
        return transitions, entries

    def _integrity(self, events: list[IntegrityEvent]) -> list[LogEntry]:
        """Integrity changes into the log; a parted train's warnings held at every crossing."""
        entries = _integrity_entries(events)
        for e in events:
            if e.state == PARTED:
                for ctl in self.crossings.values():
                    entries += _crossing_entries(ctl.train_parted(e.train, e.t_ns, "; ".join(e.evidence)))
        return entries

    def _skip_quiet(self) -> list[LogEntry]:
        """Logs from different days leave hours of nothing between them: with no
        train in view, go straight to a little before the next record."""
        nxt = [self.events[self._i_event].time_ns] if self._i_event < len(self.events) else []
        nxt += [self.fixes[self._i_fix].t_ns] if self._i_fix < len(self.fixes) else []
        if not nxt or self.trains():
            return []
        to = min(nxt) - LEAD_IN_S * NS
        if to - self._now < QUIET_SKIP_S * NS:
            return []
        gap_s = (to - self._now) / NS
        self._now = to
        return [LogEntry(to, "info", f"nothing in the logs for {_span(gap_s)}: skipped to the next record")]

    def jump(self, seconds: float) -> tuple[list[Transition], list[LogEntry]]:
        """Jump in time: forward, what happened on the way (for the log); backwards, replayed from the start
        quietly up to the target (nothing new happened)."""
        target = min(self.end_ns, max(self.start_ns, self._now + int(seconds * NS)))
        back = target < self._now
        if back:
            self._rebuild(self.start_ns)
        passed = self.advance((target - self._now) / NS, skip_quiet=False)
        return ([], []) if back else passed

    def trains(self, truth: bool = False) -> list[TrainView]:
        out = []
        for spec in self.train_specs:
            head = self._last.get((spec.train, "head"))
            eot = self._last.get((spec.train, "eot"))
            ref = head or eot
            if ref is None or self._now - ref.t_fix_ns > GONE_S * NS:
                continue  # not heard for two minutes: off the line
            view = reported_train(
                spec.train, spec.length_m, head, eot, self._now, integrity=self.integrity.state(spec.train)
            )
            if view is not None:
                out.append(view)
        return out

    def true_count(self, section_id: str) -> int | None:
        return None

    def head_counts(self) -> dict[str, int]:
        return dict(self._counts)


def _is_diag(path: Path) -> bool:
    from parsers.sources import open_input

    try:
        stream, raw, _ = open_input(path)
    except Exception:
        return False
    try:
        head = stream.read(4096)
    finally:
        stream.close()
        raw.close()
    return any(line.strip().startswith(b"Diag_id:") for line in head.splitlines()[:5])
