"""A terminal plot of the selected train's speed."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.widgets import Label, Sparkline


class SpeedPlot(Vertical):
    """The selected train's speed over the last minutes, as a sparkline with its range."""

    DEFAULT_CSS = """
    SpeedPlot { width: 30; border: round $secondary; padding: 0 1; }
    SpeedPlot Sparkline { height: 1fr; }
    SpeedPlot Label { width: 100%; }
    """

    def compose(self) -> ComposeResult:
        yield Label("no train selected", id="speed-label")
        yield Sparkline([0.0], id="speed-spark")

    def show(self, train: str | None, history: list[float]) -> None:
        label = self.query_one("#speed-label", Label)
        spark = self.query_one("#speed-spark", Sparkline)
        if not train or not history:
            label.update("no train selected")
            spark.data = [0.0]
            return
        label.update(f"{train}: {history[-1]:.0f} km/h (max {max(history):.0f})")
        spark.data = list(history)
        self.border_title = "Speed, km/h"
