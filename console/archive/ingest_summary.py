"""What an ingest says of itself: each file's outcome, the summary (``ingest --json``) and its steps' times."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass
class FileOutcome:
    path: str
    kind: str
    action: str  # new, grown, replace, skip, not-read
    note: str
    records: int = 0
    rejected: int = 0
    bytes_read: int = 0
    # Bytes after the last line end, not read yet: an unfinished line (a log still being written), read
    # once the file grows; or a file whose lines end in CR alone, which the archive does not take.
    held_back_bytes: int = 0


@dataclass
class IngestSummary:
    archive: Path
    generation: int
    files: list[FileOutcome] = field(default_factory=list)
    seconds: float = 0.0
    published: bool = False
    # Wall seconds per step: read (parse and write the inputs), records (close, compact), derive, publish.
    phases: dict[str, float] = field(default_factory=dict)
    # Each step's end: (wall ``perf_counter``, this process's ``process_time``), for benchmarks/bench_fleet.py.
    phase_ends: dict[str, tuple[float, float]] = field(default_factory=dict)
    # What the inputs held but the ingest did not read, and why (a directory's dangling links, FIFOs, hidden
    # entries; a file given twice): the report's words (console.inputs.recognise.expand).
    warnings: list[str] = field(default_factory=list)

    @property
    def records(self) -> int:
        return sum(f.records for f in self.files)

    @property
    def rejected(self) -> int:
        return sum(f.rejected for f in self.files)

    @property
    def added(self) -> list[FileOutcome]:
        return [f for f in self.files if f.action in ("new", "grown", "replace")]

    @property
    def skipped(self) -> list[FileOutcome]:
        return [f for f in self.files if f.action in ("skip", "not-read")]

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": "trackside.ingest/1",
            "archive": str(self.archive),
            "generation": self.generation,
            "published": self.published,
            "records": self.records,
            "rejected": self.rejected,
            "seconds": round(self.seconds, 3),
            "phase_seconds": {k: round(v, 3) for k, v in self.phases.items()},
            "warnings": self.warnings,
            "files": [f.__dict__ for f in self.files],
        }


class PhaseClock:
    """Wall seconds of consecutive steps, into ``phases`` (the summary's, also in ``ingest --json``), and when
    each ended, into ``ends``."""

    def __init__(self, phases: dict[str, float], ends: dict[str, tuple[float, float]]) -> None:
        self.phases, self.ends = phases, ends
        self.t = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.phases[name] = self.phases.get(name, 0.0) + now - self.t
        self.ends[name] = (now, time.process_time())
        self.t = now
