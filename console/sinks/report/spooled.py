"""The report's long lists kept on disk as the log is read: passages and the section history.

A report on a diagnostic log lists every passage and, in JSON, every state
change and every counted axle: ten times more at 30 M records than at 3 M.
They are not held.  Passages go into the :class:`~console.sinks.tables.passage_spool.PassageSpool`
that ``analyze --json`` uses (:class:`ReportPassages`), the section history
into the :class:`~console.sinks.tables.section_history.SectionsSink` spill that ``sections --json``
uses, its rows already in the report's JSON form (:func:`report_sink`,
:class:`SectionHistory`).  What stays in memory is a few numbers per state
change (the state plot) and totals; the numbers the speed plot reads of each
passage go into the spool's records on disk with its place.

The document (:func:`console.sinks.report.document.document`) refers to these
through :class:`~console.sinks.report.jsonwrite.Rows`; the renderers read them
one item at a time.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.head_table import Heads
from console.analysis.passages.buckets import Columns
from console.analysis.passages.status import STATUS_KIND
from console.analysis.passages.stream import take_passages
from console.analysis.sections.state import ResetRecord, Transition
from console.analysis.timefmt import iso
from console.engine.sinks import Sink
from console.jsonout import valid_unicode
from console.sinks.report.jsonwrite import Rows, Write, indented
from console.sinks.tables.passage_spool import PassageSpool
from console.sinks.tables.section_history import LedgerText, SectionsSink

if TYPE_CHECKING:
    import pandas as pd

TRAIN_KIND = 0  # passage_frame.PASSAGE_KINDS.index("train")
# Where the document holds the section history's rows: doc → "sections" → "timeline" / "ledger" → a row.
ROW_DEPTH = 3
# What the speed plot reads of a passage besides its head and start, as the spool keeps it.
_PLOTTED = (
    ("speed_kmh_whole_train", "<f8"),
    ("speed_kmh_per_axle_mean", "<f8"),
    ("axles", "<i4"),
    ("kind", "i1"),
)


class ReportPassages(Sink):
    """The passages a report lists, spooled as they close (status-only ones counted, not listed);
    with ``plot``, the spool keeps what the speed plot reads of each one too (on disk, 21 bytes)."""

    def __init__(self, plot: bool = True) -> None:
        self.spool = PassageSpool(columns=_PLOTTED if plot else ())
        self.plot = plot
        self.status = 0
        self.heads: Heads = []

    def passages(self, cols: Columns, heads: Heads) -> None:
        """One batch of closed passages (``heads``: the log's heads so far, by key)."""
        status = cols["kind"] == STATUS_KIND
        self.status += int(status.sum())
        self.spool.passages(take_passages(cols, np.flatnonzero(~status)) if status.any() else cols, heads)
        self.heads = heads  # the latest heads: they grow as heads appear, keys stay

    def restart(self, passages: bool) -> None:
        if passages:
            self.spool.restart(passages)
            self.status = 0

    def __len__(self) -> int:
        return self.spool.count

    def rows(self) -> Rows:
        """The listed passages as the document's JSON objects, by head then start (as ``analyze --json``)."""
        return Rows(self.spool.count, lambda: (json.loads(t) for t in self.spool.texts()))

    def trains(self) -> Columns:
        """The train passages' head key, start, speeds and axles, in the order they closed (read from disk)."""
        if not self.plot:
            raise RuntimeError("the speed plot's numbers were not kept (collected for a format without plots)")
        train = np.flatnonzero(self.spool.columns(("kind",))["kind"] == TRAIN_KIND)
        return self.spool.columns(("head", "start_ns", *(name for name, _ in _PLOTTED if name != "kind")), train)

    def close(self) -> None:
        self.spool.close()


def _transition_text(t: Transition) -> str:
    """A state change as the report's JSON lists it (a timeline row: ``sections_json``'s keys)."""
    row = {"section": t.section, "state": str(t.state), "count": t.count, "reason": t.reason, "time": iso(t.time_ns)}
    return "\n" + " " * ROW_DEPTH + valid_unicode(indented(row, ROW_DEPTH))


def report_sink(ledger_rows: bool) -> SectionsSink:
    """A sink that spills the history in the report's JSON form; the ledger's rows only when they are listed."""
    return SectionsSink(
        spill=True, spill_ledger=ledger_rows, timeline_text=_transition_text, ledger_text=LedgerText(ROW_DEPTH)
    )


class SpilledRows(Rows):
    """Rows spilled in the report's JSON form: copied as they are where the document holds them."""

    def __init__(self, count: int, make: Callable[[], Iterator[Any]], blocks: Callable[[], Iterator[str]]) -> None:
        super().__init__(count, make)
        self._blocks = blocks

    def write_json(self, write: Write, depth: int) -> None:
        if depth != ROW_DEPTH - 1 or not self.count:
            super().write_json(write, depth)
            return
        write("[")
        for block in self._blocks():
            write(block)
        write("\n" + " " * depth + "]")


class LedgerFrameRows(Rows):
    """A count ledger held as a table (the archive's, a whole read's): its JSON written row by row in the
    form the spill holds (:class:`~console.stream_jobs.LedgerText`), not a dict per axle through json."""

    COLUMNS = ("time_ns", "section", "head", "delta", "count")

    def __init__(self, ledger: pd.DataFrame) -> None:
        super().__init__(len(ledger), self._items)
        self.ledger = ledger

    def _entries(self) -> Iterator[Any]:
        from console.analysis.sections.state import LedgerEntry

        columns = [self.ledger[c].tolist() for c in self.COLUMNS]
        return (LedgerEntry(t, s, h, d, c) for t, s, h, d, c in zip(*columns, strict=True))

    def _items(self) -> Iterator[Any]:
        for x in self._entries():
            yield {"section": x.section, "head": x.head, "delta": x.delta, "count": x.count, "time": iso(x.time_ns)}

    def write_json(self, write: Write, depth: int) -> None:
        if depth != ROW_DEPTH - 1 or not self.count:
            super().write_json(write, depth)
            return
        text = LedgerText(ROW_DEPTH)
        write("[")
        first = True
        for x in self._entries():
            write(("" if first else ",") + text(x))
            first = False
        write("\n" + " " * depth + "]")


class PassageFrameRows(Rows):
    """Passages held as a table (the archive's, a whole read's): the same objects as ``analyze --json``'s,
    their JSON written from the columns by the byte encoder
    (:func:`~console.analysis.passages.json_text.indented_objects`), not a dict per passage decoded and encoded
    again; through the dicts where the encoder does not cover a value."""

    def __init__(self, passages: pd.DataFrame) -> None:
        super().__init__(len(passages), self._items)
        self.passages = passages

    def _items(self) -> Iterator[Any]:
        from console.analysis.passages.frame_json import passages_json_text

        return iter(json.loads(passages_json_text(self.passages)))

    def write_json(self, write: Write, depth: int) -> None:
        from console.analysis.passages.json_text import indented_objects
        from console.analysis.passages.passage_frame import frame_columns

        found = frame_columns(self.passages) if self.count else None
        blobs = indented_objects(*found, depth) if found is not None else None
        if blobs is None:
            super().write_json(write, depth)
            return
        write("[")
        for blob in blobs:
            write(blob.decode("ascii"))
        write("\n" + " " * depth + "]")


class PassageColumnRows(Rows):
    """Passages held as the pipeline's columns (an archive's window, a whole read's): their JSON written from
    the columns by the byte encoder, without a table; through the table (:class:`PassageFrameRows`) where the
    encoder does not cover a value."""

    def __init__(self, cols: Columns, heads: Heads) -> None:
        super().__init__(len(cols["head"]), self._items)
        self.cols = cols
        self.heads = heads

    def _table(self) -> PassageFrameRows:
        from console.analysis.passages.passage_frame import passages_frame

        return PassageFrameRows(passages_frame(self.cols, self.heads))

    def _items(self) -> Iterator[Any]:
        from console.analysis.passages.json_text import encode_passages

        text = encode_passages(self.cols, self.heads)
        return iter(json.loads(text)) if text is not None else iter(self._table())

    def write_json(self, write: Write, depth: int) -> None:
        from console.analysis.passages.json_text import indented_objects

        blobs = indented_objects(self.cols, self.heads, depth) if self.count else None
        if blobs is None:
            self._table().write_json(write, depth)
            return
        write("[")
        for blob in blobs:
            write(blob.decode("ascii"))
        write("\n" + " " * depth + "]")


class _NotKept(Rows):
    """Rows counted, not spilled (a format that shows only their totals)."""

    def __init__(self, count: int, what: str) -> None:
        super().__init__(count, self._missing)
        self.what = what

    def _missing(self) -> Iterator[Any]:
        raise RuntimeError(f"the {self.what} rows were not kept (collected for a format that does not list them)")


@dataclass
class SectionHistory:
    """A streamed section run: the final states, and the history the sink took as it was made."""

    final: dict[str, tuple[str, int, int, int, str]]  # section → (state, count, in, out, reason)
    sink: SectionsSink

    def timeline(self) -> Rows:
        sink = self.sink
        return SpilledRows(
            sink.timeline_rows,
            lambda: (json.loads(t) for t in sink.timeline_items()),
            lambda: sink.spilled_blocks("timeline"),
        )

    def ledger(self) -> Rows:
        sink = self.sink
        if not sink.ledger_spilled:
            return _NotKept(sink.ledger_rows, "ledger")
        return SpilledRows(sink.ledger_rows, self._ledger_items, lambda: sink.spilled_blocks("ledger"))

    def _ledger_items(self) -> Iterator[Any]:
        """The spilled ledger rows read back (only JSON at another depth would need them)."""
        decoder = json.JSONDecoder()
        text = ""
        for block in self.sink.spilled_blocks("ledger"):
            text += block
            pos = 0
            while True:
                try:  # a row cut at the block's end does not decode: it waits for the next block
                    row, pos = decoder.raw_decode(text, _skip_separators(text, pos))
                except ValueError:
                    break
                yield row
            text = text[pos:]
        if text.strip():
            raise ValueError("the spilled ledger ends in a row that does not decode")

    def ledger_summary(self) -> list[dict[str, Any]]:
        """Per section and head: axles in and out, first and last (section, head order)."""
        return [
            {"section": s, "head": h, "count_in": n_in, "count_out": n_out, "first": iso(t0), "last": iso(t1)}
            for (s, h), (n_in, n_out, t0, t1) in sorted(self.sink.ledger_totals.items())
        ]

    def resets(self) -> list[ResetRecord]:
        return self.sink.reset_rows

    def since_ns(self, section: str, state: str) -> int | None:
        """When ``section`` last entered ``state`` (None: never)."""
        return self.sink.entered_ns.get((section, state))

    def span_ns(self) -> tuple[int, int] | None:
        """The first and last state change's time (None: no state change)."""
        t = np.asarray(self.sink.timeline_time_ns)
        return (int(t.min()), int(t.max())) if len(t) else None

    def changes(self, section: str) -> Iterator[tuple[int, str, int, str]]:
        """One section's state changes in order: time, state, count, reason."""
        sink = self.sink
        n = sink.section_number.get(section)
        if n is None:
            return
        rows = np.flatnonzero(np.asarray(sink.timeline_section) == n)
        times = np.asarray(sink.timeline_time_ns)[rows].tolist()
        for t, text in zip(times, sink.timeline_items(rows.tolist()), strict=True):
            row = json.loads(text)
            yield t, row["state"], row["count"], row["reason"]

    def close(self) -> None:
        self.sink.close()


def _skip_separators(text: str, pos: int) -> int:
    while pos < len(text) and text[pos] in " \n,":
        pos += 1
    return pos
