"""The station view on live feeds: the same app, plus one status line per source.

Redraws follow the data, not a fixed timer: each source thread, after
queuing an item, posts one :class:`DataArrived` to the app (at most one is
pending, so a flood of items is one wake-up), and the app advances the model
on its worker thread and redraws at once.  Under a flood the advances are at
least :data:`MIN_GAP_S` apart (20 redraws a second at most); with nothing
arriving a slow timer redraws the clock and the sources' ages and gives the
crossing units their clock.
"""

from __future__ import annotations

import time

from textual import on
from textual.app import ComposeResult
from textual.css.query import NoMatches
from textual.message import Message
from textual.widgets import Header, Static

from console.analysis.timefmt import display
from console.live.engine import TICK_S as STATUS_S
from console.tui.app import StationApp
from console.tui.live_source import LiveSource, status_line
from console.tui.model import Snapshot, StationModel

MIN_GAP_S = 0.05  # between two advances under a flood: at most 20 redraws a second


class DataArrived(Message):
    """A source queued an item (posted from the source's thread)."""


class LiveStationApp(StationApp):
    """:class:`StationApp` over a :class:`LiveSource`: wall-clock time, a source panel, redrawn on data."""

    TITLE = "trackside station"
    CSS = (
        StationApp.CSS
        + """
    #sources { height: auto; max-height: 6; color: $text-muted; padding: 0 1; }
    """
    )

    def __init__(self, source: LiveSource, *, autoplay: bool = True) -> None:
        # The base class's fixed 0.1 s timer is off: this app wakes on data (and on a slow status timer).
        super().__init__(StationModel(source), autoplay=False)
        self.live_source = source
        self.follow_live = autoplay
        self._signalled = False  # a DataArrived is posted and not yet handled
        self._again = False  # data arrived while an advance ran: advance once more after it
        self._timer_set = False
        self._last_start = 0.0
        self.advances = 0
        self._sources_shape: tuple[int, tuple[int, ...]] = (0, ())

    def compose(self) -> ComposeResult:
        for widget in super().compose():
            yield widget
            if isinstance(widget, Header):
                yield Static("", id="sources", markup=False)

    def on_mount(self) -> None:
        if self.follow_live:
            self.live_source.on_data = self._data_arrived
            self.set_interval(STATUS_S, self._wake)
            self._wake()  # starts the sources

    # -- waking on data ----------------------------------------------------------
    def _data_arrived(self) -> None:
        """Called in a source's thread for every item: one message per wake-up, not per item."""
        if not self._signalled:
            self._signalled = True
            self.post_message(DataArrived())

    @on(DataArrived)
    def _on_data(self) -> None:
        self._signalled = False
        self._wake()

    def _wake(self) -> None:
        # A wake-up that comes while the app shuts down (a tick's end, a source's message, the gap timer)
        # starts nothing: a worker started then would tick a closed app and call back into it.
        if self.model.paused or not self.is_running:
            return
        if self._busy:
            self._again = True
            return
        wait = self._last_start + MIN_GAP_S - time.monotonic()
        if wait > 0:
            if not self._timer_set:
                self._timer_set = True
                self.set_timer(wait, self._on_gap_timer)
            return
        self._busy = True
        self._last_start = time.monotonic()
        self.advances += 1
        self._advance_worker(STATUS_S)

    def _on_gap_timer(self) -> None:
        self._timer_set = False
        self._wake()

    def _after_advance(self) -> None:
        super()._after_advance()
        if not self.is_running:
            return
        if self._again or self.live_source.pending():
            self._again = False
            self._wake()
            return
        # A crossing warning falls due at its instant: wake then if that is before the steady interval.
        due_s = self.live_source.live.next_wake_s()
        if due_s is not None and due_s < STATUS_S:
            self.set_timer(due_s, self._wake)

    # -- drawing -------------------------------------------------------------------
    def subtitle(self, snap: Snapshot) -> str:
        # Steady: the clock ticks in the sources panel, which is redrawn without a new layout.
        n = len(self.live_source.sources)
        return f"live · {n} source{'' if n == 1 else 's'}"

    def refresh_views(self) -> None:
        try:
            super().refresh_views()
        except NoMatches:
            return  # a redraw that lands after the screen has gone (the app is closing)
        src = self.live_source
        paused = " · paused" if self.model.paused else ""
        clock = "log time" if src.live.recordings_only else "time"
        lines = [f"{clock} {display(src.now_ns)[:19]}{paused}", *(status_line(s) for s in src.statuses())]
        panel = self.query_one("#sources", Static)
        # The ages in these lines change at every redraw; the panel's height only when a line is
        # added or starts or stops wrapping: re-lay out the screen only then (a layout costs a full repaint).
        width = max(1, panel.content_size.width)
        shape = (len(lines), tuple(len(line) // width for line in lines))
        panel.update("\n".join(lines), layout=shape != self._sources_shape)
        self._sources_shape = shape

    def on_unmount(self) -> None:
        self.live_source.on_data = None
        self.live_source.stop()
