"""The help screen: every key, what it does, and how to read the diagram."""

from __future__ import annotations

from typing import ClassVar

from rich import box
from rich.console import Group
from rich.table import Table
from rich.text import Text
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Static

KEYS: tuple[tuple[str, str], ...] = (
    ("space", "pause / resume"),
    ("+ / -", "faster / slower (1× … 1000× real time)"),
    (".", "one step (one simulated second), also while paused"),
    ("s / S", "select the next / previous section (or click its row)"),
    ("w / W", "select the next / previous train (or click its row)"),
    (
        "r",
        "reset the selected section: refused, with the reason, while a head is damped, "
        "a channel is faulty or power is lost; otherwise preparatory until a sweep train",
    ),
    ("1", "fault: dead channel (Sys2) at the selected section's first head"),
    ("2", "fault: isolated pulse at that head"),
    ("3", "fault: power loss at that head for 5 minutes"),
    ("4", "fault: the selected train's end-of-train unit lost"),
    ("5", "fault: the selected train's head unit lost"),
    ("6", "fault: the selected train parts; its rear half, with the EOT unit, brakes to a stop"),
    ("a", "add a train (it enters behind the others once the entry is clear)"),
    ("v", "show the simulator's truth beside the console (differences underlined)"),
    ("f", "event log: cycle the least severity shown"),
    ("] / [", "replay: jump 5 minutes forward / back (simulation: ] runs 5 minutes on)"),
    ("?", "this help (escape closes it)"),
    ("q", "quit"),
)

LEGEND = (
    "Section marks, readable without colour: · clear, # occupied, ! disturbed, ? preparatory.\n"
    "Crossings: ●● lights flashing (seconds until the next head arrives), ▼ barriers down, "
    "○▲ road open.\n"
    "Trains: ▶/◀ direction, id and km/h; heads: ┃id:axles counted.\n"
    "The view shows what the console derives from the devices' reports, never the simulator's "
    "truth — except in the truth view, where the truth sits beside it."
)


def help_text() -> Group:
    table = Table(box=box.SIMPLE_HEAD, expand=True, show_edge=False)
    table.add_column("key", style="bold", no_wrap=True)
    table.add_column("what it does", ratio=1)
    for key, what in KEYS:
        table.add_row(key, what)
    return Group(Text("trackside station — keys", style="bold"), table, Text(LEGEND, style="dim"))


class HelpScreen(ModalScreen[None]):
    BINDINGS: ClassVar[list[BindingType]] = [Binding("escape,q,question_mark", "dismiss", "Close")]
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 90%; height: 90%; border: thick $primary; background: $surface; padding: 0 1; }
    """

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Static(help_text())

    def action_dismiss(self) -> None:  # type: ignore[override]
        self.dismiss(None)
