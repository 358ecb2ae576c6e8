"""A terminal plot of the selected train's reported speed (plotext, through textual-plotext)."""

from __future__ import annotations

from collections.abc import Sequence

from textual_plotext import PlotextPlot

from console.safe_text import inert
from console.tui.widgets.quiet import retitle

WINDOW_S = 600.0  # the last ten minutes


class SpeedPlot(PlotextPlot):
    """Speed over the last ten minutes, km/h against seconds before now, from 0 to the line speed."""

    DEFAULT_CSS = """
    SpeedPlot { width: 2fr; min-width: 30; max-width: 80; border: round $secondary; }
    """

    def show(self, train: str | None, history: Sequence[tuple[float, float]], line_speed_kmh: float) -> None:
        """``history``: (seconds on the model clock, km/h) pairs, oldest first."""
        # Plotting and repainting take tens of milliseconds: only when the plot would change.
        key = (train, len(history), history[-1] if history else None, line_speed_kmh)
        if key == self.__dict__.get("_shown"):
            return
        self.__dict__["_shown"] = key
        plt = self.plt
        plt.clear_data()
        plt.clear_figure()
        ymax = max([line_speed_kmh, *(v for _, v in history)]) * 1.1
        plt.ylim(0, ymax)
        plt.xlim(-WINDOW_S, 0)
        if train and history:
            now = history[-1][0]
            pts = [(t - now, v) for t, v in history if now - t <= WINDOW_S]
            plt.plot([p[0] for p in pts], [p[1] for p in pts], marker="braille")
            retitle(self, title=inert(f"{train} {history[-1][1]:.0f} km/h"))
        else:
            retitle(self, title="speed: no train")
        plt.xlabel("s before now")
        self.refresh()
