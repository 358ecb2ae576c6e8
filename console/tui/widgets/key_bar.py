"""The footer: every key, wrapping onto a second line on narrow terminals.

Textual's own footer shows one line and cuts the rest off at 80 or 100
columns; an operator should never have to guess a key."""

from __future__ import annotations

from typing import Any

from rich.text import Text
from textual.widgets import Static

# (key, what it does, its action): the bar shows the keys that act in the view's mode.
KEY_BAR: tuple[tuple[str, str, str], ...] = (
    ("space", "pause", "pause"),
    ("+/-", "speed", "faster"),
    (".", "step", "single_step"),
    ("s/S", "section", "next_section"),
    ("w/W", "train", "next_train"),
    ("r", "reset", "reset_section"),
    ("1-6", "faults", "fault"),
    ("a", "add train", "add_train"),
    ("v", "truth", "truth"),
    ("f", "filter", "log_filter"),
    ("[/]", "jump", "jump"),
    ("?", "help", "help"),
    ("q", "quit", "quit"),
)
# Actions that act on the simulated line only, and those that need a clock the view can run (not live).
SIMULATION_ONLY = frozenset({"reset_section", "fault", "add_train", "truth"})
NOT_LIVE = frozenset({"faster", "slower", "single_step", "jump"})


def acts(action: str, mode: str) -> bool:
    """Whether a key's action does anything in this mode (sim, replay, live)."""
    if action in SIMULATION_ONLY and mode != "sim":
        return False
    return not (action in NOT_LIVE and mode == "live")


class KeyBar(Static):
    DEFAULT_CSS = """
    KeyBar { dock: bottom; height: auto; max-height: 3; background: $panel; padding: 0 1; }
    """

    def __init__(self, mode: str = "sim", **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.mode = mode

    def on_mount(self) -> None:
        text = Text()
        for key, what, action in KEY_BAR:
            if not acts(action, self.mode):
                continue
            text.append(key, style="bold")
            text.append(f" {what}  ", style="dim")
        self.update(text)
