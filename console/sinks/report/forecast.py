"""The report's Forecast part (``report --archive`` only): what is due for maintenance, with its trend.

The numbers come from :func:`console.archive.health_days.forecast_doc` over the report's window
(the document's ``forecast``); the HTML face draws the due series the document carries points of with
:func:`console.sinks.report.forecast_plot.forecast_svg`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from console.analysis.health.forecast import STATUSES
from console.sinks.report.blocks import Block, Cell, Figure, Heading, Para, num_or_dash, table_block

if TYPE_CHECKING:
    pass

FIGURE_NAMES = {"analog_margin": "analog margin", "disturbance_rate": "disturbance rate", "gnss_loss": "GNSS loss"}


def forecast_plots(doc_forecast: dict[str, Any] | None) -> list[str]:
    """The SVGs of the plotted due series."""
    if not doc_forecast:
        return []
    from console.sinks.report.forecast_plot import forecast_svg

    due = {(f["figure"], f["target"], f["channel"]): f for f in doc_forecast["due"]}
    return [
        forecast_svg(due[(p["figure"], p["target"], p["channel"])], p["days"], p["values"], doc_forecast["trend_days"])
        for p in doc_forecast["plotted"]
    ]


def forecast_part(doc: dict[str, Any]) -> list[Block]:
    """Part 9: when each head's and unit's health figures will cross their thresholds."""
    fc = doc.get("forecast")
    if fc is None:
        return []
    counts = ", ".join(f"{fc['counts'][s]} {s}" for s in STATUSES)
    out: list[Block] = [
        Heading(2, "9. Forecast", "forecast"),
        Para(
            (
                f"Trend of each daily health figure over its last {fc['trend_days']} days (Sen's slope, 90 % "
                f"interval); due: the interval's early end within {fc['horizon_days']:g} days of the last day, "
                f"or already past the threshold. Series: {counts}.",
            )
        ),
    ]
    if not fc["due"]:
        out.append(Para((f"Nothing is due for maintenance within {fc['horizon_days']:g} days.",)))
        return out
    out.append(Heading(3, "Due for maintenance, by date", "forecast-due"))
    if fc["plotted"]:
        out.append(Figure("forecast"))
    rows: list[list[Cell]] = [
        [
            f["target"],
            "–" if f["channel"] is None else f"Sys{f['channel']}",
            FIGURE_NAMES[f["figure"]],
            f["status"],
            num_or_dash(f["last_value"], "{:.3g}"),
            num_or_dash(f["threshold"], "{:g}"),
            num_or_dash(f["slope_per_day"], "{:+.3g}"),
            (f["crossing"] or "–")[:10],
            f"{(f['earliest'] or '–')[:10]} … {(f['latest'] or 'open')[:10]}",
            num_or_dash(f["days_left"], "{:.1f}"),
        ]
        for f in fc["due"]
    ]
    cols = [("Head / unit", False), ("Channel", False), ("Figure", False), ("Status", False), ("Last", True)]
    cols += [("Threshold", True), ("Trend /day", True), ("Crossing", False), ("Interval", False), ("Days left", True)]
    note = "Past: the last day's figure is beyond the threshold; the date is when it went beyond."
    out.append(table_block(cols, rows, note))
    return out
