"""Rich tables for `trackside forecast`: the due list, and every series on request."""

from __future__ import annotations

from collections import Counter

from rich.console import Group, RenderableType
from rich.table import Table
from rich.text import Text

from console.analysis.forecast import FIGURES, STATUSES, Forecast
from console.analysis.health import channel_name
from console.safe_text import inert

STATUS_STYLE = {"past": "bold red", "due": "yellow", "watch": "cyan", "unknown": "dim", "ok": "green"}
FIGURE_NAMES = {
    "analog_margin": "analog margin",
    "disturbance_rate": "disturbances",
    "gnss_loss": "GNSS loss",
}


def number(x: float | None, figure: str) -> str:
    if x is None:
        return "–"
    if figure == "gnss_loss":
        return f"{x:.1%}"
    return f"{x:.1f}" if figure == "analog_margin" else f"{x:.2f}"


def _trend(f: Forecast) -> str:
    if f.slope_per_day is None:
        return "–"
    unit = "pt/day" if f.figure == "gnss_loss" else "/day"
    k = 100.0 if f.figure == "gnss_loss" else 1.0
    return f"{f.slope_per_day * k:+.2f} {unit}"


def _day(iso_text: str | None) -> str:
    return "–" if iso_text is None else iso_text[:10]


def forecast_table(items: list[Forecast], title: str) -> Table:
    table = Table(title=title, title_justify="left", title_style="bold")
    for name, right in (
        ("Status", False),
        ("Head / unit", False),
        ("Figure", False),
        ("Last", True),
        ("Threshold", True),
        ("Trend", True),
        ("Crossing", False),
        ("Interval", False),
        ("Days left", True),
    ):
        table.add_column(name, justify="right" if right else "left")
    for f in items:
        d = f.to_dict()
        where = f.target if f.channel is None else f"{f.target} {channel_name(f.channel)}"
        interval = f"{_day(d['earliest'])} … {_day(d['latest']) if d['latest'] else 'open'}"
        table.add_row(
            Text(f.status, style=STATUS_STYLE[f.status]),
            inert(where),
            FIGURE_NAMES[f.figure],
            number(f.last_value, f.figure),
            number(f.threshold, f.figure),
            _trend(f),
            _day(d["crossing"]),
            interval if d["earliest"] else "–",
            "–" if d["days_left"] is None else f"{d['days_left']:.1f}",
        )
    return table


def forecast_view(items: list[Forecast], due: list[Forecast], horizon_days: float, show_all: bool) -> Group:
    counts = Counter(f.status for f in items)
    summary = ", ".join(f"{counts[s]} {s}" for s in STATUSES)
    parts: list[RenderableType] = [
        Text(f"{len(items)} series ({', '.join(FIGURE_NAMES[k] for k in FIGURES)}): {summary}", style="bold")
    ]
    if due:
        parts.append(forecast_table(due, f"Due for maintenance within {horizon_days:g} days, by date"))
    else:
        parts.append(Text(f"Nothing is due within {horizon_days:g} days.", style="green"))
    if show_all:
        parts.append(forecast_table(items, "Every series"))
    return Group(*parts)
