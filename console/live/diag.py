"""Diagnostic records arriving in pieces → the pipeline → live events.

A followed log's complete lines are parsed by the batch reader's own
tokenizer and rules (one register registry and one parse report for every
followed file) and fed to the one :class:`~console.engine.pipeline.Pipeline`,
the same that ``trackside analyze``, ``sections`` and ``health`` drive: its
passages, section changes and health findings come out as they are decided
and are turned into the events ``follow --jsonl`` prints and the station
shows (:class:`LiveEvents`).  Passages of status records only are counted,
not shown, unless asked for (as in ``analyze``).
"""

from __future__ import annotations

import codecs
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from console.analysis.diag_events import DiagEventSettings
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.state import SectionState
from console.engine.pipeline import HEALTH_REGISTERS, Pipeline, PipelineSettings
from console.engine.sinks import Sink, Sinks
from console.layout import Layout
from console.sinks.tables.event_lines import health_event, reset_event, section_event
from console.sinks.tables.passage_spool import passage_texts
from parsers.diag.read import DiagReader
from parsers.diag.records import DiagChunk
from parsers.diag.registry import DiagRegistry
from parsers.report import FileReport
from parsers.units import NO_TIME, NS

if TYPE_CHECKING:
    from console.analysis.head_table import Heads
    from console.analysis.health.findings import Finding
    from console.analysis.passages.buckets import Columns
    from console.analysis.sections.state import ResetRecord, Transition

Emit = Callable[[dict[str, Any]], None]


@dataclass
class DiagFollowStats:
    passages: int = 0
    section_changes: int = 0
    health_findings: int = 0
    rejections_shown: int = 0
    clock_steps_shown: int = 0
    by_file: dict[str, FileReport] = field(default_factory=dict)


class LiveEvents(Sink):
    """The pipeline's results as live events: passages, section changes, health findings (as the pipeline
    hands them on: new or graver than before; info findings are not news)."""

    def __init__(self, emit: Emit, stats: DiagFollowStats) -> None:
        self.emit = emit
        self.stats = stats

    def passages(self, cols: Columns, heads: Heads) -> None:
        for text in passage_texts(cols, heads):
            self.stats.passages += 1
            self.emit({"type": "passage", **json.loads(text)})

    def transitions(self, rows: Sequence[Transition]) -> None:
        for tr in rows:
            self.stats.section_changes += 1
            self.emit(section_event(tr))

    def resets(self, rows: Sequence[ResetRecord]) -> None:
        for r in rows:
            self.emit(reset_event(r))

    def findings(self, rows: Sequence[Finding]) -> None:
        for f in rows:
            if str(f.severity) == "info":
                continue
            self.stats.health_findings += 1
            self.emit(health_event(f))


def live_settings(
    layout: Layout | None,
    speed: SpeedSettings,
    include_status: bool = False,
    initial: SectionState = SectionState.PREPARATORY,
) -> PipelineSettings:
    """What the pipeline computes live: passages; with a layout, sections and health too (a head silent
    for the layout's power gap has lost power)."""
    if layout is None:
        return PipelineSettings(speed=speed, include_status=include_status)
    return PipelineSettings(
        speed=speed,
        events=DiagEventSettings(power_gap_s=layout.power_gap_s),
        layout=layout,
        sections=layout if layout.sections else None,
        initial=initial,
        keep_registers=HEALTH_REGISTERS,
        health="closed",
        include_status=include_status,
    )


class DiagFollow:
    """The diagnostic half of the live engine: feed line blocks, get events through ``emit``."""

    def __init__(
        self,
        layout: Layout | None,
        settings: SpeedSettings,
        emit: Emit,
        include_status: bool = False,
        also: Sink | None = None,
        initial: SectionState = SectionState.PREPARATORY,
        registry: DiagRegistry | None = None,
    ):
        """``also``: another sink of the pipeline's results (the integrity monitor takes its axles and
        section changes); ``initial``: the sections' state before the first detection; ``registry``: the one
        the records to be fed were parsed into (a replay: :meth:`feed`)."""
        self.layout = layout
        self.emit = emit
        self.reader = DiagReader([])
        if registry is not None:
            self.reader.registry = registry
        self.stats = DiagFollowStats()
        self._file_ids: dict[str, int] = {}
        sink = LiveEvents(emit, self.stats)
        self.pipeline = Pipeline(
            self.reader.registry,
            live_settings(layout, settings, include_status, initial),
            Sinks(sink, also) if also is not None else sink,
        )

    def add(self, source: str, file_label: str, first_line: int, data: bytes) -> None:
        if first_line == 1 and data.startswith(codecs.BOM_UTF8):
            data = data[len(codecs.BOM_UTF8) :]
        report = self.stats.by_file.get(file_label)
        if report is None:
            report = self.stats.by_file[file_label] = FileReport(file=file_label)
            self.reader.report.files.append(report)
        # One file id per followed source: a rotation continues the same stream,
        # so a second split by the rotation is not two "overlapping exports".
        file_id = self._file_ids.setdefault(source, len(self._file_ids))
        while len(self.reader.registry.files) <= file_id:
            self.reader.registry.files.append(source)
        chunk = self.reader.parse_lines(data, report, file_id, first_line)
        self._show_rejections()
        self.pipeline.feed(chunk)
        self._show_clock_steps()

    def feed(self, chunk: DiagChunk) -> None:
        """Records already parsed (into the registry given), in read order: a replay of logs or the archive."""
        self.pipeline.feed(chunk)

    def _show_rejections(self) -> None:
        rej = self.reader.report.rejections
        for r in rej[self.stats.rejections_shown :]:
            self.emit({"type": "source", "kind": "rejected", **r.to_dict()})
        self.stats.rejections_shown = len(rej)

    def _show_clock_steps(self) -> None:
        """A head whose records went back in time in a followed file: told at once, the first per head and file."""
        steps = self.pipeline.clock_steps
        if len(steps.steps) == self.stats.clock_steps_shown:
            return
        names = [name for _, name in self.pipeline.heads]
        files = list(self.reader.registry.files)
        texts = steps.warnings(names, files)
        for step, text in zip(
            steps.steps[self.stats.clock_steps_shown :], texts[self.stats.clock_steps_shown :], strict=True
        ):
            self.emit(
                {
                    "type": "source",
                    "kind": "clock_step",
                    "source": files[step.file_id],
                    "file": files[step.file_id],
                    "line": step.line,
                    "counting_head": names[step.head_key],
                    "back_s": step.back_ns / NS,
                    "detail": text,
                }
            )
        self.stats.clock_steps_shown = len(steps.steps)

    def reset(self, section: str, t_ns: int) -> None:
        """An operator asks to reset ``section`` at ``t_ns``: decided in time order with the detections
        (told as a ``reset`` event, accepted or refused with the reason)."""
        self.pipeline.reset(DetectionEvent(t_ns, EventKind.RESET, section, source="operator"))

    def advance(self, until_ns: int) -> None:
        """Every record earlier than ``until_ns`` has been added (see :meth:`Pipeline.advance`)."""
        self.pipeline.advance(until_ns)

    def finish(self) -> None:
        """End of following: every open run is closed and analysed (as the batch reader ends a file)."""
        self.pipeline.finish(start_sections=False)

    @property
    def clock_ns(self) -> int | None:
        """The latest record time read (None: none yet)."""
        stream = self.pipeline.stream
        return stream.clock_ns if stream is not None and stream.clock_ns != NO_TIME else None

    @property
    def sections(self) -> Any:
        return self.pipeline.section_engine

    def section_states(self) -> dict[str, tuple[str, int]]:
        engine = self.pipeline.section_engine
        if engine is None:
            return {}
        return {sid: (str(s.state), s.count) for sid, s in engine.sections.items()}

    @property
    def status_passages(self) -> int:
        status = self.pipeline.status
        return int(status.passages.sum()) if status is not None else 0
