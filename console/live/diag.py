"""Diagnostic records arriving in pieces → passages, section changes, health findings.

The batch analysis (:class:`~console.analysis.diagnostics.DiagAccumulator`)
decides passages per counting head by the idle gap between records.  Live,
a head's passage is decided once the log's clock (the latest record time
seen) has run more than the idle gap past the head's last record: nothing
that arrives later can join it.  Those *closed* records are analysed by the
very same accumulator, then dropped, so memory holds only the open runs and
the passages are exactly the ones ``trackside analyze`` finds in the whole
log (the live test checks this on a log written in pieces and rotated).

Wheel-sensor records of closed runs go on, in time order, through one
:class:`~console.analysis.wheels.HeadCounter` per head (state carried across
runs) into one :class:`~console.analysis.sections.SectionEngine`.  Events are
handed to the engine only below the *watermark* (the start of the earliest
still-open run), so heads that close in a different order cannot reorder
the section engine's input.
"""

from __future__ import annotations

import codecs
import heapq
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from console.analysis.diagnostics import DiagAccumulator, SpeedSettings
from console.analysis.events import DetectionEvent
from console.analysis.health import Finding, health_report
from console.analysis.sections import SectionEngine, SectionState, Transition
from console.analysis.timefmt import NS
from console.analysis.wheels import CountingSettings, HeadCounter
from console.jobs import HEALTH_REGISTERS
from console.layout import Layout
from console.live.frames import CountsListener, drain_history
from parsers.diag import DiagChunk, DiagReader, chunks_to_frame
from parsers.report import FileReport

# Logs interleave boards, each with its own clock resolution: a record may
# come this much after a later-stamped one of another board.
ORDER_SLACK_S = 2.0
NO_TIME = np.iinfo(np.int64).min

Emit = Callable[[dict[str, Any]], None]


def parse_lines(reader: DiagReader, data: bytes, report: FileReport, file_id: int, first_line: int) -> DiagChunk:
    """Complete lines → a chunk of records, through the batch reader's own tokenizer and rules.

    The reader keeps one register registry and one parse report for all followed files.
    """
    return reader.parse_lines(data, report, file_id, first_line)


@dataclass
class _HeadRun:
    first_ns: int
    last_ns: int


@dataclass
class DiagFollowStats:
    passages: int = 0
    section_changes: int = 0
    health_findings: int = 0
    records_held: int = 0
    rejections_shown: int = 0
    by_file: dict[str, FileReport] = field(default_factory=dict)


class DiagFollow:
    """The diagnostic half of the live engine: feed line blocks, get events through ``emit``."""

    def __init__(self, layout: Layout | None, settings: SpeedSettings, emit: Emit) -> None:
        self.layout = layout
        self.settings = settings
        self.emit = emit
        self.reader = DiagReader([])
        self.stats = DiagFollowStats()
        self._file_ids: dict[str, int] = {}
        self._held: list[DiagChunk] = []
        self._head_of_reg = np.zeros(0, np.int64)
        self._head_keys: dict[tuple[int, str], int] = {}
        self._heads: list[tuple[int, str]] = []
        self._open: dict[int, _HeadRun] = {}
        self._cuts: dict[int, int] = {}  # head → records up to this time form finished runs
        self.clock_ns = NO_TIME
        # Each followed file's own clock (its latest record) and the file each head's records come
        # from: a head's run is closed by its own file's clock, so a file that runs ahead (a skewed
        # clock, or a source read faster) does not cut the runs of another file mid-train.
        self._file_clock: dict[int, int] = {}
        self._head_file: dict[int, int] = {}
        self._gap_ns = int(settings.idle_gap_s * NS)
        self._slack_ns = int(ORDER_SLACK_S * NS)
        self._counters: dict[str, HeadCounter] = {}
        self._pending: list[tuple[int, int, DetectionEvent]] = []  # heap by time, then arrival
        self._seq = 0
        self.sections: SectionEngine | None = None
        self._seen_findings: set[tuple[str, str | None, int | None]] = set()
        self.listener: CountsListener | None = None  # also gets every event and section change

    # -- input -----------------------------------------------------------
    def add(self, source: str, file_label: str, first_line: int, data: bytes) -> None:
        if first_line == 1 and data.startswith(codecs.BOM_UTF8):
            data = data[len(codecs.BOM_UTF8) :]
        report = self.stats.by_file.get(file_label)
        if report is None:
            report = self.stats.by_file[file_label] = FileReport(file=file_label)
            self.reader.report.files.append(report)
        # One file id per followed source: a rotation continues the same stream,
        # so a second split by the rotation is not two "overlapping exports".
        file_id = self._file_ids.setdefault(source, len(self._file_ids))
        while len(self.reader.registry.files) <= file_id:
            self.reader.registry.files.append(source)
        chunk = parse_lines(self.reader, data, report, file_id, first_line)
        self._show_rejections()
        if len(chunk):
            self._hold(chunk)
        self._close(final=False)

    def _show_rejections(self) -> None:
        rej = self.reader.report.rejections
        for r in rej[self.stats.rejections_shown :]:
            self.emit({"type": "source", "kind": "rejected", **r.to_dict()})
        self.stats.rejections_shown = len(rej)

    def _heads_of(self, register_id: np.ndarray) -> np.ndarray:
        reg = self.reader.registry
        if len(self._head_of_reg) < reg.n_registers:
            a = reg.arrays()
            done = len(self._head_of_reg)
            extra = []
            heads = reg.heads
            for dev, code in zip(  # once per distinct register: a few hundred
                a["device_id"][done:].tolist(), a["counting_head"][done:].tolist(), strict=True
            ):
                key = (dev, heads.value(code))
                if key not in self._head_keys:
                    self._head_keys[key] = len(self._heads)
                    self._heads.append(key)
                extra.append(self._head_keys[key])
            self._head_of_reg = np.concatenate([self._head_of_reg, np.array(extra, np.int64)])
        return self._head_of_reg[register_id]

    def _hold(self, chunk: DiagChunk) -> None:
        """Hold a chunk's records; a gap longer than the idle gap inside a head's records
        ends that head's run at once (a log read from its start comes in large blocks)."""
        self._held.append(chunk)
        self.stats.records_held += len(chunk)
        heads = self._heads_of(chunk.register_id)
        t = chunk.time_ns
        self.clock_ns = max(self.clock_ns, int(t.max()))
        self._file_clock[chunk.file_id] = max(self._file_clock.get(chunk.file_id, NO_TIME), int(t.max()))
        order = np.lexsort((t, heads))
        hs, ts = heads[order], t[order]
        starts = np.flatnonzero(np.r_[True, hs[1:] != hs[:-1]])
        ends = np.r_[starts[1:], len(hs)]
        # Gaps between consecutive records of one head (sorted by time), found for all heads at once.
        gap_after = np.r_[(np.diff(ts) > self._gap_ns) & (hs[1:] == hs[:-1]), False]
        for h, a, b in zip(hs[starts].tolist(), starts.tolist(), ends.tolist(), strict=True):  # per head
            self._head_file[h] = chunk.file_id
            run = self._open.get(h)
            first, last = int(ts[a]), int(ts[b - 1])
            if run is not None and first - run.last_ns > self._gap_ns:
                self._cuts[h] = max(self._cuts.get(h, NO_TIME), run.last_ns)
                run = None
            inner = np.flatnonzero(gap_after[a : b - 1])
            if len(inner):
                i = a + int(inner[-1])
                self._cuts[h] = max(self._cuts.get(h, NO_TIME), int(ts[i]))
                self._open[h] = _HeadRun(int(ts[i + 1]), last)
            elif run is None:
                self._open[h] = _HeadRun(first, last)
            else:
                run.first_ns = min(run.first_ns, first)
                run.last_ns = max(run.last_ns, last)

    # -- closing runs -----------------------------------------------------
    def _close(self, final: bool) -> None:
        cuts = dict(self._cuts)
        self._cuts.clear()
        for h, run in list(self._open.items()):
            clock = self._file_clock.get(self._head_file.get(h, -1), self.clock_ns)
            if final or run.last_ns < clock - self._gap_ns - self._slack_ns:
                cuts[h] = np.iinfo(np.int64).max
                del self._open[h]
        if cuts:
            self._analyse(self._take(cuts))
        self._release(final)

    def _take(self, cuts: dict[int, int]) -> list[DiagChunk]:
        """Records at or before their head's cut time: out of the held chunks."""
        cut = np.full(len(self._heads), NO_TIME, np.int64)
        for h, t in cuts.items():
            cut[h] = t
        closed, kept = [], []
        for c in self._held:
            mask = c.time_ns <= cut[self._heads_of(c.register_id)]
            if mask.all():
                closed.append(c)
            elif mask.any():
                closed.append(c.take(mask))
                kept.append(c.take(~mask))
            else:
                kept.append(c)
        self._held = kept
        self.stats.records_held = sum(len(c) for c in kept)
        return closed

    def _analyse(self, chunks: list[DiagChunk]) -> None:
        acc = DiagAccumulator(self.reader.registry, keep_releases=True)
        for c in chunks:
            acc.add(c)
        analysis = acc.result(self.settings)
        for p in sorted(analysis.passages_json(), key=lambda p: (p["start"], p["counting_head"])):
            self.stats.passages += 1
            self.emit({"type": "passage", **p})
        if self.layout is None:
            return
        wheel = analysis.wheel_columns or {}
        events: list[DetectionEvent] = []
        if len(wheel.get("time_ns", ())):
            order = np.lexsort((wheel["time_ns"],))
            names = [name for _, name in analysis.heads]
            with_releases = set(wheel["head"][wheel["value"] == 0].tolist())
            for hk, ch, t, v in zip(
                wheel["head"][order].tolist(),
                wheel["channel"][order].tolist(),
                wheel["time_ns"][order].tolist(),
                wheel["value"][order].tolist(),
                strict=True,
            ):  # per wheel record: the counting rules are sequential
                counter = self._counter(names[hk], point_mode=hk not in with_releases)
                if counter is not None:
                    events += counter.feed(int(ch), int(t), int(v))
        for e in events:
            heapq.heappush(self._pending, (e.time_ns, self._seq, e))
            self._seq += 1
        self._health(chunks, events)

    def _counter(self, head: str, point_mode: bool) -> HeadCounter | None:
        lay = self.layout
        if lay is None or not lay.has_head(head):
            return None
        hc = self._counters.get(head)
        if hc is None:
            spec = lay.head(head)
            hc = self._counters[head] = HeadCounter(
                head,
                up_is_sys1_first=spec.up_is_first_channel_first,
                settings=CountingSettings(),
                point_mode=point_mode,
            )
        elif hc.point_mode and not point_mode:
            hc.point_mode = False  # releases seen: the overlap rule applies from now on
        return hc

    def _release(self, final: bool) -> None:
        if self.layout is None:
            return
        if final:
            for hc in self._counters.values():
                for e in hc.flush():
                    heapq.heappush(self._pending, (e.time_ns, self._seq, e))
                    self._seq += 1
            watermark = np.iinfo(np.int64).max
        else:
            # Nothing earlier than an open run's first record can still come.
            watermark = min((r.first_ns for r in self._open.values()), default=self.clock_ns)
            watermark = min(watermark, self.clock_ns)
            for name, hc in self._counters.items():
                key = next((k for k, (_, n) in enumerate(self._heads) if n == name), None)
                run = self._open.get(key) if key is not None else None
                for e in hc.advance(min(watermark, run.first_ns) if run else watermark):
                    heapq.heappush(self._pending, (e.time_ns, self._seq, e))
                    self._seq += 1
        while self._pending and self._pending[0][0] < watermark:
            _, _, e = heapq.heappop(self._pending)
            if self.listener is not None:
                self.listener.detection(e)
            if self.sections is None:
                self.sections = SectionEngine(self.layout, initial=SectionState.PREPARATORY, start_ns=e.time_ns)
            for tr in self.sections.step(e):
                self._section(tr)
        if self.sections is not None:
            drain_history(self.sections)

    def _section(self, tr: Transition) -> None:
        self.stats.section_changes += 1
        if self.listener is not None:
            self.listener.transition(tr)
        from console.analysis.timefmt import iso

        self.emit(
            {
                "type": "section",
                "section": tr.section,
                "state": str(tr.state),
                "count": tr.count,
                "reason": tr.reason,
                "time_ns": tr.time_ns,
                "time": iso(tr.time_ns),
            }
        )

    def _health(self, chunks: list[DiagChunk], events: list[DetectionEvent]) -> None:
        wanted = self.reader.registry.canonical_in(HEALTH_REGISTERS)
        kept = [c.take(wanted[c.register_id]) for c in chunks]
        kept = [c for c in kept if len(c)]
        if not kept and not events:
            return
        records = chunks_to_frame(kept, self.reader.registry)
        lay = self.layout
        bands = {h.id: h.analog_band for h in lay.heads if h.analog_band} if lay else None
        findings: list[Finding] = health_report(records, bands=bands or None, events=events)
        for f in findings:
            key = (f.rule, f.counting_head, f.channel)
            if key in self._seen_findings or str(f.severity) == "info":
                continue
            self._seen_findings.add(key)
            self.stats.health_findings += 1
            self.emit({"type": "health", **f.to_dict()})

    # -- end ---------------------------------------------------------------
    def finish(self) -> None:
        """End of following: every open run is closed and analysed (as the batch reader ends a file)."""
        self._close(final=True)

    def section_states(self) -> dict[str, tuple[str, int]]:
        if self.sections is None:
            return {}
        return {sid: (str(s.state), s.count) for sid, s in self.sections.sections.items()}
