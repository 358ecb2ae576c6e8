"""The footer: every key, wrapping onto a second line on narrow terminals.

Textual's own footer shows one line and cuts the rest off at 80 or 100
columns; an operator should never have to guess a key."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

KEY_BAR: tuple[tuple[str, str], ...] = (
    ("space", "pause"),
    ("+/-", "speed"),
    (".", "step"),
    ("s/S", "section"),
    ("w/W", "train"),
    ("r", "reset"),
    ("1-6", "faults"),
    ("a", "add train"),
    ("v", "truth"),
    ("f", "filter"),
    ("[/]", "jump"),
    ("?", "help"),
    ("q", "quit"),
)


class KeyBar(Static):
    DEFAULT_CSS = """
    KeyBar { dock: bottom; height: auto; max-height: 3; background: $panel; padding: 0 1; }
    """

    def on_mount(self) -> None:
        text = Text()
        for key, what in KEY_BAR:
            text.append(key, style="bold")
            text.append(f" {what}  ", style="dim")
        self.update(text)
