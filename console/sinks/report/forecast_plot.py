"""The Forecast section's plot: one series' daily figures, its trend, the threshold and the crossing's interval.

Drawn with matplotlib's SVG backend (no pyplot, no display): a figure of its own, text kept as text
(``svg.fonttype = none``), ids salted with a constant and no date in the metadata, so the same
forecast gives the same bytes.  Names from the logs are escaped (control and bidi characters) before
they reach the drawing.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from console.safe_text import clean
from parsers.units import NS_PER_DAY

FIGURE_TITLES = {
    "analog_margin": ("analog margin", "median inside the band (counts)"),
    "disturbance_rate": ("disturbance rate", "1-edge counts per hour"),
    "gnss_loss": ("GNSS report loss", "share of reports lost"),
}


def _day(ns: int | None) -> float | None:
    return None if ns is None else ns / NS_PER_DAY


def forecast_svg(forecast: dict[str, Any], days: list[int], values: list[float], trend_days: int) -> str:
    """One series as an SVG document (without the XML prologue: ready to inline in HTML); the trend is drawn
    over the days it was fitted on (the last ``trend_days``) and on to the crossing."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    what, y_label = FIGURE_TITLES[forecast["figure"]]
    where = clean(forecast["target"]) + (f" Sys{forecast['channel']}" if forecast.get("channel") else "")
    x = np.array(days, np.float64) + 0.5  # a day's figure stands for its middle
    y = np.array(values, np.float64)
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "trackside", "font.size": 8}):
        fig = Figure(figsize=(7.0, 2.6))
        FigureCanvasSVG(fig)
        ax = fig.add_subplot()
        ax.plot(_dates(x), y, "o-", ms=3, lw=1, color="#1f4e79", label="daily figure")
        thr = float(forecast["threshold"])
        ax.axhline(thr, color="#b71c1c", ls="--", lw=1, label=f"threshold {thr:g}")
        crossing = _day(_ns(forecast.get("crossing")))
        early, late = _day(_ns(forecast.get("earliest"))), _day(_ns(forecast.get("latest")))
        slope, px, py = forecast.get("slope_per_day"), forecast.get("pivot_day"), forecast.get("pivot_value")
        end = max([float(x[-1]), *(t for t in (crossing, early, late) if t is not None)]) + 1.0
        if slope is not None and px is not None and py is not None:
            t = np.linspace(max(float(x[0]), float(x[-1]) - trend_days + 1), end, 50)
            ax.plot(_dates(t), py + slope * (t - px), color="#ef6c00", lw=1.2, label=f"trend {slope:+.3g}/day")
            lo, hi = forecast.get("slope_low"), forecast.get("slope_high")
            if lo is not None and hi is not None:
                a, b = py + lo * (t - px), py + hi * (t - px)
                ax.fill_between(_dates(t), np.minimum(a, b), np.maximum(a, b), color="#ef6c00", alpha=0.15, lw=0)
        if early is not None:
            right = late if late is not None else end
            ax.axvspan(_dates(np.array([early]))[0], _dates(np.array([right]))[0], color="#b71c1c", alpha=0.08, lw=0)
        if crossing is not None:
            ax.axvline(_dates(np.array([crossing]))[0], color="#b71c1c", lw=1, label="crossing")
        ax.set_title(f"{where}: {what} ({forecast['status']})", loc="left")
        ax.set_ylabel(y_label)
        ax.grid(True, lw=0.3, color="#d0d7de")
        ax.legend(loc="best", fontsize=7, frameon=False)
        fig.autofmt_xdate()
        fig.tight_layout()
        buf = io.StringIO()
        fig.savefig(buf, format="svg", metadata={"Date": None})
    text = buf.getvalue()
    return text[text.index("<svg") :]


def _ns(iso_text: str | None) -> int | None:
    if iso_text is None:
        return None
    return int(np.datetime64(iso_text.rstrip("Z"), "ns").astype(np.int64))


def _dates(day: np.ndarray) -> np.ndarray:
    """Day numbers (days since 1970-01-01, fractional) as datetimes matplotlib places on a date axis."""
    return (np.asarray(day, np.float64) * 86_400_000).astype("datetime64[ms]")
