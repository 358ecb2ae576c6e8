"""What a report holds (:class:`ReportData`) and the safety classes of its first part.

The analyses' results, as they returned them; :mod:`console.sinks.report.document`
turns them into the report's JSON form.  Nothing here computes what the analysis
modules compute: it selects, groups and names.

Safety classes (the report's first part):

* **unsafe** (counted as ``critical`` by ``--fail-on``): a level-crossing
  timeline with a safety violation (the road open with the train on it, or
  a late warning: on less than the crossing's warning time before the head
  arrived, with how late and, where the data show it, why),
  and every critical health finding (a faulty channel, an analog value
  drifted out of its band: a head that may stop detecting);
* **failing** (counted as ``warning``): a section that ended the log
  disturbed (fail-safe: it shows occupied until a reset, so trains are
  stopped, not endangered), a refused reset, a crossing warning held on
  after the head arrived with the tail never confirmed clear (the road
  stays closed), and every warning-level health finding.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from console.analysis.events.detection import DetectionEvent
from console.analysis.health.findings import Finding, Severity
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.engine import SectionsResult
from console.analysis.sections.state import SectionState
from console.analysis.timefmt import iso
from console.drivers.batch import DiagJob
from console.inputs.recognise import natural_key
from console.layout import Layout
from console.sinks.report.gnss_units import GnssUnits
from console.sinks.report.spooled import ReportPassages, SectionHistory
from parsers.report import ParseReport

if TYPE_CHECKING:  # the crossing modules load only when GNSS telemetry is read (collect)
    # pandas too is imported where it is used: a report on a GNSS file reads its fixes first, and pandas
    # loaded before that read sat under its peak (~35 MB of a million-device CSV's 255 MB).
    import pandas as pd

    from console.analysis.crossing.timeline import TimelineRow
    from console.analysis.crossing_batch import CrossingRun

UNSAFE = "unsafe"
FAILING = "failing"


@dataclass(frozen=True)
class InputFile:
    """One input file: what it was recognised as, whether it was read, and why not."""

    path: str  # as given (a directory's files: the directory as given / the relative path)
    format: str
    read: bool
    note: str = ""


@dataclass(frozen=True)
class Attention:
    """One item of the report's first part: unsafe or failing."""

    severity: Severity  # CRITICAL for unsafe, WARNING (or a finding's own) for failing
    safety: str  # UNSAFE | FAILING
    topic: str  # crossing | integrity | health | section | reset
    subject: str
    time_ns: int | None
    message: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "class": self.safety,
            "severity": str(self.severity),
            "topic": self.topic,
            "subject": self.subject,
            "time": iso(self.time_ns),
            "message": self.message,
        }


@dataclass
class ReportData:
    """Everything the report shows, as the analyses returned it."""

    inputs: list[InputFile]
    layout: Layout | None
    settings: SpeedSettings
    job: DiagJob | None = None
    events: list[DetectionEvent] = field(default_factory=list)  # from the diagnostic logs
    sections: SectionsResult | None = None
    section_source: str | None = None  # "diagnostic" | "frames": where the section events came from
    findings: list[Finding] = field(default_factory=list)
    frames: pd.DataFrame | None = None  # sensor and CAN frames together
    frame_events: list[DetectionEvent] = field(default_factory=list)
    fixes: pd.DataFrame | None = None
    # The GNSS unit table, when the fixes were read for it alone (no crossing run): they are not kept.
    gnss_units: GnssUnits | None = None
    crossing: CrossingRun | None = None
    reports: dict[str, ParseReport] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)  # part → why it is empty
    # Daily trends (console.archive.trends): only a report from the archive has history.
    trends: dict[str, Any] | None = None
    # Condition forecasts (console.sinks.report.forecast): from the archive's daily figures too.
    forecast: dict[str, Any] | None = None
    # A diagnostic log read as a stream (console.sinks.report.spooled): its passages and section history
    # kept on disk, not in ``job`` and ``sections``.
    passage_spool: ReportPassages | None = None
    history: SectionHistory | None = None
    # What a report scoped to a head or device is about (console.archive.scope); None: everything read.
    scope: str | None = None

    def attention(self) -> list[Attention]:
        """Unsafe items first, then failing ones; each in time order."""
        items: list[Attention] = []
        if self.crossing is not None:
            for tl_row in self.crossing.timelines:
                for v in tl_row.violations:
                    if v.startswith("late") and tl_row.late_cause:
                        v = f"{v} ({tl_row.late_cause})"
                    items.append(
                        Attention(
                            Severity.CRITICAL,
                            UNSAFE,
                            "crossing",
                            f"{tl_row.crossing} train {tl_row.train}",
                            tl_row.t_head_arrival_ns or tl_row.t_on_ns,
                            v,
                        )
                    )
        if self.crossing is not None:
            for ev in self.crossing.integrity:
                if ev.state == "parted":
                    why = "train parted: " + "; ".join(ev.evidence)
                    items.append(Attention(Severity.CRITICAL, UNSAFE, "integrity", f"train {ev.train}", ev.t_ns, why))
        for f in self.findings:
            if f.severity is Severity.CRITICAL:
                items.append(Attention(f.severity, UNSAFE, "health", _where(f), f.time_ns, f.message))
        items += self._section_items()
        if self.crossing is not None:
            for row in self.crossing.timelines:
                # A train still approaching when the data ends is not a fault; one that reached the
                # crossing with its tail never confirmed clear keeps the road closed.
                if row.t_off_ns is None and row.t_head_arrival_ns is not None:
                    items.append(
                        Attention(
                            Severity.WARNING,
                            FAILING,
                            "crossing",
                            f"{row.crossing} train {row.train}",
                            row.t_head_arrival_ns,
                            f"warning held on after the head arrived ({row.reason_off or 'no tail clear'}): "
                            "the road stays closed",
                        )
                    )
        for f in self.findings:
            if f.severity is Severity.WARNING:
                items.append(Attention(f.severity, FAILING, "health", _where(f), f.time_ns, f.message))
        order = {UNSAFE: 0, FAILING: 1}
        return sorted(
            items, key=lambda a: (order[a.safety], -1 if a.time_ns is None else a.time_ns, a.topic, a.subject)
        )

    def _section_items(self) -> list[Attention]:
        """Sections that ended disturbed (since they last became so) and refused resets."""
        resets: Iterable[Any]
        since: Callable[[str, str], int | None]
        if self.history is not None:
            final, resets, since = self.history.final, self.history.resets(), self.history.since_ns
        elif self.sections is not None:
            tl = self.sections.timeline
            final, resets = self.sections.final, self.sections.resets.itertuples(index=False)

            def since(sid: str, state: str) -> int | None:
                rows = tl[(tl["section"] == sid) & (tl["state"] == state)]
                return int(rows["time_ns"].iloc[-1]) if len(rows) else None
        else:
            return []
        items = [
            Attention(
                Severity.WARNING,
                FAILING,
                "section",
                f"section {sid}",
                since(sid, state),
                f"ended the log disturbed (count {count}): {reason}; needs a reset and a sweep train",
            )
            for sid, (state, count, _in, _out, reason) in final.items()
            if state == SectionState.DISTURBED
        ]
        r: Any
        for r in resets:
            if not r.accepted:
                why = f"reset refused: {r.reason}"
                items.append(Attention(Severity.WARNING, FAILING, "reset", f"section {r.section}", int(r.time_ns), why))
        return items

    def worst(self) -> Severity | None:
        """The highest severity among health findings and attention items (None: nothing at all)."""
        sev = [f.severity for f in self.findings] + [a.severity for a in self.attention()]
        return max(sev, key=lambda s: s.rank) if sev else None

    def data_end_ns(self) -> int | None:
        """The last time any log speaks of: where open-ended bars of the plots stop."""
        ends: list[int] = []
        if self.job is not None:
            ends += [d.last_ns for d in self.job.analysis.devices if d.last_ns]
        if self.frames is not None and len(self.frames):
            ends.append(int(self.frames["time"].max().value))
        ends += [e.time_ns for e in self.events[-1:] + self.frame_events[-1:]]
        span = self.history.span_ns() if self.history is not None else None
        if span is not None:
            ends.append(span[1])
        if self.sections is not None and len(self.sections.timeline):
            ends.append(int(self.sections.timeline["time_ns"].max()))
        return max(ends) if ends else None

    def close(self) -> None:
        """Remove the spool files (a streamed report: once it is written)."""
        if self.passage_spool is not None:
            self.passage_spool.close()
        if self.history is not None:
            self.history.close()


def timeline_order(r: TimelineRow) -> tuple[Any, ...]:
    """Crossing timelines per crossing, then in the order the trains arrived."""
    t = r.t_head_arrival_ns if r.t_head_arrival_ns is not None else r.t_on_ns
    return (natural_key(r.crossing), -1 if t is None else t, natural_key(r.train))


def _where(f: Finding) -> str:
    if f.rule == "voltage_margin":
        return f"sensor {f.counting_head}"
    where = f.counting_head or "–"
    if f.channel is not None:
        where += f" Sys{f.channel}" if f.channel in (1, 2) else f" ch {f.channel}"
    return where
