"""Trends per head and day in `report --archive`: each number equals a direct computation on the analyses' output."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from console.analysis.health.band import learn_band
from console.archive.history import report_data
from console.archive.reader import Window
from console.archive.store import read_current
from console.archive.trends import archive_trends
from console.cli.app import app
from console.layout import load_layout
from console.sinks.report.model import ReportData
from tests.archive_days import DAYS, DRIFT_PER_DAY, write_days
from tests.conftest import SAMPLES

runner = CliRunner()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    base = tmp_path_factory.mktemp("trends")
    arc = base / "arc"
    res = runner.invoke(
        app, ["ingest", *map(str, write_days(base / "in")), "--archive", str(arc), "--layout", "example"]
    )
    assert res.exit_code == 0, res.output
    return arc


@pytest.fixture(scope="module")
def data(archive: Path) -> ReportData:
    return report_data(archive)


@pytest.fixture(scope="module")
def trends(archive: Path) -> dict[str, Any]:
    res = runner.invoke(app, ["report", "--archive", str(archive), "--format", "json"])
    assert res.exit_code in (0, 1), res.output
    return dict(json.loads(res.stdout)["trends"])


def _day(ns: np.ndarray | pd.Series) -> np.ndarray:
    return np.asarray(ns, dtype="int64").astype("datetime64[ns]").astype("datetime64[D]").astype(str)


def test_axles_per_head_per_day_are_the_analysis_axles_counted(trends: dict[str, Any], data: ReportData) -> None:
    assert data.job is not None
    ax = data.job.analysis.axles
    heads = data.job.analysis.heads
    direct = (
        pd.DataFrame(
            {
                "day": _day(ax["time_ns"]),
                "device_id": [heads[h][0] for h in ax["head"]],
                "counting_head": [heads[h][1] for h in ax["head"]],
            }
        )
        .groupby(["day", "device_id", "counting_head"])
        .size()
    )
    got = {(r["day"], r["device_id"], r["counting_head"]): r["axles"] for r in trends["axles_per_head_per_day"]}
    assert got == {k: int(v) for k, v in direct.items()}
    assert len({d for d, _, _ in got}) == DAYS


def _records(data: ReportData, label: str) -> pd.DataFrame:
    assert data.job is not None
    rec = data.job.records
    r = rec[rec["label_canonical"] == label].copy()
    r["time_ns"] = r["time"].to_numpy(dtype="datetime64[ns]").view(np.int64)
    r["day"] = _day(r["time_ns"])
    return r


def test_disturbances_are_the_counter_growth_with_resets(trends: dict[str, Any], data: ReportData) -> None:
    # The readings in the order the device wrote them (as the health rule reads them): a reading an overlapping
    # export repeats once, files in the order of their first readings, lines in file order.
    r = _records(data, "counter_1_edge")  # in read order
    r = r.drop_duplicates(["counting_head", "channel", "address", "time_ns", "value"])
    r["file_no"] = pd.factorize(r["file"])[0]
    r["file_start"] = r.groupby("file_no")["time_ns"].transform("min")
    r = r.sort_values(["file_start", "file_no"], kind="stable")
    series = r.groupby(["device_id", "counting_head", "channel", "address"])
    step = series["value"].diff()
    r["growth"] = np.where(step < 0, r["value"], step.fillna(0))
    # The day's growth took from the reading before its first (the first day: from its first) to its last.
    r["since_ns"] = series["time_ns"].shift().fillna(r["time_ns"]).astype("int64")
    g = r.groupby(["day", "device_id", "counting_head"])
    direct = {k: (int(v), int(n)) for (k, v), n in zip(g["growth"].sum().items(), g.size(), strict=True)}
    span = g["time_ns"].max() - g["since_ns"].min()
    got = trends["disturbances_per_head_per_day"]
    assert {(x["day"], x["device_id"], x["counting_head"]): (x["disturbances"], x["readings"]) for x in got} == direct
    for x in got:
        hours = span[(x["day"], x["device_id"], x["counting_head"])] / 3.6e12
        assert x["per_hour"] == pytest.approx(x["disturbances"] / hours, abs=1e-3)
    assert any(x["disturbances"] > 0 for x in got)


def test_analog_margin_is_the_least_distance_inside_the_learned_band(trends: dict[str, Any], data: ReportData) -> None:
    r = _records(data, "analog_value").sort_values("time_ns", kind="stable")
    expected = {}
    for (head, ch), g in r.groupby(["counting_head", "channel"]):
        lo, hi, _ = learn_band(g["value"].to_numpy(dtype=float))
        for day, d in g.groupby("day"):
            v = d["value"].to_numpy(dtype=float)
            expected[(day, head, ch)] = (
                round(float(np.minimum(v - lo, hi - v).min()), 3),
                int(((v < lo) | (v > hi)).sum()),
            )
    got = {
        (x["day"], x["counting_head"], x["channel"]): (x["margin"], x["out_of_band"])
        for x in trends["analog_margin_per_head_per_day"]
    }
    assert got == expected
    # The samples drift DRIFT_PER_DAY counts a day: WS4 Sys1's margin falls by that much each day, and goes negative.
    ws4 = [
        x["margin"]
        for x in trends["analog_margin_per_head_per_day"]
        if x["counting_head"] == "WS4" and x["channel"] == 1
    ]
    assert np.allclose(np.diff(ws4), -DRIFT_PER_DAY) and ws4[-1] < 0


def test_a_layout_band_is_used_when_the_layout_sets_one(archive: Path, data: ReportData) -> None:
    base = load_layout("example")
    heads = tuple(dataclasses.replace(h, analog_band=(2300.0, 2500.0)) if h.id == "WS4" else h for h in base.heads)
    layout = dataclasses.replace(base, heads=heads)
    got = archive_trends(archive, read_current(archive), Window(head="WS4"), layout)["analog_margin_per_head_per_day"]
    r = _records(data, "analog_value")
    r = r[r["counting_head"] == "WS4"]
    for x in got:
        v = r[(r["day"] == x["day"]) & (r["channel"] == x["channel"])]["value"].to_numpy(dtype=float)
        assert x["band"] == "layout" and x["margin"] == pytest.approx(min((v - 2300).min(), (2500 - v).min()))


def test_late_warnings_per_crossing_per_day_count_the_timelines(trends: dict[str, Any], data: ReportData) -> None:
    assert data.crossing is not None and data.crossing.timelines
    expected: dict[tuple[str, str], list[int]] = {}
    for t in data.crossing.timelines:
        when = t.t_head_arrival_ns if t.t_head_arrival_ns is not None else t.t_on_ns
        key = (str(_day(np.array([when]))[0]), t.crossing)
        late = bool(t.violations) or (t.late_by_s is not None and t.late_by_s > 0)
        expected.setdefault(key, [0, 0])
        expected[key][0] += 1
        expected[key][1] += int(late)
    got = {(x["day"], x["crossing"]): [x["warnings"], x["late"]] for x in trends["late_warnings_per_crossing_per_day"]}
    assert got == expected


def test_the_window_cuts_the_trends(archive: Path) -> None:
    res = runner.invoke(
        app,
        [
            "report",
            "--archive",
            str(archive),
            "--format",
            "json",
            "--from",
            "2015-11-01",
            "--to",
            "2015-11-03",
            "--head",
            "WS4",
        ],
    )
    t = json.loads(res.stdout)["trends"]
    for part in ("axles_per_head_per_day", "disturbances_per_head_per_day", "analog_margin_per_head_per_day"):
        assert {x["day"] for x in t[part]} == {"2015-11-01", "2015-11-02"}, part
        assert {x["counting_head"] for x in t[part]} == {"WS4"}
    assert t["late_warnings_per_crossing_per_day"] == []  # the crossings are in 2026


def test_markdown_has_trend_tables_and_html_has_plots_with_log_text_escaped(archive: Path) -> None:
    md = runner.invoke(app, ["report", "--archive", str(archive)]).stdout
    assert "## 8. Trends per day" in md and "| 2015-11-03 | WS4 | Sys1 |" in md
    html = runner.invoke(app, ["report", "--archive", str(archive), "--format", "html"]).stdout
    part = html[html.index('id="trends"') : html.index('id="forecast"')]  # the forecast part comes next
    assert part.count("<svg") == 4  # axles, disturbances, analog margin, late warnings
    assert "WS4 Sys1" in part and "<script" not in html
    files = runner.invoke(app, ["report", str(archive.parent / "in"), "--layout", "example", "--format", "html"]).stdout
    assert 'id="trends"' not in files  # no history in a report on files


def test_log_text_in_a_trend_plot_is_inert() -> None:
    from console.sinks.report.trends import trend_plots

    evil = '<script>x</script>\u202e&"'
    rows = [{"day": "2026-03-02", "crossing": evil, "warnings": 1, "late": 1}]
    (plot,) = trend_plots("trend-late", {"late_warnings_per_crossing_per_day": rows})
    assert "<script" not in plot and "\u202e" not in plot and "&lt;script&gt;" in plot


def test_the_report_has_the_forecast_of_the_archive_with_a_plot_per_due_series(archive: Path) -> None:
    """Part 9: the due list `forecast` gives (WS4's analog values drift out of their band, DRIFT_PER_DAY;
    WS5 Sys2's disturbances grow as ws4_health.log's failing sensor's do), in its order, each plotted."""
    fc = runner.invoke(app, ["forecast", "--archive", str(archive), "--json"])
    assert fc.exit_code == 0, fc.output
    due = json.loads(fc.stdout)["due"]
    got = {(f["target"], f["channel"], f["figure"], f["status"]) for f in due}
    assert {("WS4", 1, "analog_margin", "past"), ("WS5", 2, "disturbance_rate", "past")} <= got
    doc = json.loads(runner.invoke(app, ["report", "--archive", str(archive), "--format", "json"]).stdout)
    assert doc["forecast"]["due"] == due
    html = runner.invoke(app, ["report", "--archive", str(archive), "--format", "html"]).stdout
    part = html[html.index('id="forecast"') :]
    assert part.count("<svg") == min(12, len(due)) and "WS5 Sys2: disturbance rate (past)" in part
    cells = [part.index(f"<td>{f['target']}</td>") for f in due[:1]]
    assert cells and "<script" not in part


def test_a_heads_disturbances_are_its_channels_summed(archive: Path) -> None:
    # The trends and the forecast share one per-channel query; the per-head rows summed from it must equal
    # the per-head aggregate over the records themselves (the query the trends ran on their own).
    from console.archive.trends import disturbances_per_day
    from console.archive.views import connect

    con, _ = connect(archive, read_current(archive), tables={"records"})
    try:
        t0 = con.execute("SELECT min(time) FROM records WHERE label_canonical = 'counter_1_edge'").fetchone()
        assert t0 is not None and t0[0] is not None
        for window in (Window(), Window(head="WS4"), Window(start=t0[0].replace(hour=12))):
            where, params = window.where()
            cond = (
                f"{where} AND label_canonical = 'counter_1_edge'"
                if where
                else " WHERE label_canonical = 'counter_1_edge'"
            )
            cur = con.execute(
                f"""
                WITH r AS (
                    SELECT *, row_number() OVER (PARTITION BY counting_head, channel, address, time, value
                                                 ORDER BY file_seq, line) AS copy
                    FROM records{cond}
                ), u AS (
                    SELECT *, min(time) OVER (PARTITION BY file_seq) AS file_start FROM r WHERE copy = 1
                ), c AS (
                    SELECT day, device_id, counting_head, time, value,
                           value - lag(value) OVER w AS step, lag(time) OVER w AS prev_time
                    FROM u
                    WINDOW w AS (PARTITION BY device_id, counting_head, channel, address
                                 ORDER BY file_start, file_seq, line)
                )
                SELECT strftime(day, '%Y-%m-%d') AS day, device_id, counting_head,
                       sum(CASE WHEN step IS NULL THEN 0 WHEN step < 0 THEN value ELSE step END)::BIGINT,
                       count(*), epoch_ns(max(time)) - epoch_ns(min(coalesce(prev_time, time)))
                FROM c GROUP BY ALL ORDER BY 1, 2, 3
                """,
                params,
            )
            direct = cur.fetchall()
            got = disturbances_per_day(con, window)
            assert direct and len(got) == len(direct)
            for r, (day, device, head, n, readings, span_ns) in zip(got, direct, strict=True):
                assert (r["day"], r["device_id"], r["counting_head"]) == (day, device, head)
                assert (r["disturbances"], r["readings"]) == (n, readings)
                assert r["hours"] == round(span_ns / 3.6e12, 3)
    finally:
        con.close()


def test_a_board_clock_set_back_gives_the_same_disturbances_in_health_and_the_archive_trends(
    tmp_path: Path,
) -> None:
    # ws4_health.log with its second half an hour back (a reboot, a DST change of a local-time log): health read
    # its counters by time and saw resets (a critical WS4 Sys2); it reads them in the device's order now, and
    # the archive's daily trend, a query of its own, must count the same growth.
    lines = (SAMPLES / "ws4_health.log").read_text("utf-8").splitlines(keepends=True)
    half = len(lines) // 2

    def back(line: str) -> str:
        head, _, clock = line.rpartition("Time:")
        t = dt.datetime.strptime(clock.strip(), "%H:%M:%S.%f") - dt.timedelta(hours=1)
        return f"{head}Time:{t:%H:%M:%S.%f}"[:-3] + "\n"

    log = tmp_path / "ws4_set_back.log"
    log.write_text("".join(lines[:half] + [back(x) for x in lines[half:]]), "utf-8")

    def told(path: Path) -> dict[tuple[str, int], tuple[str, int]]:
        """Per head and channel, the disturbance rule's severity and the disturbances it counted."""
        doc = json.loads(runner.invoke(app, ["health", str(path), "--json"]).stdout)
        out = {}
        for f in doc["findings"]:
            if f["rule"] == "disturbance_rate":
                n = re.search(r"(\d+) disturbances? in ", f["message"])
                assert n is not None, f["message"]
                out[(f["counting_head"], f["channel"])] = (f["severity"], int(n.group(1)))
        return out

    shifted = told(log)
    assert shifted == told(SAMPLES / "ws4_health.log")  # not a reset and a burst at the hour set back
    arc = tmp_path / "arc"
    assert runner.invoke(app, ["ingest", str(log), "--archive", str(arc)]).exit_code == 0
    doc = json.loads(runner.invoke(app, ["report", "--archive", str(arc), "--format", "json"]).stdout)
    per_day: dict[str, int] = {}
    for x in doc["trends"]["disturbances_per_head_per_day"]:
        per_day[x["counting_head"]] = per_day.get(x["counting_head"], 0) + x["disturbances"]
    by_head: dict[str, int] = {}
    for (head, _channel), (_severity, n) in shifted.items():
        by_head[head] = by_head.get(head, 0) + n
    assert per_day == by_head and by_head["WS4"] == 8 + 13
