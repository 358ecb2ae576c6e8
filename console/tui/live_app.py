"""The station view on live feeds: the same app, plus one status line per source."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.css.query import NoMatches
from textual.widgets import Header, Static

from console.analysis.timefmt import display
from console.tui.app import StationApp
from console.tui.live_source import LiveSource, status_line
from console.tui.model import StationModel


class LiveStationApp(StationApp):
    """:class:`StationApp` over a :class:`LiveSource`: wall-clock time, a source panel."""

    TITLE = "trackside station · live"
    CSS = (
        StationApp.CSS
        + """
    #sources { height: auto; max-height: 6; color: $text-muted; padding: 0 1; }
    """
    )

    def __init__(self, source: LiveSource, *, autoplay: bool = True) -> None:
        super().__init__(StationModel(source), autoplay=autoplay)
        self.live_source = source

    def compose(self) -> ComposeResult:
        for widget in super().compose():
            yield widget
            if isinstance(widget, Header):
                yield Static("", id="sources", markup=False)

    def refresh_views(self) -> None:
        try:
            super().refresh_views()
        except NoMatches:
            return  # a redraw that lands after the screen has gone (the app is closing)
        src = self.live_source
        snap_time = display(src.now_ns)[:19]
        self.sub_title = f"live · {snap_time} · {len(src.sources)} source(s)"
        lines = [status_line(s) for s in src.statuses()] or ["no sources"]
        self.query_one("#sources", Static).update("\n".join(lines))

    def on_unmount(self) -> None:
        self.live_source.stop()
