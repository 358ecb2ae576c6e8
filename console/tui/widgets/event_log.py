"""The event log, newest last, filtered by severity."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

from console.analysis.timefmt import display
from console.safe_text import inert
from console.tui.model import LogEntry
from console.tui.widgets.quiet import retitle, update_if_changed

SEVERITY_STYLE = {"info": "dim", "warning": "yellow", "critical": "bold red"}
SEVERITY_MARK = {"info": "·", "warning": "!", "critical": "‼"}


class EventLog(Static):
    """The last entries that fit, at or above the chosen severity (f cycles it)."""

    DEFAULT_CSS = """
    EventLog { height: 1fr; width: 3fr; border: round $secondary; padding: 0 1; }
    """

    def render_entries(self, entries: list[LogEntry], least: str) -> None:
        lines = max(1, (self.size.height or 8) - 2)
        width = max(10, (self.size.width or 80) - 4)
        # Newest last, as many as fit once long entries wrap (measured, not guessed).
        shown: list[Text] = []
        for e in reversed(entries):
            line = Text(f"{SEVERITY_MARK[e.severity]} {display(e.time_ns)[11:19]} ", style=SEVERITY_STYLE[e.severity])
            line.append_text(inert(e.text, style=SEVERITY_STYLE[e.severity]))
            need = len(line.wrap(self.app.console, width))
            if need > lines:
                break
            lines -= need
            shown.append(line)
        out = Text("\n").join(reversed(shown))
        retitle(self, title=f"Events ({least} and above)")
        update_if_changed(self, out)
