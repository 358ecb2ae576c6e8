"""The live engine: items from any source → the analysis core → events.

Events are plain dicts with a ``type`` (``passage``, ``section``,
``crossing``, ``integrity``, ``health``, ``source``), the JSON lines of
``trackside follow --jsonl``.  The engine runs on one thread (the caller's); sources only queue
items, so the analysis state needs no locks.
"""

from __future__ import annotations

import queue
import signal
import time
from collections.abc import Callable, Sequence
from typing import Any

from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.state import SectionState
from console.engine.fixes import FixStage
from console.inputs.base import CanFrame, FrameRows, GnssFix, Item, LineBlock, Source, SourceNote
from console.layout import Layout
from console.live.archive import LiveArchiver
from console.live.backlog import Backlog
from console.live.diag import DiagFollow
from console.live.frames import FrameFollow
from parsers.diag.registry import DiagRegistry
from parsers.units import ALL_TIME, NS

Emit = Callable[[dict[str, Any]], None]
TICK_S = 0.5  # crossing units' clock and the idle wake-up: two a second is nothing for the CPU
STOP_QUIET_S = 3.0  # stopping: a source's thread that delivers nothing for this long is left behind
STOP_ABANDON_S = 1.0  # an abandoned source's thread ends within this (a file's reader: at its next block)
STOP_TELL_S = 1.0  # stopping takes longer than this (a big file's last read): say so, and how to cut it short


class LiveEngine:
    def __init__(
        self,
        layout: Layout | None,
        emit: Emit,
        settings: SpeedSettings | None = None,
        archiver: LiveArchiver | None = None,
        include_status: bool = False,
        *,
        clock: Callable[[], int] | None = None,
        initial: SectionState = SectionState.PREPARATORY,
        registry: DiagRegistry | None = None,
    ) -> None:
        """``settings``: the line facts (default: the layout's, as ``follow`` takes them); ``clock``: the
        console's clock in ns since the epoch (default: the wall clock; the simulator's station gives its
        own); ``initial``: the sections' state before the first detection; ``registry``: the one the records fed
        as parsed chunks were parsed into (a replay)."""
        self.layout = layout
        self.emit = emit
        self.include_status = include_status
        self._clock = clock or time.time_ns
        # Train integrity needs the fixes placed on the track: a layout with a [[track]].
        self.fixes = FixStage(layout, emit) if layout is not None else None
        self.integrity = self.fixes.integrity if self.fixes is not None else None
        self.diag = DiagFollow(
            layout,
            settings or SpeedSettings.of_layout(layout),
            emit,
            include_status=include_status,
            also=self.integrity,
            initial=initial,
            registry=registry,
        )
        self.crossings = self.fixes.crossings if self.fixes is not None else None
        self.frames = FrameFollow(layout, emit)
        if self.integrity is not None:
            self.frames.listener = self.integrity
        self.archiver = archiver
        self.can_frames = 0
        self.file_frames = 0  # count frames read from followed CAN and frame logs
        self.items = 0
        self.notes: dict[str, int] = {}
        # What a second interrupt left unanalysed: each file's first line not analysed, and other items.
        self.not_analysed: dict[str, int] = {}
        self.items_not_analysed = 0

    def now_ns(self) -> int:
        """The console's clock."""
        return self._clock()

    # A recorded file's fixes are judged by its own clock (it may be read far faster or slower than it was
    # written: a replay, `simulate --live --speed 30`); a live unit's by the console's, which ticks on too.
    _data_ns: int | None = None
    _live_fixes = False

    def _fix_clock(self, item: GnssFix) -> int:
        if item.recorded:
            self._data_ns = item.t_fix_ns if self._data_ns is None else max(self._data_ns, item.t_fix_ns)
            return item.t_fix_ns
        self._live_fixes = True
        return self.now_ns()

    def crossing_clock_ns(self) -> int:
        """The crossing units' clock: the console's, or the recordings' own when every fix comes from files."""
        if self._live_fixes or self._data_ns is None:
            return self.now_ns()
        return self._data_ns

    @property
    def recordings_only(self) -> bool:
        """Everything followed so far comes from files (the view runs on their clock)."""
        return not (self._live_fixes or self._live_bus)

    def view_clock_ns(self) -> int:
        """The clock a view shows: the recordings' own (the latest time they hold) when everything comes from
        files, as every event they give is stamped; the console's when a live unit or bus is followed."""
        if self._live_fixes or self._live_bus:
            return self.now_ns()
        clocks = [c for c in (self._data_ns, self.diag.clock_ns) if c is not None]
        return max(clocks) if clocks else self.now_ns()

    _live_bus = False

    def handle(self, item: Item) -> None:
        self.items += 1
        if self.archiver is not None:
            self.archiver(item)
        if isinstance(item, LineBlock):
            self.diag.add(item.source, item.file, item.first_line, item.data)
        elif isinstance(item, GnssFix):
            if self.fixes is not None and self.crossings is not None:  # placed on a track (the clocks too)
                self.fixes.take(item, self._fix_clock(item))
        elif isinstance(item, CanFrame):
            self._live_bus = True
            self.can_frames += 1
            self.frames.add(item)
        elif isinstance(item, FrameRows):
            self.file_frames += len(item)
            self.frames.add_rows(item)
        elif isinstance(item, SourceNote):
            self.notes[item.kind] = self.notes.get(item.kind, 0) + 1
            self.emit({"type": "source", "source": item.source, "kind": item.kind, "detail": item.detail})

    def idle(self) -> None:
        """Nothing more is queued: analyse what is buffered (CAN frames come one by one, are analysed in blocks)."""
        self.frames.flush()

    def tick(self, recorded_until_ns: int | None = None) -> None:
        """Time passes.  ``recorded_until_ns``: no recorded fix still to come is earlier than or at this
        (the simulator knows its radio's delay); without it, the latest recorded fix's time."""
        self.frames.flush()
        self._tick_crossings(recorded_until_ns)
        if self.integrity is not None:
            self.integrity.tick()
        if self.archiver is not None:
            self.archiver.tick()

    def next_wake_s(self) -> float | None:
        """Seconds until a live crossing unit has something due (a warning, a unit going stale): the
        console's clock wakes then, not only every TICK_S.  None: nothing pending, or the units run on
        the recordings' clock (their ticks come with the recordings)."""
        if self.crossings is None or not self._live_fixes:
            return None
        now = self.now_ns()
        wake = self.crossings.next_wake_ns(now)
        return None if wake is None else max(0.0, (wake - now) / NS)

    def _tick_crossings(self, recorded_until_ns: int | None) -> None:
        if self.crossings is None:
            return
        if self._live_fixes:  # a live unit: the console's clock
            self.crossings.tick(self.now_ns())
        else:  # recordings: the units' ticks as their own clock is known to have passed them
            until = recorded_until_ns if recorded_until_ns is not None else self._data_ns
            if until is not None:
                self.crossings.advance(until)

    def reset_section(self, section: str) -> None:
        """An operator's reset request, now: decided in time order with the detections (a ``reset`` event)."""
        self.diag.reset(section, self.view_clock_ns())

    def finish(self) -> None:
        self.diag.finish()
        self.frames.finish()
        # Recordings end: every tick the units' clocks still owe (the batch run's last ticks).
        self._tick_crossings(None if self._live_fixes else int(ALL_TIME))
        if self.archiver is not None:
            self.archiver.finish()

    def summary(self, sources: Sequence[Source]) -> dict[str, Any]:
        rep = self.diag.reader.report
        files = [
            {
                "file": f.file,
                "lines_read": f.lines_read,
                "records": f.records,
                "blank": f.blank,
                "rejected": f.rejected,
            }
            for f in rep.files
        ]
        files += [f for s in sources for f in s.file_reports()]
        return {
            "type": "summary",
            "passages": self.diag.stats.passages + self.frames.stats.passages,
            "section_changes": self.diag.stats.section_changes + self.frames.stats.section_changes,
            "health_findings": self.diag.stats.health_findings + self.frames.stats.health_findings,
            "crossing_events": self.crossings.events if self.crossings else 0,
            "integrity_events": self.integrity.events if self.integrity else 0,
            "gnss_fixes": self.crossings.fixes if self.crossings else 0,
            **(
                {"gnss_fixes_bad_clock": self.crossings.placer.bad_clock}
                if self.crossings and self.crossings.placer.bad_clock
                else {}
            ),
            "can_frames": self.can_frames,
            "file_frames": self.file_frames,
            "files": files,
            **(
                {
                    "not_analysed": [{"file": f, "from_line": n} for f, n in self.not_analysed.items()],
                    "items_not_analysed": self.items_not_analysed,
                }
                if self.not_analysed or self.items_not_analysed
                else {}
            ),
            **(self.archiver.summary() if self.archiver is not None else {}),
            "sections": {k: {"state": s, "count": c} for k, (s, c) in self.section_states().items()},
            "sources": [s.status().to_dict() for s in sources],
            # A board's status dumps make a passage each, train or not: counted, listed on request (as analyze).
            **({} if self.include_status else {"status_only_passages": self.diag.status_passages}),
        }

    def section_states(self) -> dict[str, tuple[str, int]]:
        """Sections as the diagnostic log says, else as the CAN frames say (a line has one or the other)."""
        return self.diag.section_states() or self.frames.section_states()


def run_sources(
    engine: LiveEngine,
    sources: Sequence[Source],
    *,
    until: Callable[[], bool] | None = None,
    duration_s: float | None = None,
    tell: Callable[[str], None] | None = None,
) -> int | None:
    """Start the sources, feed their items to the engine until ``until()``, the duration, the end of
    every source's input (streams: their writers closed them), or Ctrl-C / SIGTERM; then stop them and
    finish the engine.  Returns the signal that ended it.

    The signals only set a flag (from the main thread): an item is never cut half-way through
    its analysis, and what the sources delivered before stopping is still analysed (a followed
    file is read to its end, in bounded memory).  A second signal while that takes long stops at
    once: the rest is recorded in the engine's ``not_analysed``.  ``tell`` hears, once, that the
    stop takes long.
    """
    q = Backlog()  # bounded: a big file followed from its start is read as fast as it is analysed
    started: list[Source] = []
    deadline = None if duration_s is None else time.monotonic() + duration_s
    stopped_by: list[int] = []
    previous: dict[int, Any] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[sig] = signal.signal(sig, lambda signum, _frame: stopped_by.append(signum))
        except ValueError:  # not the main thread: the caller stops us through ``until``
            break
    try:
        for s in sources:
            s.start(q.putter(s))
            started.append(s)
        next_tick = time.monotonic() + TICK_S
        while not stopped_by:
            now = time.monotonic()
            if (until is not None and until()) or (deadline is not None and now >= deadline):
                break
            if all(s.input_ended for s in started) and q.empty():
                break  # every source's input ended (streams whose writers closed them), all of it analysed
            # A crossing warning falls due at its instant, not at the next steady tick.
            due_s = engine.next_wake_s()
            wake_at = next_tick if due_s is None else min(next_tick, now + due_s)  # next_tick ≤ now + TICK_S
            try:
                item: Item | None = q.get(max(0.0, wake_at - now))
            except queue.Empty:
                item = None
            if item is not None:
                engine.handle(item)
                if q.empty():
                    engine.idle()
            if time.monotonic() >= wake_at:
                engine.tick()
                if time.monotonic() >= next_tick:
                    next_tick = time.monotonic() + TICK_S
    finally:
        for s in started:
            s.request_stop()
        again = len(stopped_by) + 1  # one more signal than ended the run
        _drain_while_stopping(q, engine, started, cut_short=lambda: len(stopped_by) >= again, tell=tell)
        engine.not_analysed, engine.items_not_analysed = q.not_analysed()
        engine.finish()
        for restored, handler in previous.items():
            signal.signal(restored, handler)
    return stopped_by[0] if stopped_by else None


def _drain_while_stopping(
    q: Backlog,
    engine: LiveEngine,
    sources: Sequence[Source],
    cut_short: Callable[[], bool],
    tell: Callable[[str], None] | None,
) -> None:
    """What the sources deliver while they stop (a followed file is read to its end) is still analysed:
    the backlog is drained for as long as any of their threads runs, not for a fixed time, so a long last
    read on a busy machine is not cut off.  A thread that delivers nothing for ``STOP_QUIET_S`` (blocked
    on a device that never answers) is left behind.  ``cut_short()`` (a second Ctrl-C) abandons the
    sources and closes the backlog: what was not analysed is recorded there."""
    began = quiet_since = time.monotonic()
    told = False
    while True:
        if cut_short():
            q.abandon(sources, STOP_ABANDON_S)
            return
        if tell is not None and not told and time.monotonic() - began > STOP_TELL_S:
            told = True
            tell(
                "stopping: analysing what the sources still deliver (a followed file to its end); Ctrl-C stops at once"
            )
        try:
            engine.handle(q.get(0.05))
            quiet_since = time.monotonic()
        except queue.Empty:
            if not any(s.running for s in sources) or time.monotonic() - quiet_since > STOP_QUIET_S:
                break
    while True:  # what came in as the last thread ended
        try:
            engine.handle(q.get())
        except queue.Empty:
            break
