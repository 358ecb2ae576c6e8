"""Compose parser and analysis for the faces: one call per job."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from console.analysis.diagnostics import DiagAccumulator, DiagAnalysis, SpeedSettings
from parsers.diag import DiagReader
from parsers.report import ParseReport


@dataclass
class DiagJob:
    files: list[str]
    report: ParseReport
    analysis: DiagAnalysis


def input_bytes(paths: Sequence[Path]) -> int:
    """Total on-disk size, for the progress bar (missing files count 0)."""
    return sum(p.stat().st_size for p in paths if p.is_file())


def analyze_files(
    paths: Sequence[Path],
    settings: SpeedSettings,
    on_progress: Callable[[int], None] | None = None,
) -> DiagJob:
    """Parse and analyse diagnostic logs in one streaming pass."""
    reader = DiagReader(paths, on_progress=on_progress)
    acc = DiagAccumulator(reader.registry)
    for chunk in reader.chunks():
        acc.add(chunk)
    analysis = acc.result(settings)
    return DiagJob(files=[str(p) for p in paths], report=reader.report, analysis=analysis)
