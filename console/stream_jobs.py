"""`sections`, `health` and `report` over a diagnostic log in memory bounded by heads and open passages.

One read of the log through :class:`~console.analysis.stream.PassageStream`
(closed passages) and :class:`~console.analysis.stream_sections.EventStream`
(detection events in the batch order) into a
:class:`~console.analysis.sections.SectionEngine`.  What the faces print is
what the whole-file path (:func:`console.jobs.analyze_files` +
:func:`console.jobs.detection_events` + :func:`console.analysis.sections.run_sections`
+ :func:`console.jobs.health_findings`) gives, byte for byte
(``tests/test_stream_sections.py``).

The engine's history (state timeline, count ledger) grows with the traffic,
not the heads: a :class:`SectionsSink` takes it as it is made, keeps the
first rows and per-(section, head) totals for the tables, and, for
``--json`` and the report, spills each row's JSON text to a temporary file
that the document copies in at the end.  Closed passages go to the caller as
they close (``on_passages``: the report spools them).

Several files (their overlap is found record by record) and layouts with
three-element heads are read whole, as before.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from array import array
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import numpy as np

from console.analysis.diag_events import DiagEventSettings
from console.analysis.diagnostics import DiagAnalysis, PartAnalysis, SpeedSettings
from console.analysis.event_block import KIND_CODE, EventBlock
from console.analysis.events import DetectionEvent, EventKind, sort_events
from console.analysis.passages import Columns
from console.analysis.sections import LedgerEntry, ResetRecord, SectionEngine, SectionState, Transition
from console.analysis.stream import PassageStream, by_head_and_start, by_start, concat_passages, take_passages
from console.analysis.stream_sections import EventStream, HeadFacts
from console.analysis.timefmt import NS, _fraction, iso
from console.jobs import DiagJob, OnPassages, analyze_files, detection_events
from console.jsonout import valid_unicode
from console.layout import Layout
from console.memory import read_memory
from parsers.diag import DiagChunk, DiagReader, chunks_to_frame
from parsers.sources import DEFAULT_CHUNK_BYTES

# The events health reads (channel_fault_findings): everything else only drives sections.
HEALTH_EVENT_KINDS = frozenset({EventKind.CHANNEL_FAULT, EventKind.CHANNEL_OK, EventKind.SINGLE_CHANNEL})
TIMELINE_ROWS_KEPT = 201  # the text table shows 200 and says whether there are more
SPILL_BLOCK_BYTES = 1 << 20  # spilled rows copied out at a time


def _row_json(row: dict[str, Any] | str) -> str:
    return valid_unicode(json.dumps(row, ensure_ascii=True, separators=(",", ":"), allow_nan=False))


def transition_json(t: Transition) -> str:
    """One timeline row as ``sections --json`` writes it."""
    return _row_json(
        {"section": t.section, "state": str(t.state), "count": t.count, "reason": t.reason, "time": iso(t.time_ns)}
    )


def ledger_json(x: LedgerEntry) -> str:
    """One ledger row as ``sections --json`` writes it (:func:`_LedgerText` writes the same, faster)."""
    return _row_json({"section": x.section, "head": x.head, "delta": x.delta, "count": x.count, "time": iso(x.time_ns)})


class _LedgerText:
    """:func:`ledger_json` for a row per counted axle: the JSON of each (section, head) and of each
    second's time text made once (``tests/test_stream_sections.py`` holds them equal).

    ``depth`` None: compact, as ``sections --json`` writes a row; else the row as
    ``json.dumps(indent=1)`` writes an array item at that depth, its newline and
    indent first (the report's JSON: ``console.report.jsonwrite``).
    """

    def __init__(self, depth: int | None = None) -> None:
        self._prefix: dict[tuple[str, str], str] = {}
        self._second: dict[int, str] = {}
        if depth is None:
            self._open, self._sep, self._colon, self._close = "{", ",", ":", "}"
        else:
            member = "\n" + " " * (depth + 1)
            self._open, self._sep, self._colon = "\n" + " " * depth + "{" + member, "," + member, ": "
            self._close = "\n" + " " * depth + "}"

    def __call__(self, x: LedgerEntry) -> str:
        prefix = self._prefix.get((x.section, x.head))
        sep, colon = self._sep, self._colon
        if prefix is None:
            text = f'{self._open}"section"{colon}{_row_json(x.section)}{sep}"head"{colon}{_row_json(x.head)}'
            prefix = self._prefix[(x.section, x.head)] = f'{text}{sep}"delta"{colon}'
        whole, frac = divmod(x.time_ns, NS)
        second = self._second.get(whole)
        if second is None:
            if len(self._second) > 1 << 16:
                self._second.clear()
            second = self._second[whole] = str(iso(whole * NS))[:-5]  # without ".000Z"
        return (
            f'{prefix}{x.delta}{sep}"count"{colon}{x.count}{sep}"time"{colon}"{second}{_fraction(frac)}Z"{self._close}'
        )


def reset_json(r: ResetRecord) -> str:
    return _row_json({"section": r.section, "accepted": r.accepted, "reason": r.reason, "time": iso(r.time_ns)})


class _Spill:
    """JSON array items written to a temporary file as they come (``track``: where each one starts, to read it back)."""

    def __init__(self, track: bool = False) -> None:
        self.file: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115 (closed by close())
        self.n = 0
        self.size = 0
        self.starts: array[int] | None = array("q") if track else None

    def add(self, text: str) -> None:
        data = (b"," if self.n else b"") + text.encode("ascii")
        if self.starts is not None:
            self.starts.append(self.size + (1 if self.n else 0))
        self.file.write(data)
        self.size += len(data)
        self.n += 1

    def copy_to(self, out: IO[str]) -> None:
        out.write("[")
        out.flush()
        self.file.seek(0)
        buf = getattr(out, "buffer", None)
        if buf is not None:
            shutil.copyfileobj(self.file, buf, 1 << 20)
            buf.flush()
        else:
            while block := self.file.read(1 << 20):
                out.write(block.decode("ascii"))
        out.write("]")

    def blocks(self) -> Iterator[str]:
        """The items as written (comma-separated, no brackets), in pieces of ``SPILL_BLOCK_BYTES``."""
        self.file.flush()
        fd, step = self.file.fileno(), SPILL_BLOCK_BYTES
        for offset in range(0, self.size, step):
            yield os.pread(fd, min(step, self.size - offset), offset).decode("ascii")

    def items(self, rows: Iterable[int] | None = None) -> Iterator[str]:
        """Items one by one (``rows``: these, in this order; needs ``track``)."""
        assert self.starts is not None
        self.file.flush()
        fd, starts, n = self.file.fileno(), self.starts, self.n
        for i in range(n) if rows is None else rows:
            end = starts[i + 1] - 1 if i + 1 < n else self.size  # the next item's comma
            yield os.pread(fd, end - starts[i], starts[i]).decode("ascii")

    def close(self) -> None:
        self.file.close()


@dataclass
class SectionsSink:
    """The section engine's history as it is made: first rows, totals, and (``spill``) every row as JSON.

    ``spill`` writes each state change with ``timeline_text`` (where each
    starts is kept, to read rows back) and, with ``spill_ledger``, each
    counted axle with ``ledger_text``: by default as ``sections --json``
    writes them; the report gives its own form (``console.report.spooled``).
    """

    spill: bool = False
    keep_all: bool = False  # the whole history in memory as well (report's collect(whole=True), tests)
    spill_ledger: bool = True
    timeline_text: Callable[[Transition], str] = transition_json
    ledger_text: Callable[[LedgerEntry], str] = field(default_factory=_LedgerText)
    timeline_rows: int = 0
    timeline_first: list[Transition] = field(default_factory=list)
    ledger_rows: int = 0
    # (section, head) → [in, out, first, last]
    ledger_totals: dict[tuple[str, str], list[int]] = field(default_factory=dict)
    resets: list[ResetRecord] = field(default_factory=list)
    timeline_all: list[Transition] = field(default_factory=list)
    ledger_all: list[LedgerEntry] = field(default_factory=list)
    # Per state change: its section (numbered as first seen: `section_number`) and time, for plots.
    section_number: dict[str, int] = field(default_factory=dict)
    timeline_section: array[int] = field(default_factory=lambda: array("i"))
    timeline_time_ns: array[int] = field(default_factory=lambda: array("q"))
    # (section, state) → when the section last entered that state.
    entered_ns: dict[tuple[str, str], int] = field(default_factory=dict)
    _timeline: _Spill | None = None
    _ledger: _Spill | None = None

    def __post_init__(self) -> None:
        if self.spill:
            self._timeline = _Spill(track=True)
            self._ledger = _Spill() if self.spill_ledger else None

    def take(self, engine: SectionEngine) -> None:
        """Move the engine's new history out of it."""
        if engine.transitions:
            trs, engine.transitions = engine.transitions, []
            self.timeline_rows += len(trs)
            room = TIMELINE_ROWS_KEPT - len(self.timeline_first)
            if room > 0:
                self.timeline_first += trs[:room]
            if self.keep_all:
                self.timeline_all += trs
            numbers, entered = self.section_number, self.entered_ns
            for t in trs:  # per state change: a few per train and section
                n = numbers.setdefault(t.section, len(numbers))
                self.timeline_section.append(n)
                self.timeline_time_ns.append(t.time_ns)
                entered[(t.section, str(t.state))] = t.time_ns
                if self._timeline is not None:
                    self._timeline.add(self.timeline_text(t))
        if engine.ledger:
            led, engine.ledger = engine.ledger, []
            self.ledger_rows += len(led)
            totals = self.ledger_totals
            text = self.ledger_text
            for x in led:  # per counted axle: a dict update
                tot = totals.get((x.section, x.head))
                if tot is None:
                    tot = totals[(x.section, x.head)] = [0, 0, x.time_ns, x.time_ns]
                tot[0 if x.delta > 0 else 1] += 1
                tot[2] = min(tot[2], x.time_ns)
                tot[3] = max(tot[3], x.time_ns)
                if self._ledger is not None:
                    self._ledger.add(text(x))
            if self.keep_all:
                self.ledger_all += led
        if engine.resets:
            self.resets += engine.resets
            engine.resets = []

    def timeline_items(self, rows: Iterable[int] | None = None) -> Iterator[str]:
        """The spilled state changes' texts, one by one (``rows``: these, in this order)."""
        assert self._timeline is not None
        return self._timeline.items(rows)

    def spilled_blocks(self, what: str) -> Iterator[str]:
        """The spilled ``timeline`` or ``ledger`` rows' texts, comma-separated, in pieces."""
        spill = self._timeline if what == "timeline" else self._ledger
        assert spill is not None, f"the {what} was not spilled"
        return spill.blocks()

    @property
    def ledger_spilled(self) -> bool:
        return self._ledger is not None

    def write_json_arrays(self, out: IO[str]) -> None:
        """``"timeline":[…],"ledger":[…],"resets":[…]`` (spilled rows copied in)."""
        assert self._timeline is not None and self._ledger is not None
        out.write('"timeline":')
        self._timeline.copy_to(out)
        out.write(',"ledger":')
        self._ledger.copy_to(out)
        out.write(',"resets":[' + ",".join(reset_json(r) for r in self.resets) + "]")

    def close(self) -> None:
        for s in (self._timeline, self._ledger):
            if s is not None:
                s.close()


@dataclass
class StreamOutcome:
    """One read of the log: the job, the events' warnings, the engine's final states and history."""

    job: DiagJob
    warnings: list[str]
    health_events: list[DetectionEvent]
    engine: SectionEngine | None
    sink: SectionsSink | None
    last_event: DetectionEvent | None = None
    reads: int = 1  # 2: the per-head facts guessed on the first read were wrong


def _new_engine(layout: Layout, initial: SectionState, start_ns: int) -> SectionEngine:
    return SectionEngine(layout, initial=initial, start_ns=start_ns)


@dataclass
class _Run:
    """The section engine fed in order; its history drained into the sink."""

    layout: Layout | None
    initial: SectionState
    sink: SectionsSink | None
    engine: SectionEngine | None = None
    last: DetectionEvent | None = None

    def step(self, events: list[DetectionEvent]) -> None:
        if not events:
            return
        # The last diagnostic event (the report's data end): operator resets do not count.
        self.last = next((e for e in reversed(events) if e.kind is not EventKind.RESET), self.last)
        if self.layout is None or self.sink is None:
            return
        if self.engine is None:
            self.engine = _new_engine(self.layout, self.initial, events[0].time_ns)
        for e in events:
            self.engine.step(e)
        self.sink.take(self.engine)

    def step_block(self, block: EventBlock) -> None:
        """:meth:`step` for events as columns: the engine takes the block at once."""
        if not len(block):
            return
        diag = np.flatnonzero(block.kind != KIND_CODE[EventKind.RESET])
        if len(diag):
            self.last = block.event(int(diag[-1]))
        if self.layout is None or self.sink is None:
            return
        if self.engine is None:
            self.engine = _new_engine(self.layout, self.initial, int(block.time_ns[0]))
        self.engine.step_block(block)
        self.sink.take(self.engine)

    def end(self) -> SectionEngine | None:
        if self.layout is not None and self.sink is not None and self.engine is None:
            self.engine = _new_engine(self.layout, self.initial, 0)  # no event at all: as run_sections
            self.sink.take(self.engine)
        return self.engine


def _streamable(paths: Sequence[Path], layout: Layout | None) -> bool:
    return len(paths) == 1 and not (layout is not None and any(h.channels == 3 for h in layout.heads))


def stream_diag(
    paths: Sequence[Path],
    settings: SpeedSettings,
    *,
    layout: Layout | None,
    event_settings: DiagEventSettings,
    sections_layout: Layout | None = None,
    resets: Sequence[DetectionEvent] = (),
    initial: SectionState = SectionState.PREPARATORY,
    sink: SectionsSink | None = None,
    keep_registers: Collection[str] = (),
    keep_passages: bool = False,
    on_passages: OnPassages | None = None,
    on_progress: Callable[[int], None] | None = None,
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
) -> StreamOutcome:
    """Read the log once (twice when a guessed head fact was wrong): events, sections, health records.

    ``layout`` None: events on the log's own heads (health without a layout).
    ``sections_layout`` (with ``sink``): run the section engine on it.
    ``keep_registers``: those registers' records kept as the job's record table (health).
    ``keep_passages``: the passages table kept, else only counted.
    ``on_passages``: each batch of closed passages (by start), once (the report spools them).
    """
    with read_memory():
        if not _streamable(paths, layout):
            whole = _whole(
                paths,
                settings,
                layout,
                event_settings,
                sections_layout,
                resets,
                initial,
                sink,
                keep_registers,
                on_progress,
            )
            cols = whole.job.analysis.passage_columns
            if on_passages is not None and cols is not None and len(cols["head"]):
                on_passages(take_passages(cols, by_start(cols)), whole.job.analysis.heads)
            return whole
        facts: dict[int, HeadFacts] | None = None
        for attempt in (1, 2):
            out = _stream_once(
                paths,
                settings,
                layout,
                event_settings,
                sections_layout,
                resets,
                initial,
                sink if attempt == 1 else _fresh(sink),
                keep_registers,
                keep_passages,
                # A second read closes the same passages (the facts change events only): taken once.
                on_passages if attempt == 1 else None,
                on_progress,
                chunk_bytes,
                facts,
            )
            if isinstance(out, StreamOutcome):
                out.reads = attempt
                return out
            facts = out
        raise AssertionError("the second read runs with the facts of the first")


def _fresh(sink: SectionsSink | None) -> SectionsSink | None:
    if sink is None:
        return None
    sink.close()
    return SectionsSink(
        spill=sink.spill,
        keep_all=sink.keep_all,
        spill_ledger=sink.spill_ledger,
        timeline_text=sink.timeline_text,
        ledger_text=sink.ledger_text,
    )


def _stream_once(
    paths: Sequence[Path],
    settings: SpeedSettings,
    layout: Layout | None,
    event_settings: DiagEventSettings,
    sections_layout: Layout | None,
    resets: Sequence[DetectionEvent],
    initial: SectionState,
    sink: SectionsSink | None,
    keep_registers: Collection[str],
    keep_passages: bool,
    on_passages: OnPassages | None,
    on_progress: Callable[[int], None] | None,
    chunk_bytes: int,
    facts: dict[int, HeadFacts] | None,
) -> StreamOutcome | dict[int, HeadFacts]:
    reader = DiagReader(paths, on_progress=on_progress, chunk_bytes=chunk_bytes)
    stream = PassageStream(reader.registry, settings, keep_releases=True)
    health_events: list[DetectionEvent] = []
    events = EventStream(
        layout, event_settings, facts=facts, on_event=health_events.append, event_kinds=HEALTH_EVENT_KINDS
    )
    for r in resets:
        events.add_reset(r)
    run = _Run(sections_layout, initial, sink)
    kept: list[DiagChunk] = []
    passages: list[Columns] = []
    slack_ns = stream._slack_ns

    def closed(part: PartAnalysis | None) -> None:
        if part is None:
            return
        events.add(part.wheel, part.activity, stream.heads)
        if part.passages is not None and len(part.passages["head"]):
            cols = take_passages(part.passages, by_start(part.passages))
            if keep_passages:
                passages.append(cols)
            if on_passages is not None:
                on_passages(cols, stream.heads)

    wanted = np.zeros(0, bool)
    for chunk in reader.chunks():
        closed(stream.add(chunk))
        if keep_registers:
            if len(wanted) < reader.registry.n_registers:
                wanted = reader.registry.canonical_in(keep_registers)
            mask = wanted[chunk.register_id]
            if mask.any():
                kept.append(chunk.take(mask))
        if len(chunk) and stream.clock_ns > np.iinfo(np.int64).min + slack_ns:
            watermark = min(stream.open_first_ns(), stream.clock_ns - slack_ns)
            run.step_block(events.release_block(watermark))
    closed(stream.finish())
    run.step_block(events.finish_block())
    if events.guess_failed and facts is None:
        return events.facts
    cols = concat_passages(passages)
    cols = take_passages(cols, by_head_and_start(cols)) if cols is not None else None
    analysis = DiagAnalysis(
        settings=settings,
        devices=stream.acc.devices(),
        passage_columns=cols,
        axle_columns=_no_axles(),
        overlap_records=0,
        unpaired_detections=stream.unpaired_detections,
        overlap_by_file=[0] * len(reader.report.files),
        heads=stream.heads,
    )
    records = chunks_to_frame(kept, reader.registry) if keep_registers else None
    job = DiagJob(files=[str(p) for p in paths], report=reader.report, analysis=analysis, kept_records=records)
    return StreamOutcome(job, events.warnings(stream.heads), health_events, run.end(), sink, run.last)


def _no_axles() -> Columns:
    from console.jobs import _no_axles as empty

    return empty()


def _whole(
    paths: Sequence[Path],
    settings: SpeedSettings,
    layout: Layout | None,
    event_settings: DiagEventSettings,
    sections_layout: Layout | None,
    resets: Sequence[DetectionEvent],
    initial: SectionState,
    sink: SectionsSink | None,
    keep_registers: Collection[str],
    on_progress: Callable[[int], None] | None,
) -> StreamOutcome:
    """Several files, or three-element heads: the whole-file path, its history through the same sink."""
    job = analyze_files(paths, settings, on_progress=on_progress, keep_registers=keep_registers, keep_releases=True)
    evs, warnings = detection_events(job, layout, event_settings)
    run = _Run(sections_layout, initial, sink)
    ordered = sort_events([*evs, *resets])
    run.step(ordered)
    last = evs[-1] if evs else None
    health_events = [e for e in evs if e.kind in HEALTH_EVENT_KINDS]
    return StreamOutcome(job, warnings, health_events, run.end(), sink, last)
