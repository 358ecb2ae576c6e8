"""Compose parser and analysis for the faces: one call per job, no computing here."""

from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.diagnostics import DiagAccumulator, DiagAnalysis, SpeedSettings
from parsers.diag import DiagChunk, DiagReader, chunks_to_frame
from parsers.report import ParseReport

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
    # One file cannot overlap another: no per-record fingerprints kept then.
    acc = DiagAccumulator(reader.registry, keep_releases=keep_releases, track_overlap=len(paths) > 1)
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
    for file_report, overlap in zip(reader.report.files, analysis.overlap_by_file, strict=False):
        file_report.overlap_records = overlap
    records = chunks_to_frame(kept, reader.registry) if keep_registers else None
    return DiagJob(files=[str(p) for p in paths], report=reader.report, analysis=analysis, kept_records=records)


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
