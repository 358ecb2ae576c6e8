"""Compose parser and analysis for the faces: one call per job, no computing here."""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from console.analysis.diag_events import DiagEventSettings, diag_detection_events
from console.analysis.diagnostics import DiagAccumulator, DiagAnalysis, SpeedSettings
from console.analysis.events import DetectionEvent
from console.analysis.health import Finding, health_report
from console.layout import Layout, layout_from_heads
from parsers.diag import DiagChunk, DiagReader, chunks_to_frame
from parsers.report import ParseReport

HEALTH_REGISTERS = frozenset({"analog_value", "counter_1_edge"})


@dataclass
class DiagJob:
    files: list[str]
    report: ParseReport
    analysis: DiagAnalysis
    records: pd.DataFrame = field(default_factory=pd.DataFrame)  # only the kept registers


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
    acc = DiagAccumulator(reader.registry, keep_releases=keep_releases)
    kept: list[DiagChunk] = []
    for chunk in reader.chunks():
        acc.add(chunk)
        if keep_registers:
            regs = reader.registry.registers
            wanted = np.fromiter((r.label_canonical in keep_registers for r in regs), bool, len(regs))
            mask = wanted[chunk.register_id]
            if mask.any():
                kept.append(chunk.take(mask))
    analysis = acc.result(settings)
    records = chunks_to_frame(kept, reader.registry) if keep_registers else pd.DataFrame()
    return DiagJob(files=[str(p) for p in paths], report=reader.report, analysis=analysis, records=records)


def detection_events(
    job: DiagJob, layout: Layout | None, settings: DiagEventSettings
) -> tuple[list[DetectionEvent], list[str]]:
    """The log's detection events on the layout, or on its own heads when none is given."""
    lay = layout or layout_from_heads(sorted({name for _, name in job.analysis.heads}))
    return diag_detection_events(job.analysis, lay, settings)


def health_findings(
    job: DiagJob, layout: Layout | None, events: list[DetectionEvent], voltages: pd.DataFrame | None
) -> list[Finding]:
    bands = {h.id: h.analog_band for h in layout.heads if h.analog_band} if layout else None
    return health_report(job.records, bands=bands or None, events=events, voltages=voltages)
