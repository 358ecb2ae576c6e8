"""The help screen: every key, what it does."""

from __future__ import annotations

from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Markdown

HELP = """\
# trackside station — keys

| key | what it does |
|---|---|
| **space** | pause / resume |
| **+** / **-** | faster / slower (1× … 1000× real time) |
| **.** | one step (one simulated second), also while paused |
| **s** / **S** | select the next / previous section |
| **w** / **W** | select the next / previous train |
| **r** | reset the selected section: refused, with the reason, while a head is damped, |
| | a channel is faulty or power is lost; otherwise preparatory until a sweep train |
| **1** | fault: dead channel (Sys2) at the selected section's first head |
| **2** | fault: isolated pulse at that head |
| **3** | fault: power loss at that head for 5 minutes |
| **4** | fault: the selected train's end-of-train unit lost |
| **5** | fault: the selected train's head unit lost |
| **a** | add a train |
| **v** | show the simulator's truth beside the console (differences underlined) |
| **f** | event log: cycle the least severity shown |
| **]** / **[** | replay: jump 5 minutes forward / back |
| **?** | this help |
| **q** | quit |

Section marks, readable without colour: **·** clear, **#** occupied, **!** disturbed, **?** preparatory.
Crossings: **●●** warning on (with the seconds until the next head arrives), **○** road open.
The view shows what the console derives from the devices' reports, never the simulator's truth
(except in the truth view, where it sits beside it).
"""


class HelpScreen(ModalScreen[None]):
    BINDINGS: ClassVar[list[BindingType]] = [Binding("escape,q,question_mark", "dismiss", "Close")]
    DEFAULT_CSS = """
    HelpScreen { align: center middle; }
    HelpScreen > VerticalScroll { width: 90%; height: 90%; border: thick $primary; background: $surface; }
    """

    def compose(self) -> ComposeResult:
        with VerticalScroll():
            yield Markdown(HELP)

    def action_dismiss(self) -> None:  # type: ignore[override]
        self.dismiss(None)
