"""Rich tables for `trackside forecast`: the due list, and every series on request."""

from __future__ import annotations

from collections import Counter

from rich import box
from rich.console import Group, RenderableType
from rich.table import Table
from rich.text import Text

from console.analysis.health.findings import channel_name
from console.analysis.health.forecast import (
    ANALOG_MARGIN_LIMIT,
    DISTURBANCE_LIMIT_PER_H,
    GNSS_LOSS_LIMIT,
    STATUSES,
    Forecast,
)
from console.safe_text import inert
from parsers.units import NS_PER_DAY

STATUS_STYLE = {"past": "bold red", "due": "yellow", "watch": "cyan", "unknown": "dim", "ok": "green"}
FIGURE_NAMES = {"analog_margin": "analog", "disturbance_rate": "1-edge/h", "gnss_loss": "GNSS loss"}
FIGURE_LONG = {"analog_margin": "analog margin", "disturbance_rate": "disturbance rate", "gnss_loss": "GNSS loss"}


def number(x: float | None, figure: str) -> str:
    if x is None:
        return "–"
    if figure == "gnss_loss":
        return f"{x:.1%}"
    return f"{x:.1f}" if figure == "analog_margin" else f"{x:.2f}"


def _trend(f: Forecast) -> str:
    if f.slope_per_day is None:
        return "–"
    if f.figure == "gnss_loss":
        return f"{f.slope_per_day * 100:+.2f}pt"
    return f"{f.slope_per_day:+.2f}"


def _days_left(f: Forecast) -> str:
    """Days from the archive's last day to the crossing, with the interval's ends: ``3.2 (2.1–5.0)``."""
    if f.crossing_ns is None and f.earliest_ns is None:
        return "–"
    if f.status == "past" and f.crossing_ns is not None:  # since when: a whole day
        return f"{(f.crossing_ns - f.from_ns) / NS_PER_DAY:.0f}"

    def d(ns: int | None) -> str:
        return "open" if ns is None else f"{(ns - f.from_ns) / NS_PER_DAY:.1f}"

    point = "–" if f.crossing_ns is None else d(f.crossing_ns)
    return f"{point} ({d(f.earliest_ns)}…{d(f.latest_ns)})"


def forecast_table(items: list[Forecast], title: str) -> Table:
    table = Table(title=title, title_justify="left", title_style="bold", box=box.SIMPLE_HEAD, pad_edge=False)
    for name, right in (
        ("Status", False),
        ("Head/unit", False),
        ("Figure", False),
        ("Last", True),
        ("Trend/d", True),
        ("Crossing", False),
        ("Days left", True),
    ):
        table.add_column(
            name, justify="right" if right else "left", no_wrap=True, min_width=9 if name == "Figure" else len(name)
        )
    for f in items:
        d = f.to_dict()
        where = f.target if f.channel is None else f"{f.target} {channel_name(f.channel)}"
        table.add_row(
            Text(f.status, style=STATUS_STYLE[f.status]),
            inert(where),
            FIGURE_NAMES[f.figure],
            number(f.last_value, f.figure),
            _trend(f),
            (d["crossing"] or "–")[:10],
            _days_left(f),
        )
    return table


def forecast_view(items: list[Forecast], due: list[Forecast], horizon_days: float, show_all: bool) -> Group:
    counts = Counter(f.status for f in items)
    summary = ", ".join(f"{counts[s]} {s}" for s in STATUSES)
    limits = (
        f"analog margin {ANALOG_MARGIN_LIMIT:g} (the band edge), disturbance rate {DISTURBANCE_LIMIT_PER_H:g}/h,"
        f" GNSS loss {GNSS_LOSS_LIMIT:.0%}"
    )
    parts: list[RenderableType] = [Text(f"{len(items)} series: {summary}. Thresholds: {limits}.", style="bold")]
    if due:
        parts.append(forecast_table(due, f"Due for maintenance within {horizon_days:g} days, by date"))
    else:
        parts.append(Text(f"Nothing is due within {horizon_days:g} days.", style="green"))
    if show_all:
        parts.append(forecast_table(items, "Every series"))
    return Group(*parts)
