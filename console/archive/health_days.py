"""The daily health figures a forecast follows, from the archive; and the forecasts themselves.

Three figures per day (console.analysis.health.forecast says what each means and its threshold):

* ``analog_margin`` per counting head and channel: the day's median analog value's distance inside
  the band (``median_margin`` of :func:`console.archive.trends.analog_margins_per_day`);
* ``disturbance_rate`` per head and channel: 1-edge counter growth per hour
  (:func:`console.archive.trends.disturbances_per_day` per channel);
* ``gnss_loss`` per GNSS unit: the share of its reports missing, :func:`gnss_loss_per_day`.
"""

from __future__ import annotations

import importlib.util
from collections import defaultdict
from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.health.forecast import (
    FIGURES,
    STATUSES,
    Forecast,
    ForecastSettings,
    Series,
    due_list,
    forecasts,
    last_day_end,
)
from console.archive.query import QueryError
from console.archive.reader import Window, user_window
from console.archive.store import archive_dir, read_current
from console.archive.trends import (
    RecordFigures,
    analog_margins_per_day,
    archive_trends,
    disturbance_figures,
    disturbances_per_day,
    record_figures,
)
from console.archive.views import connect
from console.layout import LayoutError, load_layout
from parsers.units import NS_PER_DAY

# The due series whose daily points the document carries (the report plots them).
PLOTS_SHOWN = 12

if TYPE_CHECKING:
    import duckdb
    import pyarrow as pa

    from console.archive.store import Manifest
    from console.layout import Layout
    from console.sinks.report.model import ReportData

BREAK_PERIODS = 20  # a gap this many report periods long is the unit off the line (between trips), not losses
PERIOD_QUANTILE = 0.1  # the report period: a low quantile of the gaps (the median grows once half is lost)
MIN_EXPECTED = 20  # fewer reports expected in a day: no loss figure that day
CENTRE_SOURCE = "centre"  # the monitoring-centre table samples units every 10 s: its gaps are not a unit's losses


def gnss_loss_per_day(con: duckdb.DuckDBPyConnection, window: Window) -> list[dict[str, Any]]:
    """Per GNSS unit and day: reports received, reports missing, and the share lost.

    A unit's report period is the 10th percentile of the gaps between its fixes (per unit and source);
    a gap of k periods is k − 1 reports lost, a gap over 20 periods is the unit off the line.  Where a
    unit's fixes come from several files (its NMEA and a device CSV of the same reports), the source
    with the most fixes that day stands for it.  Days are UTC days of the fix times.
    """
    columns = {d[0] for d in con.execute("SELECT * FROM fixes LIMIT 0").description or []}
    if not {"time", "device", "source"} <= columns:
        return []  # no GNSS file in the archive: its empty view has no fix columns
    conds = ["time IS NOT NULL", f"source <> '{CENTRE_SOURCE}'"]
    params: list[Any] = []
    if window.start is not None:
        conds.append("epoch_ns(time) >= ?")
        params.append(_ns(window.start))
    if window.end is not None:
        conds.append("epoch_ns(time) < ?")
        params.append(_ns(window.end))
    if window.head is not None:
        conds.append("device = ?")
        params.append(window.head)
    rows = _rows(
        con,
        f"""
        WITH g AS (
            SELECT device, source, epoch_ns(time) AS t,
                   epoch_ns(time) - lag(epoch_ns(time)) OVER (PARTITION BY device, source ORDER BY time) AS gap
            FROM fixes WHERE {" AND ".join(conds)}
        ), p AS (
            SELECT device, source, quantile_cont(gap, {PERIOD_QUANTILE}) AS period
            FROM g WHERE gap > 0 GROUP BY ALL
        )
        SELECT g.t // {NS_PER_DAY} AS day, device, source, any_value(p.period)::BIGINT AS period_ns,
               count(*) FILTER (WHERE g.gap IS NULL OR g.gap > 0) AS fixes,
               coalesce(sum(CASE WHEN g.gap > 0 AND g.gap <= {BREAK_PERIODS} * p.period
                                 THEN greatest(round(g.gap / p.period) - 1, 0) ELSE 0 END), 0)::BIGINT AS missing
        FROM g JOIN p USING (device, source) GROUP BY ALL ORDER BY day, device, fixes DESC, source
        """,
        params,
    )
    out: dict[tuple[int, str], dict[str, Any]] = {}
    for r in rows:
        key = (int(r["day"]), str(r["device"]))
        if key in out:  # ordered by fixes, most first: the best copy of the unit's reports stands
            continue
        expected = int(r["fixes"]) + int(r["missing"])
        out[key] = {
            "day": str(np.datetime64(key[0], "D")),
            "device": key[1],
            "source": r["source"],
            "period_s": round(int(r["period_ns"]) / 1e9, 3),
            "fixes": int(r["fixes"]),
            "missing": int(r["missing"]),
            "loss": round(int(r["missing"]) / expected, 5) if expected >= MIN_EXPECTED else None,
        }
    return list(out.values())


def _rows(con: duckdb.DuckDBPyConnection, sql: str, params: list[Any]) -> list[dict[str, Any]]:
    cur = con.execute(sql, params)
    names = [d[0] for d in cur.description or []]
    return [dict(zip(names, r, strict=True)) for r in cur.fetchall()]


def _ns(t: Any) -> int:
    return int(np.datetime64(t, "ns").astype(np.int64))


def _day_number(day: str) -> int:
    return int(np.datetime64(day, "D").astype(np.int64))


def daily_figures(
    con: duckdb.DuckDBPyConnection,
    window: Window,
    layout: Layout | None,
    say: Callable[[str], None] | None = None,
    figures: RecordFigures | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """The three daily figures of the window, as rows (see the module's doc); ``say`` hears each step.

    ``figures``: the window's record figures when the caller has them (the same window and layout)."""
    tell = say or (lambda _: None)
    if figures is not None and figures.window == window:
        analog, dist = figures.analog, disturbance_figures(figures.disturbances, by_channel=True)
    else:
        tell("daily analog values per head and channel")
        analog = analog_margins_per_day(con, window, layout)
        tell("daily disturbance rates per head and channel")
        dist = disturbances_per_day(con, window, by_channel=True)
    tell("daily report losses per GNSS unit")
    return {"analog_margin": analog, "disturbance_rate": dist, "gnss_loss": gnss_loss_per_day(con, window)}


def series_of(figures: dict[str, list[dict[str, Any]]]) -> list[Series]:
    """One series per head and channel (or unit) and figure, days ascending; days without a figure left out."""
    pick = {
        "analog_margin": (lambda r: (r["counting_head"], r["channel"]), "median_margin"),
        "disturbance_rate": (lambda r: (r["counting_head"], r["channel"]), "per_hour"),
        "gnss_loss": (lambda r: (r["device"], None), "loss"),
    }
    out: list[Series] = []
    for figure, rows in figures.items():
        key_of, field = pick[figure]
        grouped: dict[tuple[str, int | None], list[tuple[int, float]]] = defaultdict(list)
        for r in rows:
            if r[field] is not None:
                grouped[key_of(r)].append((_day_number(r["day"]), float(r[field])))
        for (target, channel), points in grouped.items():
            points.sort()
            out.append(
                Series(
                    figure,
                    str(target),
                    None if channel is None else int(channel),
                    np.array([d for d, _ in points], np.int64),
                    np.array([v for _, v in points], np.float64),
                    FIGURES[figure][0],
                )
            )
    return out


def archive_forecasts(
    root: Path,
    manifest: Manifest,
    window: Window,
    layout: Layout | None,
    settings: ForecastSettings | None = None,
    say: Callable[[str], None] | None = None,
    figures: RecordFigures | None = None,
) -> tuple[list[Forecast], list[Series]]:
    """Every head's, channel's and unit's forecast over the window (and the series they were fitted on).

    A window of one head (or unit) is forecast from the end of the last day of every head's figures, as it is
    among the others: the horizon starts on the same day whichever heads are asked for."""
    con, _ = connect(root, manifest, tables={"records", "fixes"})
    try:
        every = series_of(daily_figures(con, replace(window, head=None), layout, say, figures))
    finally:
        con.close()
    series = every if window.head is None else [s for s in every if s.target == window.head]
    if say is not None:
        say(f"fitting the trends of {len(series):,} series")
    return forecasts(series, settings or ForecastSettings(), now_ns=last_day_end(every)), series


FORECAST_COLUMNS = (
    "target",
    "channel",
    "figure",
    "status",
    "due",
    "threshold",
    "unit",
    "days",
    "last_value",
    "slope_per_day",
    "crossing",
    "earliest",
    "latest",
    "days_left",
)


def forecast_table(items: Iterable[Forecast]) -> pa.Table:
    """The forecasts as the ``forecasts`` view of ``trackside query`` (times as timestamps)."""
    import pyarrow as pa

    items = list(items)
    rows = [{**f.to_dict(), "due": f.due} for f in items]
    times = {"crossing": "crossing_ns", "earliest": "earliest_ns", "latest": "latest_ns"}
    cols: dict[str, pa.Array] = {}
    for name in FORECAST_COLUMNS:
        if name in times:
            cols[name] = pa.array([getattr(f, times[name]) for f in items], pa.int64()).cast(pa.timestamp("ns"))
        elif name == "channel":
            cols[name] = pa.array([r[name] for r in rows], pa.int64())
        elif name == "due":
            cols[name] = pa.array([r[name] for r in rows], pa.bool_())
        elif name in ("target", "figure", "status", "unit"):
            cols[name] = pa.array([r[name] for r in rows], pa.string())
        elif name == "days":
            cols[name] = pa.array([r[name] for r in rows], pa.int64())
        else:
            cols[name] = pa.array([r[name] for r in rows], pa.float64())
    return pa.table(cols)


def query_forecasts(root: Path, manifest: Manifest) -> pa.Table:
    """The ``forecasts`` view of ``trackside query``: every series' forecast, default settings (30-day
    horizon, 14-day trend), the bands of the layout the archive was ingested with."""
    try:
        import scipy.stats  # noqa: F401 - the trend's library, an optional extra
    except ImportError:
        raise QueryError("the forecasts view needs scipy: pip install 'trackside[forecast]'") from None
    spec = manifest.derived.get("layout")
    try:
        layout = load_layout(spec) if spec else None
    except LayoutError:
        layout = None  # the layout file is gone: the bands are learned, as without one
    items, _ = archive_forecasts(root, manifest, Window(), layout)
    return forecast_table(items)


def forecast_doc(
    root: Path, manifest: Manifest, window: Window, layout: Layout | None, figures: RecordFigures | None = None
) -> dict[str, Any] | None:
    """The document's ``forecast``: counts, the due list, and the daily points of the plotted series.
    None when scipy (the ``forecast`` extra) is not installed.  ``figures``: as :func:`daily_figures`."""
    # Installed? (the trend's library, an optional extra).  Not imported here: a second of a report's start-up,
    # and an archive without health registers fits no trend.
    if importlib.util.find_spec("scipy") is None:
        return None
    settings = ForecastSettings()
    items, series = archive_forecasts(root, manifest, window, layout, settings, figures=figures)
    due = due_list(items)
    by_key = {(s.figure, s.target, s.channel): s for s in series}
    plotted = []
    for f in due[:PLOTS_SHOWN]:
        s = by_key[(f.figure, f.target, f.channel)]
        plotted.append(
            {
                "figure": f.figure,
                "target": f.target,
                "channel": f.channel,
                "days": [int(d) for d in s.day],
                "values": [round(float(v), 4) for v in s.value],
            }
        )
    return {
        "horizon_days": settings.horizon_days,
        "trend_days": settings.fit_days,
        "counts": {st: sum(1 for f in items if f.status == st) for st in STATUSES},
        "due": [f.to_dict() for f in due],
        "plotted": plotted,
    }


def with_trends_and_forecast(
    collector: Callable[[], ReportData],
    archive: Path | None,
    start: str | None,
    end: str | None,
    head: str | None,
    device_id: int | None,
) -> Callable[[], ReportData]:
    """``report --archive``'s collector, its data completed with the window's trends and forecast (the forecast
    over every device: no ``device_id``); the record figures both read are queried once where the windows agree."""

    def collect() -> ReportData:
        data = collector()  # checks the archive and the window first (one-line errors)
        root = archive_dir(archive)
        manifest = read_current(root)
        window = user_window(start, end, head, device_id)  # as the collector read it
        con, _ = connect(root, manifest, tables={"records"})
        try:
            figures = record_figures(con, window, data.layout)
        finally:
            con.close()
        data.trends = archive_trends(root, manifest, window, data.layout, figures)
        data.forecast = forecast_doc(root, manifest, replace(window, device_id=None), data.layout, figures)
        return data

    return collect
