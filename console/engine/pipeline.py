"""The one pipeline: parsed items in, passages, section history, health and crossing events out.

Every mode drives this class: a batch read feeds a log's chunks and ends
with :meth:`Pipeline.finish`; ``follow`` and the station's live view feed
the chunks of a growing file as they come; the archive's ingest feeds the
chunks it stores; a Dask task feeds one partition's records.  The
pipeline owns, for diagnostic records:

* the per-head passage stream (:class:`~console.analysis.passages.stream.PassageStream`):
  a head's records up to an idle gap are *closed* once nothing read later
  can join them, analysed by the batch analysis itself, and handed on;
* the counting of their wheel records into detection events
  (:class:`~console.analysis.sections.stream.EventStream`), released in
  the whole-log order below a *watermark* (nothing still to come is
  earlier);
* the section engine (:class:`~console.analysis.sections.engine.SectionEngine`),
  stepped on the released events, whose history (state changes, ledger,
  resets) is handed on as it is made;
* the health inputs (the health registers' records and channel events),
  judged when the input ends.

Results go to one :class:`~console.engine.sinks.Sink`.

**Whole mode.**  Several files read together may repeat each other's
records at their seams (overlapping exports); that is found by comparing
all records, so passages close only at :meth:`finish` (``whole=True``).
Three-element (majority) heads are counted from all their records too.
The results are the same objects, handed to the same sink.

**Facts.**  Two facts about a head (point mode: no release records; any
whole-second stamp) are guessed from its first closed passage and checked
on every later one; :attr:`Pipeline.facts_wrong` says a guess failed, and a
driver that can read its input again does so with :attr:`Pipeline.facts`.
A driver that knows each head's stamp resolution over the whole input up
front (the archive, from its records) gives it as ``head_step_s``: axles
then pair in every passage as in a read of everything at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.diag_events import silent_head_warnings
from console.analysis.events.detection import DetectionEvent, EventKind, sort_events
from console.analysis.passages.accumulator import DiagAccumulator, wheel_columns
from console.analysis.passages.clock_steps import ClockSteps
from console.analysis.passages.part_analysis import PartAnalysis
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.status import StatusSummary
from console.analysis.passages.stream import ORDER_SLACK_S, PassageStream, by_start, take_passages
from console.analysis.sections.state import SectionState
from console.engine.sinks import Sink
from parsers.diag.records import DiagChunk
from parsers.diag.registry import DiagRegistry
from parsers.units import NO_TIME, NS

if TYPE_CHECKING:
    # Imported where first used: a read of passages alone (analyze, speeds) never counts events or runs the
    # section engine, and its start-up is a third of a 3 M-record analyze's wall time.
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.events.block import EventBlock
    from console.analysis.head_table import Heads
    from console.analysis.health.findings import Finding
    from console.analysis.inventory import DeviceInventory
    from console.analysis.sections.engine import SectionEngine
    from console.analysis.sections.stream import EventStream, HeadFacts
    from console.layout import Layout

# The events health reads (channel_fault_findings): everything else only drives sections.
HEALTH_EVENT_KINDS = frozenset({EventKind.CHANNEL_FAULT, EventKind.CHANNEL_OK, EventKind.SINGLE_CHANNEL})
# The registers health judges (analog values against their band, 1-edge counter growth).
HEALTH_REGISTERS = frozenset({"analog_value", "counter_1_edge"})
# Live health ("closed"): judged again at most this often in log time, and at once on a new channel event ...
HEALTH_EVERY_NS = 600 * NS
# ... on the evidence of the last day (a batch read's of a day's log: the same findings; memory stays bounded).
HEALTH_WINDOW_NS = 86_400 * NS


@dataclass(frozen=True)
class PipelineSettings:
    """What the pipeline computes, and on which line."""

    speed: SpeedSettings = field(default_factory=SpeedSettings)
    # Detection events from the wheel records (None: passages only, as analyze and speeds need).
    events: DiagEventSettings | None = None
    # The heads the events count (None: every head of the log, with default facts).
    layout: Layout | None = None
    # Run the section engine on this layout (needs events).
    sections: Layout | None = None
    initial: SectionState = SectionState.PREPARATORY
    resets: tuple[DetectionEvent, ...] = ()
    # These registers' records are kept (health reads them).
    keep_registers: frozenset[str] = frozenset()
    # Health findings (needs events and the health registers kept): judged on everything at the end
    # ("end", a batch read), or as passages close ("closed", live: on the last day's evidence, every
    # HEALTH_EVERY_NS of log time and on each new channel event; a finding is handed on when it is new or
    # graver than the one handed on before); None: not judged here.
    health: str | None = None
    # Status-only passages handed on (False: counted per head in :attr:`Pipeline.status`).
    include_status: bool = True
    # Each closed batch's axles handed on (Sink.axles).
    axles: bool = False
    # The sections' start rows (each section's first state, at the first event) handed on; off where several
    # pipelines share a line (the archive's groups on Dask: the start is the line's first event, not theirs).
    start_rows: bool = True


@dataclass
class DiagOutcome:
    """What the pipeline knows when the input has ended, besides what it handed to the sink."""

    devices: Sequence[DeviceInventory]
    heads: Heads
    passages: int  # passages handed on
    unpaired_detections: int
    overlap_by_file: list[int]
    overlap_times_ns: np.ndarray
    late_records: int
    clock_steps: ClockSteps
    status: StatusSummary | None
    warnings: list[str]
    health_events: list[DetectionEvent]
    kept: list[DiagChunk]
    sections: SectionEngine | None
    last_event: DetectionEvent | None
    findings: list[Finding]


class Pipeline:
    """Feed diagnostic chunks in read order with :meth:`feed`; end with :meth:`finish`."""

    def __init__(
        self,
        registry: DiagRegistry,
        settings: PipelineSettings,
        sink: Sink | None = None,
        *,
        whole: bool = False,
        facts: dict[int, HeadFacts] | None = None,
        head_step_s: np.ndarray | None = None,
        close_every_chunks: int = 1,
    ) -> None:
        """``close_every_chunks``: see :attr:`PassageStream.close_every_chunks` (a read of files sets it, and
        its closed passages are then analysed aside; taken only without detection events, whose release waits
        on the open runs)."""
        self.registry = registry
        self.settings = s = settings
        self.sink = sink if sink is not None else Sink()
        self.whole = whole or (s.layout is not None and s.events is not None and _has_majority(s.layout))
        keep_releases = s.events is not None
        self.status = None if s.include_status else StatusSummary()
        self.passages = 0
        self.kept: list[DiagChunk] = []
        self._wanted = np.zeros(0, bool)
        self.health_events: list[DetectionEvent] = []
        self.last_event: DetectionEvent | None = None
        self.findings: list[Finding] = []  # "closed": the latest judgement's
        self._kept_newest_ns = NO_TIME
        self._judged_ns = NO_TIME
        self._judged_events = 0
        self._handed_rank: dict[tuple[str, str | None, int | None], int] = {}
        self.section_engine: SectionEngine | None = None
        self.clock_steps = ClockSteps(int(ORDER_SLACK_S * NS))  # where a head's records went back in time
        self._stepped: list[tuple[np.ndarray, np.ndarray]] = []  # whole mode: those heads, and from when
        if s.health is not None and not (s.events is not None and s.keep_registers >= HEALTH_REGISTERS):
            raise ValueError("health needs the detection events and the health registers kept")
        self._resets_pending = list(s.resets)
        if self.whole:
            self.acc = DiagAccumulator(registry, keep_releases=keep_releases, track_overlap=True)
            self.stream: PassageStream | None = None
            self.events: EventStream | None = None
        else:
            # Wheel records reach the counting as they are read; closed passages give it only their activity
            # (for power-loss events, when asked for), which the stream keeps with the releases.
            power = s.events is not None and s.events.power_gap_s is not None
            batched = close_every_chunks > 1 and s.events is None
            self.stream = PassageStream(
                registry,
                s.speed,
                keep_releases=power,
                head_step_s=head_step_s,
                close_every_chunks=close_every_chunks if batched else 1,
                analyse_aside=batched,
            )
            self.acc = self.stream.acc
            self.events = None
            if s.events is not None:
                from console.analysis.sections.stream import EventStream

                self.events = EventStream(
                    s.layout, s.events, facts=facts, on_event=self.health_events.append, event_kinds=HEALTH_EVENT_KINDS
                )
                for r in s.resets:
                    self.events.add_reset(r)
                self._resets_pending = []

    # -- input -----------------------------------------------------------------
    def feed(self, chunk: DiagChunk) -> None:
        """One chunk of parsed records, in read order."""
        if not len(chunk):
            return
        s = self.settings
        stepped, before_ns = self.clock_steps.feed(
            chunk.file_id, self.acc._lookup().head_of(chunk.register_id), chunk.time_ns, chunk.line
        )
        if len(stepped) and s.events is not None:
            # Doubt from the record before the step on: a section it bounds is not shown clear on counts
            # that sorting by time may have put out of order.
            if self.events is not None:
                self.events.add_clock_steps(stepped, before_ns, self.heads)
            else:
                self._stepped.append((stepped, before_ns))
        if s.keep_registers:
            if len(self._wanted) < self.registry.n_registers:
                self._wanted = self.registry.canonical_in(s.keep_registers)
            mask = self._wanted[chunk.register_id]
            if mask.any():
                kept = chunk.take(mask)
                self.kept.append(kept)
                self._kept_newest_ns = max(self._kept_newest_ns, int(kept.time_ns.max()))
        if self.stream is None:
            self.acc.add(chunk)
            return
        if self.events is not None:
            # Counted as they are read (the heads whose facts are settled): events wait for the order slack,
            # not for their passage to close.
            wheel = wheel_columns(self.acc._lookup(), chunk)
            if wheel is not None:
                self.events.add_records(wheel, self.heads)
        self._take(self.stream.add(chunk))
        if self.events is not None:
            slack_ns = self.stream._slack_ns
            clock = self.stream.lagging_clock_ns()
            if clock > NO_TIME + slack_ns:
                self._step(self.events.release_block(clock - slack_ns, self.stream.open_firsts()))

    def advance(self, until_ns: int) -> None:
        """No record still to come is earlier than ``until_ns``: a source that hands its records over in time
        order as its clock runs (the simulated heads, wired to the station's console) says so, and events up
        to then are released without waiting for later records and the order slack.  A followed file never
        can: its lines may arrive late."""
        if self.stream is None:
            return
        self._take(self.stream.complete_until(until_ns))
        if self.events is not None:
            self._step(self.events.release_block(until_ns, self.stream.open_firsts()))

    def reset(self, e: DetectionEvent) -> None:
        """An operator's reset request (a live console's), decided in time order with the detections: it
        is released with them once nothing still to come precedes it."""
        if self.events is not None:
            self.events.add_reset(e)
        else:
            self._resets_pending.append(e)

    def finish(self, start_sections: bool = True) -> DiagOutcome:
        """The input has ended: every open passage is whole; every held event is released.

        ``start_sections``: with no event at all, the section engine is still made (every section in its
        start state), as a batch read reports it; a live source that gave no record makes none.
        """
        warnings: list[str] = []
        if self.stream is None:
            warnings = self._finish_whole()
        else:
            self._take(self.stream.finish(), wait=True)
            if self.events is not None:
                clock = self.stream.clock_ns
                slack_ns = self.stream._slack_ns
                self._step(self.events.finish_block(clock - slack_ns if clock > NO_TIME + slack_ns else None))
                warnings = self.events.warnings(self.stream.heads)
        s = self.settings
        if start_sections and s.sections is not None and s.events is not None and self.section_engine is None:
            # No event at all: every section keeps its start state, from the log's first record (none in an
            # empty log: then no start rows, rather than rows timed 1970-01-01).
            first = self.acc.first_record_ns()
            engine = self._engine(first if first is not None else 0)
            if first is None:
                engine.transitions = []
            self.first_event_ns = None
            self._drain()
        if self.section_engine is not None and s.sections is not None:
            # Heads in the log the engine never heard (status records only): their sections held, said why.
            warnings += silent_head_warnings(s.sections, self.heads, self.section_engine.unheard)
        if self.settings.health is not None:
            self._judge(final=True)
        heads = self.heads
        by_file = self._overlap_by_file
        return DiagOutcome(
            devices=self.acc.devices(),
            heads=heads,
            passages=self.passages,
            unpaired_detections=self._unpaired,
            overlap_by_file=by_file,
            overlap_times_ns=self._overlap_times,
            late_records=self.stream.late_records if self.stream is not None else 0,
            clock_steps=self.clock_steps,
            status=self.status,
            warnings=warnings,
            health_events=self.health_events,
            kept=self.kept,
            sections=self.section_engine,
            last_event=self.last_event,
            findings=self.findings,
        )

    # -- state ---------------------------------------------------------------
    @property
    def heads(self) -> Heads:
        return self.acc._lookup().heads

    @property
    def facts(self) -> dict[int, HeadFacts]:
        """Per head key, the facts seen in the records read so far."""
        return self.events.facts if self.events is not None else {}

    @property
    def facts_wrong(self) -> bool:
        """A guessed head fact was contradicted by a later passage: read again with :attr:`facts`."""
        return self.events is not None and self.events.guess_failed and self.events.known_facts is None

    @property
    def late_records(self) -> int:
        return self.stream.late_records if self.stream is not None else 0

    # -- passages ----------------------------------------------------------------
    _unpaired = 0
    _overlap_by_file: list[int] = []  # noqa: RUF012 (replaced, never mutated)
    _overlap_times = np.zeros(0, np.int64)

    def _take(self, part: PartAnalysis | None, wait: bool = False) -> None:
        """A part the stream closed at once, then those its worker has analysed since (``wait``: all)."""
        assert self.stream is not None
        self._closed(part)
        for done in self.stream.closed_parts(wait):
            self._closed(done)

    def _closed(self, part: PartAnalysis | None) -> None:
        if part is None:
            return
        if self.stream is not None:
            self._unpaired = self.stream.unpaired_detections
        heads = self.heads
        if self.events is not None:
            self.events.add(None, part.activity, heads)
            p = part.passages
            if p is not None:
                # A head's facts are guessed once a passage of its wheel records has closed (as from all of them).
                wheels = (p["detections_sys1"] + p["detections_sys2"]) > 0
                self.events.settle(p["head"][wheels], heads)
        if self.settings.axles and len(part.axles["head"]):
            self.sink.axles(part.axles, heads)
        if self.settings.health == "closed":
            self._judge()
        if part.passages is None or not len(part.passages["head"]):
            return
        cols = take_passages(part.passages, by_start(part.passages))
        if self.status is not None:
            cols = self.status.take(cols)
        if len(cols["head"]):
            self.passages += len(cols["head"])
            self.sink.passages(cols, heads)

    def _finish_whole(self) -> list[str]:
        """Whole mode: every record is in; analyse them together, as one read of every file."""
        from console.analysis.diag_events import diag_detection_events
        from console.analysis.events.block import EventBlock, StringPool
        from console.layout import layout_from_heads

        s = self.settings
        analysis = self.acc.result(s.speed)
        self._unpaired = analysis.unpaired_detections
        self._overlap_by_file = analysis.overlap_by_file
        self._overlap_times = analysis.overlap_times_ns
        heads = analysis.heads
        if s.axles and len(analysis.axle_columns["head"]):
            self.sink.axles(analysis.axle_columns, heads)
        cols = analysis.passage_columns
        if cols is not None and len(cols["head"]):
            cols = take_passages(cols, by_start(cols))
            if self.status is not None:
                cols = self.status.take(cols)
            if len(cols["head"]):
                self.passages += len(cols["head"])
                self.sink.passages(cols, heads)
        if s.events is None:
            return []
        lay = s.layout or layout_from_heads(sorted({name for _, name in heads}))
        events, warnings = diag_detection_events(analysis, lay, s.events)
        events += [
            DetectionEvent(t, EventKind.CLOCK_STEP, heads[k][1], source="diag")
            for stepped, before_ns in self._stepped
            for k, t in zip(stepped.tolist(), before_ns.tolist(), strict=True)
            if lay.counted_head(heads[k][1], heads[k][0]) is not None  # as the streamed events count heads
        ]
        self.health_events += [e for e in events if e.kind in HEALTH_EVENT_KINDS]
        if events:
            self.last_event = events[-1]
        ordered = sort_events([*events, *self._resets_pending])
        if ordered:
            block = EventBlock.from_events(ordered, (), StringPool())
            self.sink.detections(block)
            if s.sections is not None:
                engine = self._engine(ordered[0].time_ns)
                for e in ordered:
                    engine.step(e)
                self._drain()
        return warnings

    # -- health -----------------------------------------------------------------------
    def _judge(self, final: bool = False) -> None:
        """Health findings on the records kept and the channel events, handed on.

        Live ("closed"): judged when HEALTH_EVERY_NS of log time passed since the last judgement, a channel
        event came, or the read ends (``final``); on the last HEALTH_WINDOW_NS of evidence; a finding is handed
        on when new or graver than before for its rule, head and channel.
        """
        from console.analysis.health.rules import health_report
        from parsers.diag.records import chunks_to_frame

        s = self.settings
        closed = s.health == "closed"
        if closed:
            news = len(self.health_events) > self._judged_events
            due = self._kept_newest_ns - self._judged_ns >= HEALTH_EVERY_NS if self.kept else False
            if not (news or due or (final and (self.kept or self.health_events))):
                return
        lay = s.layout or s.sections
        bands = {h.id: h.analog_band for h in lay.heads if h.analog_band} if lay is not None else None
        records = chunks_to_frame(self.kept, self.registry, all_heads=False)  # the kept ones' heads only
        findings = health_report(records, bands=bands or None, events=self.health_events)
        if not closed:
            self.findings += findings
            if findings:
                self.sink.findings(findings)
            return
        self.findings = findings
        newer = []
        for f in findings:
            key, rank = (f.rule, f.counting_head, f.channel), f.severity.rank
            if rank > self._handed_rank.get(key, -1):
                self._handed_rank[key] = rank
                newer.append(f)
        # The evidence older than the window is let go (in place: the event stream appends to this list).
        cutoff = self._kept_newest_ns - HEALTH_WINDOW_NS
        self.kept[:] = [c for c in self.kept if int(c.time_ns.max()) >= cutoff]
        self.health_events[:] = [e for e in self.health_events if e.time_ns >= cutoff]
        self._judged_ns, self._judged_events = self._kept_newest_ns, len(self.health_events)
        if newer:
            self.sink.findings(newer)

    # -- events and sections ---------------------------------------------------------
    def _step(self, block: EventBlock) -> None:
        from console.analysis.events.block import KIND_CODE

        if not len(block):
            return
        # The last diagnostic event (a report's data end): operator resets do not count.
        diag = np.flatnonzero(block.kind != KIND_CODE[EventKind.RESET])
        if len(diag):
            self.last_event = block.event(int(diag[-1]))
        self.sink.detections(block)
        if self.settings.sections is None:
            return
        self._engine(int(block.time_ns[0])).step_block(block)
        self._drain()

    def _engine(self, start_ns: int) -> SectionEngine:
        if self.section_engine is None:
            from console.analysis.sections.engine import SectionEngine

            s = self.settings
            assert s.sections is not None
            self.section_engine = SectionEngine(s.sections, initial=s.initial, start_ns=start_ns)
            self.first_event_ns = start_ns
            if not s.start_rows:
                self.section_engine.transitions = []
        return self.section_engine

    first_event_ns: int | None = None  # when the section engine started (its first event)

    def _drain(self) -> None:
        """The section engine's new history, handed on (the engine keeps none of it)."""
        assert self.section_engine is not None
        transitions, ledger, resets = self.section_engine.take_history()
        if transitions:
            self.sink.transitions(transitions)
        if ledger:
            self.sink.ledger(ledger)
        if resets:
            self.sink.resets(resets)


def _has_majority(layout: Layout) -> bool:
    return any(h.channels == 3 for h in layout.heads)
