"""The station view's replay of recorded logs: the one live engine fed the records and fixes on their own clock."""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.crossing.controller import CrossingController
from console.analysis.passages.stream import ORDER_SLACK_S
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState, Transition
from console.inputs.base import GnssFix
from console.layout import Layout
from console.live.engine import LiveEngine
from console.plural import count
from console.tui.live_source import take_events
from console.tui.model import LogEntry, TrainView
from console.tui.sources import engine_trains
from parsers.units import NS

if TYPE_CHECKING:
    import pandas as pd

    from console.drivers.batch import ChunkSource
    from parsers.diag.records import DiagChunk
    from parsers.diag.registry import DiagRegistry
    from parsers.report import ParseReport

ORDER_SLACK_NS = int(ORDER_SLACK_S * NS)
INTERLEAVE_NS = NS  # several files' records are fed a second at a time: well inside the order slack
GONE_S = 120.0  # a replayed train not heard for this long has left the line
QUIET_SKIP_S = 300.0  # a replay skips quiet stretches longer than this
LEAD_IN_S = 10  # and resumes this long before the next record


def span(seconds: float) -> str:
    d, rest = divmod(int(seconds), 86400)
    h, rest = divmod(rest, 3600)
    m = rest // 60
    return (f"{d} d " if d else "") + (f"{h} h " if h or d else "") + f"{m} min"


class ReplaySource:
    """Recorded logs played back through the one live engine (``follow``'s), on the recordings' own clock.

    Diagnostic records (from log files, or the archive's) reach the engine's pipeline as they were parsed,
    released up to the replay's clock; GNSS fixes reach its crossing units and integrity monitor as recorded
    fixes, each when the clock passes its time.  The view shows that engine's events and state, as it shows
    ``station --live``'s, at any speed; a jump back replays quietly from the start."""

    mode = "replay"

    def __init__(self, paths: Sequence[Path], layout: Layout) -> None:
        from console.drivers.batch import LogFiles

        diag = [p for p in paths if _is_diag(p)]
        other = [p for p in paths if p not in diag]
        frame = None
        gnss_report = None
        if other and len(layout.track) >= 2:
            from parsers.gnss_files import parse_gnss

            frame, gnss_report, _states = parse_gnss(other)
        self._setup(layout, LogFiles(diag) if diag else None, frame, gnss_report)

    @classmethod
    def from_parts(cls, layout: Layout, records: ChunkSource | None, fixes: pd.DataFrame | None) -> ReplaySource:
        """A replay of diagnostic records from another source (the archive's) and a GNSS fix table at hand."""
        source = cls.__new__(cls)
        source._setup(layout, records, fixes)
        return source

    def _setup(
        self,
        layout: Layout,
        records: ChunkSource | None,
        frame: pd.DataFrame | None,
        gnss_report: ParseReport | None = None,
    ) -> None:
        self.layout = layout
        self._registry, self._files, diag_report = _records_by_file(records)
        # The lines the replay could not read, for the log at the first step (as `station --live` lists a
        # followed file's): nothing the logs hold vanishes unseen.
        self._unread = [r for r in (diag_report, gnss_report) if r is not None]
        self.fixes = _fixes_in_time_order(frame) if frame is not None and len(layout.track) >= 2 else []
        firsts = [int(f.time_ns.min()) for f in self._files]
        lasts = [int(f.time_ns.max()) for f in self._files]
        self.first_record_ns = min(firsts) if firsts else None
        times = firsts + lasts + [f.t_fix_ns for f in self.fixes[:1] + self.fixes[-1:]]
        if not times:
            raise ValueError("nothing to replay: no wheel-sensor records and no placeable GNSS fixes")
        self.start_ns, self.end_ns = min(times) - NS, max(times) + NS
        self._rebuild(self.start_ns)

    def _rebuild(self, t_ns: int) -> None:
        self._now = t_ns
        self._events: list[dict[str, Any]] = []
        self.live = LiveEngine(self.layout, self._emit, clock=lambda: self._now, registry=self._registry)
        self._placeholder = SectionEngine(self.layout, initial=SectionState.PREPARATORY, start_ns=t_ns)
        self.engine: SectionEngine = self._placeholder
        self.crossings: dict[str, CrossingController] = (
            self.live.crossings.controllers if self.live.crossings is not None else {}
        )
        self._cursor = [0] * len(self._files)
        self._i_fix = 0
        self._finished = False
        self._counts: Counter[str] = Counter()

    sink: Callable[[dict[str, Any]], None] | None = None  # another consumer of the engine's events

    def _emit(self, ev: dict[str, Any]) -> None:
        self._events.append(ev)
        if self.sink is not None:
            self.sink(ev)

    @property
    def now_ns(self) -> int:
        return self._now

    def _next_ns(self) -> int | None:
        """The time of the next record or fix still to be played (None: all played)."""
        nxt = [f.reached_ns[c] for f, c in zip(self._files, self._cursor, strict=True) if c < len(f)]
        if self._i_fix < len(self.fixes):
            nxt.append(self.fixes[self._i_fix].t_fix_ns)
        return int(min(nxt)) if nxt else None

    def _play(self, target: int) -> None:
        """Everything recorded up to ``target`` into the engine, files interleaved a second at a time."""
        while (nxt := self._next_ns()) is not None and nxt <= target:
            until = min(target, nxt + INTERLEAVE_NS)
            for k, f in enumerate(self._files):
                c = self._cursor[k]
                j = int(np.searchsorted(f.reached_ns, until, side="right"))
                if j > c:
                    self.live.diag.feed(f.chunk.take(slice(c, j)))  # type: ignore[arg-type]
                    self._cursor[k] = j
            while self._i_fix < len(self.fixes) and self.fixes[self._i_fix].t_fix_ns <= until:
                self.live.handle(self.fixes[self._i_fix])
                self._i_fix += 1
        # No record still to play is earlier than the clock less the order slack a log may have.
        self.live.diag.advance(target - ORDER_SLACK_NS)
        self.live.tick(recorded_until_ns=target)  # no fix still to play was measured before the clock
        if target >= self.end_ns and not self._finished:
            self._finished = True
            self.live.finish()
        self.engine = self.live.diag.sections or self._placeholder

    def advance(self, seconds: float, skip_quiet: bool = True) -> tuple[list[Transition], list[LogEntry]]:
        skipped = self._unread_notes() + (self._skip_quiet() if skip_quiet else [])
        target = min(self.end_ns, self._now + int(seconds * NS))
        self._now = max(self._now, target)
        self._play(self._now)
        transitions, entries = take_events(self._events, self._counts, self._now)
        return transitions, skipped + entries

    def _unread_notes(self) -> list[LogEntry]:
        """The replayed files' rejected lines, as warnings, once (the first step after the logs are read)."""
        entries: list[LogEntry] = []
        for report in self._unread:
            entries += [
                LogEntry(self._now, "warning", f"rejected {r.file}:{r.line}: {r.reason}") for r in report.rejections
            ]
            more = report.rejected - len(report.rejections)
            if more > 0:
                entries.append(LogEntry(self._now, "warning", f"and {count(more, 'more rejected line')}"))
        self._unread = []
        return entries

    def _skip_quiet(self) -> list[LogEntry]:
        """Logs from different days leave hours of nothing between them: with no
        train in view, go straight to a little before the next record."""
        nxt = self._next_ns()
        if nxt is None or self.trains():
            return []
        to = nxt - LEAD_IN_S * NS
        if to - self._now < QUIET_SKIP_S * NS:
            return []
        gap_s = (to - self._now) / NS
        self._now = to
        return [LogEntry(to, "info", f"nothing in the logs for {span(gap_s)}: skipped to the next record")]

    def jump(self, seconds: float) -> tuple[list[Transition], list[LogEntry]]:
        """Jump in time: forward, what happened on the way (for the log); backwards, replayed from the start
        quietly up to the target (nothing new happened)."""
        target = min(self.end_ns, max(self.start_ns, self._now + int(seconds * NS)))
        back = target < self._now
        if back:
            self._rebuild(self.start_ns)
        passed = self.advance((target - self._now) / NS, skip_quiet=False)
        return ([], []) if back else passed

    def trains(self, truth: bool = False) -> list[TrainView]:
        """The trains placed where their units' last fixes put them; one not heard for two minutes has left."""
        return engine_trains(self.live, self._now, GONE_S)

    def true_count(self, section_id: str) -> int | None:
        return None

    def head_counts(self) -> dict[str, int]:
        return dict(self._counts)


@dataclass
class _FileRecords:
    """One file's parsed records in read order, and the latest time reached at each (the replay's gate: a
    record a little out of order goes with its neighbours, as the log has it)."""

    chunk: DiagChunk
    reached_ns: np.ndarray

    def __len__(self) -> int:
        return len(self.chunk)

    @property
    def time_ns(self) -> np.ndarray:
        return self.chunk.time_ns


def _records_by_file(
    records: ChunkSource | None,
) -> tuple[DiagRegistry | None, list[_FileRecords], ParseReport | None]:
    """Every record of ``records``, parsed once, per file in read order (with the registry they refer to, and
    the report of the lines read)."""
    if records is None:
        return None, [], None
    from console.drivers.batch import ReadOptions
    from parsers.diag.records import DiagChunk

    registry, chunks, report = records.open(ReadOptions())
    by_file: dict[int, list[DiagChunk]] = {}
    for chunk in chunks:
        if len(chunk):
            by_file.setdefault(chunk.file_id, []).append(chunk)
    out = []
    for file_id, parts in sorted(by_file.items()):
        fields = [np.concatenate([getattr(p, name) for p in parts]) for name in _CHUNK_FIELDS]
        chunk = DiagChunk(file_id, *fields)
        out.append(_FileRecords(chunk, np.maximum.accumulate(chunk.time_ns)))
    return registry, out, report


_CHUNK_FIELDS = ("register_id", "time_ns", "subsecond", "value", "data_code", "data_kind", "line")


def _fixes_in_time_order(frame: pd.DataFrame) -> list[GnssFix]:
    """The GNSS rows' fixes (as a followed file's become), each file's as its own source, in time order."""
    from console.inputs.file_gnss import fix_items

    fixes: list[GnssFix] = []
    for file, rows in frame.groupby("file", sort=False, observed=True):
        fixes += fix_items(str(file), rows)[0]
    fixes.sort(key=lambda f: f.t_fix_ns)
    return fixes


def _is_diag(path: Path) -> bool:
    from parsers.sources import open_input

    try:
        stream, raw, _ = open_input(path)
    except Exception:
        return False
    try:
        head = stream.read(4096)
    finally:
        stream.close()
        raw.close()
    return any(line.strip().startswith(b"Diag_id:") for line in head.splitlines()[:5])
