"""Compose parser and analysis for the faces: one call per job, no computing here."""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.diagnostics import DiagAccumulator, DiagAnalysis, PartAnalysis, SpeedSettings
from console.analysis.head_table import Heads
from console.analysis.passages import Columns
from console.analysis.status import StatusSummary
from console.analysis.stream import PassageStream, by_head_and_start, by_start, concat_passages, take_passages
from parsers.diag import DiagChunk, DiagReader, chunks_to_frame
from parsers.report import ParseReport
from parsers.sources import DEFAULT_CHUNK_BYTES

# Imported where used: `analyze --json` needs neither pandas nor the event
# and health modules.
if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.events import DetectionEvent
    from console.analysis.health import Finding
    from console.layout import Layout

HEALTH_REGISTERS = frozenset({"analog_value", "counter_1_edge"})


@dataclass
class DiagJob:
    files: list[str]
    report: ParseReport
    analysis: DiagAnalysis
    kept_records: pd.DataFrame | None = None  # only the kept registers
    # Passages with status records only, counted per head (None: they are in the passages table).
    status: StatusSummary | None = None
    # Passages listed, when the job does not hold them (streamed: see stream_files).
    passage_count: int | None = None
    # Records later than their passage's close (a log out of time order): see PassageStream.
    late_records: int = 0

    @property
    def records(self) -> pd.DataFrame:
        """The kept registers' records (an empty table when none were kept)."""
        if self.kept_records is None:
            import pandas as pd

            self.kept_records = pd.DataFrame()
        return self.kept_records


def input_bytes(paths: Sequence[Path]) -> int:
    """Total on-disk size, for the progress bar (missing files count 0)."""
    return sum(p.stat().st_size for p in paths if p.is_file())


def analyze_files(
    paths: Sequence[Path],
    settings: SpeedSettings,
    on_progress: Callable[[int], None] | None = None,
    keep_registers: Collection[str] = (),
    keep_releases: bool = False,
) -> DiagJob:
    """Parse and analyse diagnostic logs in one streaming pass.

    ``keep_registers`` (canonical label names) are also kept as a record
    table, e.g. the analog values and 1-edge counters health needs; nothing
    else is held in memory.
    """
    reader = DiagReader(paths, on_progress=on_progress)
    return _read_whole(reader, paths, settings, keep_registers, keep_releases)


def _read_whole(
    reader: DiagReader,
    paths: Sequence[Path],
    settings: SpeedSettings,
    keep_registers: Collection[str] = (),
    keep_releases: bool = False,
    on_records: Callable[[int], None] | None = None,
) -> DiagJob:
    # One file cannot overlap another: no per-record fingerprints kept then.
    acc = DiagAccumulator(reader.registry, keep_releases=keep_releases, track_overlap=len(paths) > 1)
    kept: list[DiagChunk] = []
    for chunk in reader.chunks():
        acc.add(chunk)
        if on_records is not None:
            on_records(len(chunk))
        if keep_registers:
            mask = reader.registry.canonical_in(keep_registers)[chunk.register_id]
            if mask.any():
                kept.append(chunk.take(mask))
    analysis = acc.result(settings)
    for file_report, overlap in zip(reader.report.files, analysis.overlap_by_file, strict=False):
        file_report.overlap_records = overlap
    records = chunks_to_frame(kept, reader.registry) if keep_registers else None
    return DiagJob(files=[str(p) for p in paths], report=reader.report, analysis=analysis, kept_records=records)


# A batch of closed passages (columns of diagnostics._passages, by start time) and the head list.
OnPassages = Callable[[Columns, Heads], None]


def stream_files(
    paths: Sequence[Path],
    settings: SpeedSettings,
    on_progress: Callable[[int], None] | None = None,
    on_passages: OnPassages | None = None,
    include_status: bool = True,
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    max_rejections_kept: int | None = None,
    on_reject: Callable[..., None] | None = None,
    on_records: Callable[[int], None] | None = None,
    hold_passages: bool = True,
    keep_axles: bool = True,
    whole: bool = False,
) -> DiagJob:
    """:func:`analyze_files` in memory bounded by the heads and open passages, for one log.

    Passages are handed to ``on_passages`` as they close; the job's
    passages table (by head, then start, as a whole-file read orders it)
    holds one row per passage, no records.  Without ``include_status``,
    status-only passages are counted per head instead of kept.
    ``on_records`` is told how many records each chunk held (progress).
    Without ``hold_passages`` the job holds no passages (``on_passages``
    had them all: memory stays bounded however many there are), only their
    count; without ``keep_axles``, no axles table.  ``whole``: read the log
    whole instead (as several files are), for a log out of time order.
    """
    reader = DiagReader(paths, on_progress=on_progress, chunk_bytes=chunk_bytes)
    if max_rejections_kept is not None:
        reader.report.max_rejections_kept = max_rejections_kept
    reader.report.on_reject = on_reject
    status = None if include_status else StatusSummary()
    if len(paths) > 1 or whole:
        # Several files may overlap (the same export pulled twice): that is found by
        # comparing the files' records, so they are read whole, as analyze_files does.
        job = _read_whole(reader, paths, settings, on_records=on_records)
        cols = job.analysis.passage_columns
        if cols is not None:
            if status is not None:
                cols = job.analysis.passage_columns = status.take(cols)
            if on_passages is not None and len(cols["head"]):
                on_passages(take_passages(cols, by_start(cols)), job.analysis.heads)
        job.status = status
        job.passage_count = len(cols["head"]) if cols is not None else 0
        return job
    stream = PassageStream(reader.registry, settings)
    kept: list[Columns] = []
    axles: list[Columns] = []
    count = 0

    def closed(part: PartAnalysis | None) -> None:
        if part is None or part.passages is None:
            return
        cols = take_passages(part.passages, by_start(part.passages))
        if status is not None:
            cols = status.take(cols)
        if keep_axles:
            axles.append(part.axles)
        nonlocal count
        count += len(cols["head"])
        if len(cols["head"]):
            if hold_passages:
                kept.append(cols)
            if on_passages is not None:
                on_passages(cols, stream.heads)

    for chunk in reader.chunks():
        if on_records is not None:
            on_records(len(chunk))
        closed(stream.add(chunk))
    closed(stream.finish())
    cols = concat_passages(kept)
    cols = take_passages(cols, by_head_and_start(cols)) if cols is not None else None
    axle_cols = {c: np.concatenate([a[c] for a in axles]) for c in axles[0]} if axles else _no_axles()
    analysis = DiagAnalysis(
        settings=settings,
        devices=stream.acc.devices(),
        passage_columns=cols,
        axle_columns=axle_cols,
        overlap_records=0,
        unpaired_detections=stream.unpaired_detections,
        overlap_by_file=[0] * len(reader.report.files),
        heads=stream.heads,
    )
    return DiagJob(
        files=[str(p) for p in paths],
        report=reader.report,
        analysis=analysis,
        status=status,
        passage_count=count,
        late_records=stream.late_records,
    )


def status_json(status: StatusSummary, heads: Heads) -> dict[str, object]:
    """``status_passages`` of a JSON document: the rows per head encoded as they are written."""
    from console.jsonout import array_parts

    return {**status.totals(), "by_head": array_parts(status.by_head(heads))}


def summarise_status(job: DiagJob) -> None:
    """Count a whole read's status-only passages per head instead of listing them."""
    job.status = StatusSummary()
    cols = job.analysis.passage_columns
    if cols is not None:
        job.analysis.passage_columns = job.status.take(cols)
        job.analysis.__dict__.pop("passages", None)  # the cached table, if built


def summary_doc(job: DiagJob, schema: str) -> dict[str, object]:
    """The ``summary`` line of ``--jsonl``: what the JSON document holds besides passages and devices."""
    from console import __version__

    a, s = job.analysis, job.analysis.settings
    cols = a.passage_columns
    report = job.report.to_dict()
    report.pop("rejections")  # listed as lines of their own
    return {
        "schema": schema,
        "trackside_version": __version__,
        "files": job.files,
        "settings": {
            "spacing_m": s.spacing_m,
            "train_length_m": s.train_length_m,
            "idle_gap_s": s.idle_gap_s,
            "pair_window_s": s.pair_window_s,
        },
        "passages": job.passage_count if job.passage_count is not None else (len(cols["head"]) if cols else 0),
        **({"status_passages": status_json(job.status, a.heads)} if job.status is not None else {}),
        "overlap_records": a.overlap_records,
        "unpaired_detections": a.unpaired_detections,
        "parse_report": report,
        **({"late_records": job.late_records} if job.late_records else {}),
    }


def _no_axles() -> Columns:
    from console.analysis.wheels import PairingSettings, pair_axle_arrays

    empty = np.zeros(0, np.int64)
    axles, _ = pair_axle_arrays(
        {"head": empty, "channel": empty, "time_ns": empty, "subsecond": np.zeros(0, bool)}, PairingSettings()
    )
    return axles


def detection_events(
    job: DiagJob, layout: Layout | None, settings: DiagEventSettings
) -> tuple[list[DetectionEvent], list[str]]:
    """The log's detection events on the layout, or on its own heads when none is given."""
    from console.analysis.diag_events import diag_detection_events
    from console.layout import layout_from_heads

    lay = layout or layout_from_heads(sorted({name for _, name in job.analysis.heads}))
    return diag_detection_events(job.analysis, lay, settings)


def health_findings(
    job: DiagJob, layout: Layout | None, events: list[DetectionEvent], voltages: pd.DataFrame | None
) -> list[Finding]:
    from console.analysis.health import health_report

    bands = {h.id: h.analog_band for h in layout.heads if h.analog_band} if layout else None
    return health_report(job.records, bands=bands or None, events=events, voltages=voltages)
