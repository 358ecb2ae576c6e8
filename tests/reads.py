"""Reading logs in tests: the whole-file reference and the pipeline, side by side.

``whole_job`` is the reference: every chunk into one
:class:`~console.analysis.passages.accumulator.DiagAccumulator`, analysed once at the
end, as the analysis has always been defined.  ``stream_job`` is the
pipeline (:func:`console.drivers.batch.read_diag`) reading in chunks, with
the passages and axles held as tables so the two can be compared.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

from console.analysis.diag_events import DiagEventSettings, diag_detection_events
from console.analysis.events.detection import DetectionEvent
from console.analysis.passages.accumulator import DiagAccumulator
from console.analysis.passages.speed_settings import SpeedSettings
from console.drivers.batch import DiagJob, ReadOptions, read_diag
from console.engine.pipeline import PipelineSettings
from console.engine.sinks import Sink
from console.layout import Layout, layout_from_heads
from parsers.diag.read import DiagReader
from parsers.diag.records import chunks_to_frame


def whole_job(
    paths: Sequence[Path],
    settings: SpeedSettings = SpeedSettings(),  # noqa: B008 (frozen)
    keep_registers: Collection[str] = (),
    keep_releases: bool = False,
) -> DiagJob:
    """Every record read, then analysed together (the reference the pipeline is held to)."""
    reader = DiagReader(paths)
    acc = DiagAccumulator(reader.registry, keep_releases=keep_releases, track_overlap=len(paths) > 1)
    kept = []
    for chunk in reader.chunks():
        acc.add(chunk)
        if keep_registers:
            mask = reader.registry.canonical_in(keep_registers)[chunk.register_id]
            if mask.any():
                kept.append(chunk.take(mask))
    analysis = acc.result(settings)
    for file_report, overlap in zip(reader.report.files, analysis.overlap_by_file, strict=False):
        file_report.overlap_records = overlap
    records = chunks_to_frame(kept, reader.registry) if keep_registers else None
    return DiagJob([str(p) for p in paths], reader.report, analysis, kept_records=records)


def stream_job(
    paths: Sequence[Path],
    settings: SpeedSettings = SpeedSettings(),  # noqa: B008 (frozen)
    *,
    chunk_bytes: int | None = None,
    include_status: bool = True,
    sink: Sink | None = None,
    whole: bool = False,
    hold: bool = True,
) -> DiagJob:
    """The pipeline's read in chunks, passages and axles held as tables (``hold``)."""
    opts = ReadOptions(whole=whole, hold_passages=hold)
    if chunk_bytes is not None:
        opts.chunk_bytes = chunk_bytes
    return read_diag(paths, PipelineSettings(speed=settings, include_status=include_status, axles=hold), sink, opts)


def detection_events(
    job: DiagJob, layout: Layout | None, settings: DiagEventSettings
) -> tuple[list[DetectionEvent], list[str]]:
    """The whole read's detection events on the layout, or on the log's own heads when none is given."""
    lay = layout or layout_from_heads(sorted({name for _, name in job.analysis.heads}))
    return diag_detection_events(job.analysis, lay, settings)


def pipeline_sections(
    paths: Sequence[Path],
    speed: SpeedSettings,
    *,
    layout: Layout | None,
    event_settings: DiagEventSettings,
    sections_layout: Layout | None = None,
    resets: Sequence[DetectionEvent] = (),
    sink: Sink | None = None,
    keep_registers: Collection[str] = (),
    chunk_bytes: int | None = None,
    **settings: Any,
) -> DiagJob:
    """The pipeline's read with detection events (and sections, health registers) as a command asks."""
    pipe = PipelineSettings(
        speed=speed,
        events=event_settings,
        layout=layout,
        sections=sections_layout,
        resets=tuple(resets),
        keep_registers=frozenset(keep_registers),
        **settings,
    )
    opts = ReadOptions()
    if chunk_bytes is not None:
        opts.chunk_bytes = chunk_bytes
    return read_diag(paths, pipe, sink, opts)
