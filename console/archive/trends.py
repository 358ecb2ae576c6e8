"""Daily trends from the archive for ``report --archive``: axles, disturbances, analog margins, late warnings.

Four daily aggregates, each one DuckDB query over the archive (the
``axles`` and ``crossing_timelines`` derived tables, the ``records`` of two
registers), cut to the report's window (``--from/--to/--head/--device``):

* **axles** per device, counting head and day (the derived ``axles`` table);
* **disturbances** per device, counting head and day: the growth of the
  1-edge counters (``counter_1_edge``) summed over the head's channels and
  addresses, a decrease counted as a reset (the new reading is the
  growth), as :func:`console.analysis.health.disturbance.disturbance_rate_findings`
  takes it; ``per_hour`` divides by the time that growth took: from the
  reading before the day's first (the day's first step is growth since then)
  to the day's last (none under 10 minutes, the health rule's shortest span);
* **analog margin** per counting head, channel and day: how far the day's
  analog values (``analog_value``) stayed inside the channel's band, in
  counts (negative: out of band).  The band is the layout's for the head,
  else the one :func:`console.analysis.health.band.learn_band` learns from the
  window's first values, as the health rule does;
* **late warnings** per crossing and day (the day of the head's arrival,
  else of the warning's start): warnings and how many were late.

Trends exist only for the archive: a report on files has no history.
Times are the logs' own, read as UTC like everywhere in trackside.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from console.archive.reader import Window
from console.archive.views import connect

if TYPE_CHECKING:
    import duckdb

    from console.archive.store import Manifest
    from console.layout import Layout

NS_PER_HOUR = 3_600 * 10**9
MIN_RATE_SPAN_NS = 600 * 10**9  # the disturbance rule's shortest span (health.disturbance_rate_findings)


def _rows(con: duckdb.DuckDBPyConnection, sql: str, params: list[Any]) -> list[dict[str, Any]]:
    cur = con.execute(sql, params)
    names = [d[0] for d in cur.description or []]
    return [dict(zip(names, r, strict=True)) for r in cur.fetchall()]


def axles_per_day(con: duckdb.DuckDBPyConnection, window: Window) -> list[dict[str, Any]]:
    where, params = window.where()
    rows = _rows(
        con,
        f"SELECT day, device_id, counting_head, count(*) AS axles FROM axles{where} "
        "GROUP BY ALL ORDER BY day, device_id, counting_head",
        params,
    )
    return [{**r, "day": str(r["day"])} for r in rows]


def disturbances_per_day(
    con: duckdb.DuckDBPyConnection, window: Window, *, by_channel: bool = False
) -> list[dict[str, Any]]:
    """Per (day, device, head), or per channel too with ``by_channel`` (as the health rule judges a rate)."""
    return disturbance_figures(disturbance_rows(con, window), by_channel=by_channel)


def disturbance_rows(con: duckdb.DuckDBPyConnection, window: Window) -> list[dict[str, Any]]:
    """Per (day, device, head, channel): the 1-edge counters' growth, readings, and the time that growth took
    (``first_ns``: the reading before the day's first, ``last_ns``: the day's last); what
    :func:`disturbance_figures` makes both the per-channel and the per-head figures of."""
    where, params = window.where()
    cond = f"{where} AND label_canonical = 'counter_1_edge'" if where else " WHERE label_canonical = 'counter_1_edge'"
    # Growth since the series' previous reading, in the order the device wrote them, as the health rule reads
    # them (health.disturbance._counter_readings): a reading an overlapping export repeats counted once, files in the
    # order of their first readings, lines in file order.  Not by time: a board clock set back (a reboot, a DST
    # change of local time) would interleave two stretches, each fall a counter reset.
    return _rows(
        con,
        f"""
        WITH r AS (
            SELECT day, device_id, counting_head, channel, address, time, value, file_seq, line,
                   row_number() OVER (PARTITION BY counting_head, channel, address, time, value
                                      ORDER BY file_seq, line) AS copy
            FROM records{cond}
        ), u AS (
            SELECT *, min(time) OVER (PARTITION BY file_seq) AS file_start FROM r WHERE copy = 1
        ), c AS (
            SELECT day, device_id, counting_head, channel, time, value,
                   value - lag(value) OVER w AS step, lag(time) OVER w AS prev_time
            FROM u
            WINDOW w AS (PARTITION BY device_id, counting_head, channel, address ORDER BY file_start, file_seq, line)
        )
        SELECT day, device_id, counting_head, channel,
               sum(CASE WHEN step IS NULL THEN 0 WHEN step < 0 THEN value ELSE step END)::BIGINT AS disturbances,
               count(*) AS readings,
               epoch_ns(min(coalesce(prev_time, time))) AS first_ns, epoch_ns(max(time)) AS last_ns
        FROM c GROUP BY ALL ORDER BY day, device_id, counting_head, channel
        """,
        params,
    )


def disturbance_figures(rows: list[dict[str, Any]], *, by_channel: bool = False) -> list[dict[str, Any]]:
    """:func:`disturbances_per_day`'s rows from :func:`disturbance_rows`' (a head's: its channels' summed,
    its span from the earliest first to the latest last)."""
    key = ("day", "device_id", "counting_head", "channel") if by_channel else ("day", "device_id", "counting_head")
    merged: dict[tuple[Any, ...], dict[str, Any]] = {}
    for r in rows:  # ordered by day, device, head, channel: a head's channels are together
        k = tuple(r[c] for c in key)
        m = merged.get(k)
        if m is None:
            merged[k] = {
                **{c: r[c] for c in key},
                **{c: r[c] for c in ("disturbances", "readings", "first_ns", "last_ns")},
            }
            continue
        m["disturbances"] += r["disturbances"]
        m["readings"] += r["readings"]
        m["first_ns"] = min(m["first_ns"], r["first_ns"])
        m["last_ns"] = max(m["last_ns"], r["last_ns"])
    out = []
    for r in merged.values():
        span = int(r.pop("last_ns")) - int(r.pop("first_ns"))
        rate = r["disturbances"] / (span / NS_PER_HOUR) if span >= MIN_RATE_SPAN_NS else None
        out.append({**r, "day": str(r["day"]), "hours": round(span / NS_PER_HOUR, 3), "per_hour": _round(rate)})
    return out


@dataclass(frozen=True)
class RecordFigures:
    """The daily figures of a window's records that the trends and the forecast both read: the analog margins
    (:func:`analog_margins_per_day`) and the disturbance counters per channel (:func:`disturbance_rows`);
    queried once for a report that shows both."""

    window: Window
    analog: list[dict[str, Any]]
    disturbances: list[dict[str, Any]]


def record_figures(con: duckdb.DuckDBPyConnection, window: Window, layout: Layout | None) -> RecordFigures:
    return RecordFigures(window, analog_margins_per_day(con, window, layout), disturbance_rows(con, window))


def analog_margins_per_day(
    con: duckdb.DuckDBPyConnection, window: Window, layout: Layout | None
) -> list[dict[str, Any]]:
    """Per (head, channel, day): values, min, max, the band, the margin (least distance inside it), the
    median (of each register, averaged over the channel's registers) and its distance inside the band."""
    from console.analysis.health.band import learn_band

    where, params = window.where()
    cond = f"{where} AND label_canonical = 'analog_value'" if where else " WHERE label_canonical = 'analog_value'"
    # Fetched as numpy arrays and made a table (as DuckDB's df() does) only when there are rows: a window
    # without analog values needs no pandas.
    arrays = con.execute(
        f"SELECT strftime(day, '%Y-%m-%d') AS day, counting_head, channel, address, value::DOUBLE AS value "
        f"FROM records{cond} "
        "ORDER BY counting_head, channel, time, file_seq, line",
        params,
    ).fetchnumpy()
    if not len(arrays["value"]):
        return []
    import pandas as pd

    df = pd.DataFrame.from_dict(arrays)
    bands: dict[str, tuple[float, float]] = (
        {h.id: h.analog_band for h in layout.heads if h.analog_band} if layout is not None else {}
    )
    low = np.empty(len(df))
    high = np.empty(len(df))
    origin = np.empty(len(df), dtype=object)
    # One band per (head, channel), as the health rule judges it: a loop over channels, not records.
    groups = cast(dict[tuple[str, int], np.ndarray], df.groupby(["counting_head", "channel"], sort=False).indices)
    for (head, _channel), idx in groups.items():
        if head in bands:
            lo, hi = (float(x) for x in bands[head])
            how = "layout"
        else:
            lo, hi, _ = learn_band(df["value"].to_numpy()[idx])
            how = "learned"
        low[idx], high[idx], origin[idx] = lo, hi, how
    v = df["value"].to_numpy()
    df["margin"] = np.minimum(v - low, high - v)
    df["out_of_band"] = df["margin"] < 0
    df["band_low"], df["band_high"], df["band"] = low, high, origin
    g = df.groupby(["day", "counting_head", "channel"], sort=True)
    agg = pd.DataFrame(
        {
            "values": g.size(),
            "min": g["value"].min(),
            "max": g["value"].max(),
            "band_low": g["band_low"].first(),
            "band_high": g["band_high"].first(),
            "band": g["band"].first(),
            "margin": g["margin"].min(),
            "out_of_band": g["out_of_band"].sum(),
            # A channel's registers (Adr 134, 136) read a few counts apart: the median of each, averaged
            # (the median of both together would jump between the two clusters from day to day).
            "median": df.groupby(["day", "counting_head", "channel", "address"])["value"]
            .median()
            .groupby(["day", "counting_head", "channel"])
            .mean(),
        }
    ).reset_index()
    out: list[dict[str, Any]] = []
    for r in agg.to_dict("records"):
        out.append(
            {
                "day": str(r["day"]),
                "counting_head": str(r["counting_head"]),
                "channel": int(r["channel"]),
                "values": int(r["values"]),
                **{k: _round(r[k]) for k in ("min", "max", "band_low", "band_high")},
                "band": str(r["band"]),
                "margin": _round(r["margin"]),
                "out_of_band": int(r["out_of_band"]),
                "median": _round(r["median"]),
                # The day's typical value inside the band: the figure the forecast follows (noise moves the
                # least distance with the number of readings; the median drifts as the sensor does).
                "median_margin": _round(min(r["median"] - r["band_low"], r["band_high"] - r["median"])),
            }
        )
    return out


def late_warnings_per_day(con: duckdb.DuckDBPyConnection, window: Window) -> list[dict[str, Any]]:
    when = "coalesce(t_head_arrival, t_on)"
    conds: list[str] = [f"{when} IS NOT NULL"]
    params: list[Any] = []
    if window.start is not None:
        conds.append(f"{when} >= ?")
        params.append(window.start)
    if window.end is not None:
        conds.append(f"{when} < ?")
        params.append(window.end)
    rows = _rows(
        con,
        f"SELECT CAST({when} AS DATE) AS day, crossing, count(*) AS warnings, "
        f"count(*) FILTER (WHERE late) AS late FROM crossing_timelines WHERE {' AND '.join(conds)} "
        "GROUP BY 1, 2 ORDER BY 1, 2",
        params,
    )
    return [{**r, "day": str(r["day"])} for r in rows]


def _round(x: float | None, digits: int = 3) -> float | None:
    if x is None or not np.isfinite(x):
        return None
    return round(float(x), digits)


def archive_trends(
    root: Path, manifest: Manifest, window: Window, layout: Layout | None, figures: RecordFigures | None = None
) -> dict[str, Any]:
    """The four daily trends of the window, as plain JSON values (the report's ``trends`` part).

    ``figures``: the window's record figures when the caller has them (the same window and layout)."""
    con, _ = connect(root, manifest, tables={"records", "axles", "crossing_timelines"})
    try:
        if figures is None or figures.window != window:
            figures = record_figures(con, window, layout)
        return {
            "axles_per_head_per_day": axles_per_day(con, window),
            "disturbances_per_head_per_day": disturbance_figures(figures.disturbances),
            "analog_margin_per_head_per_day": figures.analog,
            "late_warnings_per_crossing_per_day": late_warnings_per_day(con, window),
        }
    finally:
        con.close()
