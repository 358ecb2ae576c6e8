"""Live sources for the station view: what follow's engine derives, shown as it happens.

The view's clock is the wall clock: :meth:`LiveSource.advance` ignores the
playback speed and takes whatever the sources delivered since the last call.
Sections come from the live engine's section engine (all preparatory until
the first detection), trains from the last fixes of their units, crossings
from the live crossing units.
"""

from __future__ import annotations

import queue
import time
from collections import Counter
from collections.abc import Callable, Sequence
from typing import Any

from console.analysis.crossing.controller import CrossingController
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState, Transition
from console.inputs.base import Item, Source, SourceStatus
from console.layout import Layout
from console.live.backlog import Backlog
from console.live.engine import LiveEngine
from console.tui.model import LogEntry, TrainView
from console.tui.sources import engine_trains, integrity_entry

LIVE_GONE_S = 300.0  # a live train not heard for this long has left the line
MAX_ITEMS_PER_ADVANCE = 20_000  # a burst is taken over several redraws, the view stays responsive
STOP_WAIT_S = 3.0  # closing the view: each source's thread gets this long to end


def _iso_ns(text: Any) -> int | None:
    """An event's ISO time (``…Z``) in ns since the epoch (None: not one)."""
    import datetime as dt

    if not isinstance(text, str):
        return None
    try:
        t = dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    return (t - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)) // dt.timedelta(microseconds=1) * 1000


def take_events(
    events: list[dict[str, Any]], axles_by_head: Counter[str], now_ns: int
) -> tuple[list[Transition], list[LogEntry]]:
    """The console's events since the last call (``events`` is emptied), as the view's section changes and log
    entries; each passage's axles added to its head's count."""
    taken, events[:] = list(events), []
    transitions: list[Transition] = []
    entries: list[LogEntry] = []
    for ev in taken:
        if ev.get("type") == "passage":
            axles_by_head[str(ev["counting_head"])] += int(ev.get("axles") or 0)
        tr, entry = event_entry(ev, now_ns)
        if tr is not None:
            transitions.append(tr)
        if entry is not None:
            entries.append(entry)
    return transitions, entries


def event_entry(ev: dict[str, Any], now_ns: int) -> tuple[Transition | None, LogEntry | None]:
    """An event as the view shows it, at the time it happened in the log (``now_ns``: when it says none)."""
    kind = ev.get("type")
    t = int(ev.get("time_ns") or _iso_ns(ev.get("end")) or _iso_ns(ev.get("time")) or now_ns)
    if kind == "section":
        return Transition(t, ev["section"], SectionState(ev["state"]), int(ev["count"]), ev["reason"]), None
    if kind == "crossing":
        verb = {"on": "warning ON", "off": "road given back", "alarm": "ALARM"}.get(ev["kind"], ev["kind"])
        sev = "warning" if ev["kind"] == "alarm" else "info"
        return None, LogEntry(t, sev, f"crossing {ev['crossing']} {verb} (train {ev['train']}): {ev['reason']}")
    if kind == "reset":
        verdict = "reset accepted" if ev["accepted"] else "reset REFUSED"
        return None, LogEntry(t, "warning", f"section {ev['section']}: {verdict} — {ev['reason']}")
    if kind == "integrity":
        return None, integrity_entry(t, ev["train"], ev["state"], ev["evidence"])
    if kind == "passage":
        speed = ev.get("speed_kmh_whole_train")
        sp = f", {speed:.1f} km/h" if isinstance(speed, int | float) else ""
        return None, LogEntry(t, "info", f"passage at {ev['counting_head']}: {ev['axles']} axles{sp}")
    if kind == "health":
        sev = "critical" if ev.get("severity") == "critical" else "warning"
        return None, LogEntry(t, sev, f"health {ev['rule']} {ev.get('counting_head') or ''}: {ev['message']}")
    if kind == "source":
        if ev.get("kind") == "rejected":
            return None, LogEntry(now_ns, "warning", f"rejected {ev['file']}:{ev['line']}: {ev['reason']}")
        sev = (
            "warning"
            if ev.get("kind") in ("disconnected", "malformed", "lost", "unrecognised", "clock_step")
            else "info"
        )
        return None, LogEntry(now_ns, sev, f"source {ev.get('source', '')}: {ev.get('kind')} {ev.get('detail', '')}")
    return None, None


class LiveSource:
    """The station view's source over live feeds (files, gpsd, MQTT, CAN)."""

    mode = "live"

    def __init__(
        self, layout: Layout, sources: Sequence[Source], sink: Callable[[dict[str, Any]], None] | None = None
    ) -> None:
        self.layout = layout
        self.sources = list(sources)
        self._events: list[dict[str, Any]] = []
        self.sink = sink  # another consumer of the engine's events (the Prometheus metrics)
        self.live = LiveEngine(layout, self._emit)
        self._queue = Backlog()  # bounded: a file read faster than it is analysed waits
        self._placeholder = SectionEngine(layout, initial=SectionState.PREPARATORY, start_ns=time.time_ns())
        self._counts: Counter[str] = Counter()
        self.started = False
        # Called from the sources' threads after each item is queued: the app wakes on data, not on a timer.
        self.on_data: Callable[[], None] | None = None
        # The live engine makes its section engine at the first detection; until then all are preparatory.
        self.engine: SectionEngine = self._placeholder
        self.crossings: dict[str, CrossingController] = (
            self.live.crossings.controllers if self.live.crossings is not None else {}
        )

    def _emit(self, ev: dict[str, Any]) -> None:
        self._events.append(ev)
        if self.sink is not None:
            self.sink(ev)

    def start(self) -> None:
        for s in self.sources:
            s.start(self._putter(s))
        self.started = True

    def _putter(self, source: Source) -> Callable[[Item], None]:
        put = self._queue.putter(source)

        def put_and_wake(item: Item) -> None:
            put(item)
            wake = self.on_data
            if wake is not None:
                wake()

        return put_and_wake

    def pending(self) -> bool:
        """Items are waiting (a burst larger than one advance takes)."""
        return not self._queue.empty()

    def stop(self) -> None:
        """The view closes: nothing more is shown, so a followed file's last read is not wanted, and a reader
        waiting for room in the backlog is let go."""
        self._queue.abandon(self.sources, STOP_WAIT_S)

    @property
    def now_ns(self) -> int:
        """The view's clock: the logs' own time when every source is a recorded file (the events it shows are
        stamped so), else the console's."""
        return self.live.view_clock_ns()

    def advance(self, seconds: float) -> tuple[list[Transition], list[LogEntry]]:
        """Take what arrived (``seconds`` is the playback step: live runs on the wall clock)."""
        if not self.started:
            self.start()
        for _ in range(MAX_ITEMS_PER_ADVANCE):
            try:
                self.live.handle(self._queue.get())
            except queue.Empty:
                break
        self.live.tick()
        self.engine = self.live.diag.sections or self.live.frames.sections or self._placeholder
        return take_events(self._events, self._counts, self.now_ns)

    def trains(self, truth: bool = False) -> list[TrainView]:
        """The trains placed where their units' last fixes put them; one not heard for five minutes has left."""
        return engine_trains(self.live, self.now_ns, LIVE_GONE_S)

    def true_count(self, section_id: str) -> int | None:
        return None

    def head_counts(self) -> dict[str, int]:
        return dict(self._counts)

    def statuses(self) -> list[SourceStatus]:
        return [s.status() for s in self.sources]


def status_line(s: SourceStatus) -> str:
    """One line per source: connected, last message age, rate, losses."""
    from console.safe_text import clean

    age = "never" if s.last_message_age_s is None else f"{s.last_message_age_s:.1f} s ago"
    state = "connected" if s.connected else "ended" if s.detail.startswith("ended") else "DOWN"
    return clean(
        f"{s.uri}: {state} · last {age} · {s.rate_per_s:.1f}/s · lost {s.lost} · malformed {s.malformed}"
        f" · dup {s.duplicates}"
    )
