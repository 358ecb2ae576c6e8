"""Batch: read log files → the pipeline → sinks, in memory bounded by the heads and open passages.

Every batch command (``analyze``, ``speeds``, ``sections``, ``health``,
``approach``, ``report``) reads diagnostic logs through :func:`read_diag`;
what differs is what the pipeline is asked to compute
(:class:`~console.engine.pipeline.PipelineSettings`) and which sinks take
the results.

A read is repeated, from the start, in two rare cases a file allows (a
stream such as standard input does not: a warning says so):

* a head fact the pipeline guessed from a head's first passage was wrong
  (:attr:`Pipeline.facts_wrong`): read again with the facts now known; the
  passages are the same, so only the section history is taken again;
* records came later than their passage's close (a log out of time order
  by more than the pipeline's slack): read again whole, so passages are
  those of the files read together.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.diag_events import HELD
from console.analysis.passages.buckets import Columns
from console.analysis.passages.diag_analysis import DiagAnalysis
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.status import StatusSummary
from console.analysis.passages.stream import ORDER_SLACK_S, by_head_and_start, concat_passages, take_passages
from console.engine.pipeline import DiagOutcome, Pipeline, PipelineSettings
from console.engine.sinks import Sink, Sinks
from console.memory import read_memory
from console.plural import count
from console.safe_text import clean, show_path
from parsers.diag.read import DiagReader, compiled_tokenizer
from parsers.diag.records import DiagChunk, chunks_to_frame
from parsers.diag.registry import DiagRegistry
from parsers.report import ParseReport
from parsers.sources import DEFAULT_CHUNK_BYTES

if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.events.detection import DetectionEvent
    from console.analysis.head_table import Heads
    from console.analysis.health.findings import Finding
    from console.analysis.sections.engine import SectionEngine
    from console.layout import Layout

STDIN = "-"
# A read of regular files closes passages every 4 chunks (fewer where runs are many: see PassageStream.add) rather
# than after each, and analyses them aside: fewer, larger analysis calls, off the reading thread; the same
# passages.  A pipe, standard input or a live source closes after every chunk: a reader waiting on it sees each
# passage as soon as it is whole.
FILE_CLOSE_EVERY_CHUNKS = 4


@dataclass
class DiagJob:
    """One batch read of diagnostic logs: what the faces show besides what the sinks took."""

    files: list[str]
    report: ParseReport
    analysis: DiagAnalysis
    kept_records: pd.DataFrame | None = None
    # What the pipeline knew at the end (None: a job made of stored rows, the archive's history).
    outcome: DiagOutcome | None = None
    reads: int = 1  # 2: read again (a guessed head fact was wrong, or the log is out of time order)
    registry: DiagRegistry | None = None

    @property
    def status(self) -> StatusSummary | None:
        return self.outcome.status if self.outcome is not None else None

    @property
    def passage_count(self) -> int:
        if self.outcome is not None:
            return self.outcome.passages
        cols = self.analysis.passage_columns
        return len(cols["head"]) if cols is not None else 0

    @property
    def late_records(self) -> int:
        """Records that came after their passage had closed, in the first (streamed) read."""
        return self.late_first if self.late_first is not None else self.outcome.late_records if self.outcome else 0

    late_first: int | None = None

    @property
    def warnings(self) -> list[str]:
        return self.outcome.warnings if self.outcome is not None else []

    @property
    def clock_step_warnings(self) -> list[str]:
        """A line per head and file whose records go back in time (said on stderr as the read ends)."""
        if self.outcome is None or not self.outcome.clock_steps.steps:
            return []
        heads = [clean(name) for _, name in self.outcome.heads]
        return self.outcome.clock_steps.warnings(heads, [show_path(f) for f in self.files])

    @property
    def sections(self) -> SectionEngine | None:
        """The section engine at the end (its final states), when the read ran one."""
        return self.outcome.sections if self.outcome is not None else None

    @property
    def last_event(self) -> DetectionEvent | None:
        """The last detection event but operator resets (where the data ends)."""
        return self.outcome.last_event if self.outcome is not None else None

    @property
    def findings(self) -> list[Finding]:
        """The health findings the pipeline judged (settings.health)."""
        return self.outcome.findings if self.outcome is not None else []

    @property
    def health_events(self) -> list[DetectionEvent]:
        return self.outcome.health_events if self.outcome is not None else []

    @property
    def kept_nothing(self) -> bool:
        """Whether no record was kept: known without making the table (none: no pandas needed for it)."""
        if self.kept_records is not None:
            return len(self.kept_records) == 0
        return self.outcome is None or not self.registry or not any(len(c) for c in self.outcome.kept)

    @property
    def records(self) -> pd.DataFrame:
        """The kept registers' records (an empty table when none were kept)."""
        if self.kept_records is None:
            import pandas as pd

            kept = self.outcome.kept if self.outcome is not None else []
            self.kept_records = (
                chunks_to_frame(kept, self.registry, all_heads=False) if self.registry else pd.DataFrame()
            )
        return self.kept_records


class PassageTable(Sink):
    """Every passage held, as the whole table (by head, then start): for faces that need it all."""

    def __init__(self) -> None:
        self.parts: list[Columns] = []
        self.axle_parts: list[Columns] = []

    def passages(self, cols: Columns, heads: Heads) -> None:
        self.parts.append(cols)

    def axles(self, cols: Columns, heads: Heads) -> None:
        self.axle_parts.append(cols)

    def restart(self, passages: bool) -> None:
        if passages:
            self.parts, self.axle_parts = [], []

    def columns(self) -> Columns | None:
        cols = concat_passages(self.parts)
        return take_passages(cols, by_head_and_start(cols)) if cols is not None else None

    def axle_columns(self) -> Columns:
        if not self.axle_parts:
            return no_axles()
        out = {c: np.concatenate([a[c] for a in self.axle_parts]) for c in self.axle_parts[0]}
        return {c: v[np.lexsort((out["time_ns"], out["head"]))] for c, v in out.items()} if len(out["head"]) else out


def no_axles() -> Columns:
    from console.analysis.counting.wheels import PairingSettings, pair_axle_arrays

    empty = np.zeros(0, np.int64)
    axles, _ = pair_axle_arrays(
        {"head": empty, "channel": empty, "time_ns": empty, "subsecond": np.zeros(0, bool)}, PairingSettings()
    )
    return axles


def input_bytes(paths: Sequence[Path]) -> int:
    """Total on-disk size, for the progress bar (missing files count 0)."""
    return sum(p.stat().st_size for p in paths if p.is_file())


@dataclass
class ReadOptions:
    """How the input is read (not what is computed)."""

    on_progress: Callable[[int], None] | None = None
    on_records: Callable[[int], None] | None = None
    chunk_bytes: int = DEFAULT_CHUNK_BYTES
    max_rejections_kept: int | None = None
    on_reject: Callable[..., None] | None = None
    whole: bool = False  # read every file together (passages close at the end)
    # Sinks that wrote passages where they cannot be taken back (stdout): no whole re-read then.
    passages_final: bool = False
    hold_passages: bool = False  # the job's analysis holds the passages table (PassageTable)


class ChunkSource:
    """Where a batch read's chunks come from; :meth:`open` starts a read (again) from the beginning."""

    files: list[str]
    several: bool = False  # several files read together: their overlap is found (whole mode)
    rereadable: bool = True

    def open(self, opts: ReadOptions) -> tuple[DiagRegistry, Iterator[DiagChunk], ParseReport]:
        raise NotImplementedError


class LogFiles(ChunkSource):
    """Diagnostic log files, parsed as they are read."""

    def __init__(self, paths: Sequence[Path]) -> None:
        self.paths = list(paths)
        self.files = [str(p) for p in paths]
        self.several = len(paths) > 1
        self.rereadable = all(os.fsdecode(p) != STDIN and os.path.isfile(p) for p in paths)

    def open(self, opts: ReadOptions) -> tuple[DiagRegistry, Iterator[DiagChunk], ParseReport]:
        reader = DiagReader(self.paths, on_progress=opts.on_progress, chunk_bytes=opts.chunk_bytes)
        if opts.max_rejections_kept is not None:
            reader.report.max_rejections_kept = opts.max_rejections_kept
        reader.report.on_reject = opts.on_reject
        return reader.registry, reader.chunks(), reader.report


def read_diag(
    paths: Sequence[Path] | ChunkSource,
    settings: PipelineSettings,
    sink: Sink | None = None,
    opts: ReadOptions | None = None,
) -> DiagJob:
    """Read diagnostic records (log files, or another source) through the pipeline; results to ``sink``
    as they are made."""
    source = paths if isinstance(paths, ChunkSource) else LogFiles(paths)
    o = opts or ReadOptions()
    table = PassageTable() if o.hold_passages else None
    sinks = Sinks(sink, table) if table is not None else (sink or Sink())
    # Log files read by the compiled tokenizer need no Arrow; another source (stored records) may.
    with read_memory(arrow=not (isinstance(source, LogFiles) and compiled_tokenizer())):
        whole = o.whole or source.several
        job = _read(source, settings, sinks, o, whole, None, passages=True)
        if not whole and job.late_records and not o.passages_final and source.rereadable:
            # Nothing written that cannot be taken back: read the file again, whole, as several files are.
            sinks.restart(passages=True)
            late = job.late_records
            job = _read(source, settings, sinks, o, True, None, passages=True)
            job.reads, job.late_first = 2, late
        elif not whole and job.late_records:
            sys.stderr.write(
                f"trackside: warning: {count(job.late_records, 'record')} came after their passage had closed"
                f" (the log is out of time order by more than {ORDER_SLACK_S:g} s); passages near them may be split"
                " or differ from a whole read: --json on the file reads it whole\n"
            )
    _tell_clock_steps(job.clock_step_warnings)
    # A section held for a head not heard: said where the clock steps are, whatever the output; not for a log
    # of no record at all (every head unheard), which the command refuses in one line of its own.
    for line in job.warnings if job.report.records else ():
        if HELD in line:
            sys.stderr.write(f"trackside: warning: {line}\n")
    if table is not None:
        job.analysis.passage_columns = table.columns()
        job.analysis.axle_columns = table.axle_columns()
    return job


def _tell_clock_steps(lines: list[str]) -> None:
    """A line on stderr per head and file whose records go back in time (up to 5; then how many more)."""
    for line in lines[:5]:
        sys.stderr.write(f"trackside: warning: {line}\n")
    if len(lines) > 5:
        more = count(len(lines) - 5, "more head")
        sys.stderr.write(f"trackside: warning: and {more} whose records go back in time\n")


def _read(
    source: ChunkSource,
    settings: PipelineSettings,
    sink: Sink,
    o: ReadOptions,
    whole: bool,
    facts: dict | None,
    passages: bool,
) -> DiagJob:
    registry, chunks, report = source.open(o)
    pipeline = Pipeline(
        registry,
        settings,
        sink if passages else _HistoryOnly(sink),
        whole=whole,
        facts=facts,
        close_every_chunks=FILE_CLOSE_EVERY_CHUNKS if source.rereadable else 1,
    )
    for chunk in chunks:
        if o.on_records is not None:
            o.on_records(len(chunk))
        pipeline.feed(chunk)
    outcome = pipeline.finish()
    if pipeline.facts_wrong and source.rereadable:
        # The passages are those of the first read (facts change events only): the history is taken again.
        sink.restart(passages=False)
        again = ReadOptions(chunk_bytes=o.chunk_bytes, max_rejections_kept=o.max_rejections_kept)
        job = _read(source, settings, sink, again, whole, pipeline.facts, passages=False)
        job.reads = 2
        return job
    return _job(source.files, report, registry, settings.speed, outcome)


def _job(
    files: list[str], report: ParseReport, registry: DiagRegistry, speed: SpeedSettings, outcome: DiagOutcome
) -> DiagJob:
    for file_report, overlap in zip(report.files, outcome.overlap_by_file, strict=False):
        file_report.overlap_records = overlap
    by_file = outcome.overlap_by_file or [0] * len(report.files)
    analysis = DiagAnalysis(
        settings=speed,
        devices=outcome.devices,
        passage_columns=None,
        axle_columns=no_axles(),
        overlap_records=sum(by_file),
        unpaired_detections=outcome.unpaired_detections,
        overlap_by_file=list(by_file),
        heads=outcome.heads,
        overlap_times_ns=outcome.overlap_times_ns,
    )
    return DiagJob(files, report, analysis, outcome=outcome, registry=registry)


class _HistoryOnly(Sinks):
    """A second read's results, but for the passages and axles the first read already handed on."""

    def passages(self, cols: Columns, heads: Heads) -> None:
        return None

    def axles(self, cols: Columns, heads: Heads) -> None:
        return None


def health_findings(
    job: DiagJob,
    layout: Layout | None,
    events: list[DetectionEvent] | None = None,
    voltages: pd.DataFrame | None = None,
) -> list[Finding]:
    """Health findings of a read that kept the health registers and channel events (``events``: these)."""
    from console.analysis.health.rules import health_report

    bands = {h.id: h.analog_band for h in layout.heads if h.analog_band} if layout else None
    evs = job.health_events if events is None else events
    records = None if job.kept_nothing else job.records
    return health_report(records, bands=bands or None, events=evs, voltages=voltages)
