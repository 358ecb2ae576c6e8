"""The report's trends part (``report --archive`` only): tables for every format, plots for the HTML face.

The numbers come from :func:`console.archive.trends.archive_trends` (the
document's ``trends``).  :func:`trends_part` gives the outline's blocks;
:func:`trend_plots` draws a figure's SVGs, at most :data:`SERIES_PER_PLOT`
series each so every legend fits on its line.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from console.sinks.report import plots
from console.sinks.report.blocks import Block, Cell, Figure, Heading, Para, num_or_dash, table_block
from console.sinks.report.model import natural_key

SERIES_PER_PLOT = 8
PLOTS = {
    "trend-axles": ("axles_per_head_per_day", "axles", "Axles per head per day"),
    "trend-disturbances": ("disturbances_per_head_per_day", "per_hour", "Disturbances per hour, per head per day"),
    "trend-analog": ("analog_margin_per_head_per_day", "margin", "Analog margin per head and channel per day"),
    "trend-late": ("late_warnings_per_crossing_per_day", "late", "Late warnings per crossing per day"),
}
Y_CAPTIONS = {
    "trend-axles": "axles",
    "trend-disturbances": "disturbances / h",
    "trend-analog": "margin (counts)",
    "trend-late": "late warnings",
}
CAPTIONS = {
    "trend-axles": "Axles counted per counting head, one point per day.",
    "trend-disturbances": (
        "Growth of the 1-edge counters (disturbances) per hour of the day's readings, per counting head."
    ),
    "trend-analog": (
        "Least distance of the day's analog values inside the channel's band (negative: out of band; the dashed "
        "red line is the band edge)."
    ),
    "trend-late": "Warnings that came late or broke a safety rule, per crossing and day.",
}


def _series_name(plot: str, row: dict[str, Any]) -> str:
    if plot == "trend-late":
        return str(row["crossing"])
    if plot == "trend-analog":
        return f"{row['counting_head']} Sys{row['channel']}"
    return str(row["counting_head"])


def trend_plots(plot: str, trends: dict[str, Any] | None) -> list[str]:
    """The SVGs of one trend figure (empty when there is nothing to draw)."""
    if trends is None or plot not in PLOTS:
        return []
    key, field, title = PLOTS[plot]
    grouped: dict[str, list[tuple[str, float | None]]] = defaultdict(list)
    for row in trends.get(key, []):
        grouped[_series_name(plot, row)].append((str(row["day"]), row[field]))
    names = sorted(grouped, key=_natural)
    series = [
        plots.DaySeries(n, tuple(d for d, _ in grouped[n]), tuple(v for _, v in grouped[n]))
        for n in names
        if any(v is not None for _, v in grouped[n])
    ]
    out = []
    for i in range(0, len(series), SERIES_PER_PLOT):
        part = series[i : i + SERIES_PER_PLOT]
        prefix = f"{plot}{i // SERIES_PER_PLOT}"
        body = plots.day_plot(part, title, Y_CAPTIONS[plot], prefix, zero_line=plot == "trend-analog")
        if body:
            out.append(body)
    return out


def caption(plot: str) -> str:
    return CAPTIONS.get(plot, "")


def _natural(text: str) -> tuple[Any, ...]:
    return natural_key(text)


def trends_part(doc: dict[str, Any]) -> list[Block]:
    """Part 8: the daily trends of a report from the archive (absent from a report on files)."""
    t = doc.get("trends")
    if t is None:
        return []
    out: list[Block] = [
        Heading(2, "8. Trends per day", "trends"),
        Para(("From the archive's history over the report's window; days are the logs' dates.",)),
    ]
    axles = t["axles_per_head_per_day"]
    out.append(Heading(3, "Axles per head per day", "trend-axles"))
    if axles:
        out.append(Figure("trend-axles"))
        rows: list[list[Cell]] = [[a["day"], str(a["device_id"]), a["counting_head"], f"{a['axles']:,}"] for a in axles]
        out.append(table_block([("Day", False), ("Device", True), ("Head", False), ("Axles", True)], rows))
    else:
        out.append(Para(("No axles in the window.",)))
    dist = t["disturbances_per_head_per_day"]
    out.append(Heading(3, "Disturbance rate per head per day", "trend-disturbances"))
    if dist:
        out.append(Figure("trend-disturbances"))
        rows = [
            [
                d["day"],
                str(d["device_id"]),
                d["counting_head"],
                f"{d['disturbances']:,}",
                f"{d['readings']:,}",
                num_or_dash(d["hours"], "{:.2f}"),
                num_or_dash(d["per_hour"], "{:.1f}"),
            ]
            for d in dist
        ]
        cols = [("Day", False), ("Device", True), ("Head", False), ("Disturbances", True), ("Readings", True)]
        note = "Per hour: over the span of the day's counter readings; none under 10 minutes."
        out.append(table_block([*cols, ("Hours", True), ("Per hour", True)], rows, note))
    else:
        out.append(Para(("No 1-edge counter readings (Zähler 1-Flanken) in the window.",)))
    analog = t["analog_margin_per_head_per_day"]
    out.append(Heading(3, "Analog margin per head per day", "trend-analog"))
    if analog:
        out.append(Figure("trend-analog"))
        rows = [
            [
                a["day"],
                a["counting_head"],
                f"Sys{a['channel']}",
                f"{a['values']:,}",
                num_or_dash(a["min"], "{:.0f}"),
                num_or_dash(a["max"], "{:.0f}"),
                f"{num_or_dash(a['band_low'], '{:.0f}')}–{num_or_dash(a['band_high'], '{:.0f}')} ({a['band']})",
                num_or_dash(a["margin"], "{:.0f}"),
                f"{a['out_of_band']:,}",
            ]
            for a in analog
        ]
        cols = [("Day", False), ("Head", False), ("Channel", False), ("Values", True), ("Min", True)]
        cols += [("Max", True), ("Band", False), ("Margin", True), ("Out of band", True)]
        note = "Margin: the least distance inside the band that day, in counts; negative when a value left it."
        out.append(table_block(cols, rows, note))
    else:
        out.append(Para(("No analog receiver values (Analogwert registers) in the window.",)))
    late = t["late_warnings_per_crossing_per_day"]
    out.append(Heading(3, "Late warnings per crossing per day", "trend-late"))
    if late:
        out.append(Figure("trend-late"))
        rows = [[w["day"], w["crossing"], f"{w['warnings']:,}", f"{w['late']:,}"] for w in late]
        out.append(table_block([("Day", False), ("Crossing", False), ("Warnings", True), ("Late", True)], rows))
    else:
        out.append(Para(("No level-crossing warnings in the window.",)))
    return out
