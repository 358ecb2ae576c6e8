"""One diagnostic file's one pass: parsed, its records written to parts, each chunk handed on as it is stored.

Every ingest reads a diagnostic file through :func:`parse_one_pass`: the
local ingest (its chunks fed to the line's pipeline), and on a cluster the
task that parses and derives one group of files
(:mod:`console.archive.group_ingest`, its chunks fed to the groups'
pipelines).  So the records stored, the rejected lines kept and the chunks
the pipeline sees are made by one piece of code on every engine.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from console.archive.day_rows import DayRows
from console.archive.parts import PartWriter
from console.archive.records import RecordEncoder
from parsers.report import ParseReport
from parsers.units import NS_PER_DAY

if TYPE_CHECKING:
    from parsers.diag.records import DiagChunk
    from parsers.diag.registry import DiagRegistry
    from parsers.report import Rejection

# Record parts keep the input's order (file, line; time order in an exported log): the order the derivation
# reads them in, no sort when they are written, and row groups that each span a stretch of time (a query for
# one hour skips the others by their statistics).
RECORD_ORDER = ("file_seq", "line")
# Rejected lines gathered before they go to the rejected table's writer (a few MB of rows at most).
REJECTED_BATCH_ROWS = 20_000


def rejected_row(r: Rejection, shown: str, file_seq: int, first_line: int, generation: int) -> dict[str, Any]:
    """A rejected line as a row of the archive's ``rejected`` table."""
    return {
        "file": shown,
        "file_seq": file_seq,
        "line": r.line + first_line,
        "reason": r.reason,
        "text": r.text,
        "generation": generation,
    }


@dataclass
class ParsedFile:
    """A diagnostic file parsed on a worker: the parts it wrote and its parse report."""

    records: list[str]
    rejected: list[str]
    report: ParseReport


class RejectedRows:
    """Rejected rows gathered and handed to their writer a batch at a time (a hostile file may reject millions)."""

    def __init__(self, writer: PartWriter) -> None:
        self.writer = writer
        self.rows: list[dict[str, Any]] = []

    def add(self, row: dict[str, Any]) -> None:
        self.rows.append(row)
        if len(self.rows) >= REJECTED_BATCH_ROWS:
            self.flush()

    def adder(self, shown: str, file_seq: int, first_line: int, generation: int) -> Callable[[Rejection], None]:
        """What a parser of this file calls with each rejected line."""
        return lambda r: self.add(rejected_row(r, shown, file_seq, first_line, generation))

    def flush(self) -> None:
        if self.rows:
            self.writer.add(pa.Table.from_pylist(self.rows))
            self.rows = []


def parse_one_pass(
    source: Path,
    shown: str,
    file_seq: int,
    first_line: int,
    records: PartWriter,
    reject: Callable[[Rejection], None],
    *,
    registry: DiagRegistry | None = None,
    on_chunk: Callable[[DiagChunk], None] | None = None,
    on_bytes: Callable[[int], None] | None = None,
    day_rows: DayRows | None = None,
) -> ParseReport:
    """Parse ``source`` (known as ``shown``, the archive's file ``file_seq``, its first line ``first_line`` + 1):
    each chunk's records to ``records``, then to ``on_chunk``; each rejected line to ``reject``.

    ``registry``: the one to parse into (a pipeline's, shared by the files of a read), else the reader's own.
    ``day_rows``: given each chunk's records too (the head_days figures of the read).
    """
    from parsers.diag.read import DiagReader

    reader = DiagReader([source], on_progress=on_bytes)
    reader.report.on_reject = reject
    if registry is not None:
        reader.registry = registry
    enc = RecordEncoder(reader.registry)
    for chunk in reader.chunks():
        # Buffered with each record's register number: the writer expands them (records.expand_records).
        table, device_id, registers = enc.encode_compact(chunk, shown, file_seq, first_line)
        records.add(table, chunk.time_ns // NS_PER_DAY, device_id, context=(enc.registry, registers))
        # Past days' files closed (at the chunk's median time: one damaged time does not move it).  The median
        # is no later than the chunk's latest time: only a chunk whose latest time would close a day is ranked.
        if len(chunk.time_ns) and records.closes_day(int(chunk.time_ns.max())):
            records.advance(int(np.median(chunk.time_ns)))
        if day_rows is not None:
            day_rows.add(enc.registry, chunk, file_seq, first_line)
        if on_chunk is not None:
            on_chunk(chunk)
    return reader.report
