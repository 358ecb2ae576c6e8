"""Work-site approach warnings (seed 003's purpose): from detection vs from speed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.analysis.crossing.approach import approach_timeline
from console.analysis.crossing.values import earliest_arrival_s
from console.analysis.passages.speed_settings import SpeedSettings
from console.cli.app import app
from console.layout import WorkSite, load_layout
from tests.reads import whole_job

TRACKSIDE = str(Path(sys.executable).with_name("trackside"))


def test_earliest_arrival_with_and_without_acceleration() -> None:
    assert earliest_arrival_s(300.0, 10.0, 0.0, 10.0) == pytest.approx(30.0)
    assert earliest_arrival_s(300.0, 10.0, 0.5, 10.0) == pytest.approx(30.0)  # already at the limit
    t = earliest_arrival_s(300.0, 0.0, 0.5, 100.0)
    assert t == pytest.approx((2 * 300 / 0.5) ** 0.5)  # from standstill: s = a t² / 2
    assert earliest_arrival_s(0.0, 5.0, 0.5, 10.0) == 0.0


def test_speed_based_alarm_gives_the_warning_time_and_saves_the_rest(samples: Path) -> None:
    lay = load_layout("osong")  # switch works 150 m up the line from WS4, 20 s warning, 20 km/h limit
    job = whole_job([samples / "ws4_subsecond.log"], SpeedSettings())
    (row,) = approach_timeline(job.analysis.passages, lay, lay.work_sites[0])
    # The up tram, 8 axles at 16.1-18.0 km/h (mean 17.05): 150 m at 4.74 m/s is 31.7 s.
    assert row.speed_kmh == pytest.approx(17.05, abs=0.01) and row.lead_fixed_s == pytest.approx(31.68, abs=0.05)
    # It could still speed up to the 20 km/h limit: earliest arrival 27.1 s, alarm 7.1 s after detection.
    assert row.lead_speed_s == pytest.approx(24.6, abs=0.2) and row.lead_speed_s >= 20
    assert row.saved_s == pytest.approx(7.1, abs=0.2)


def test_trains_running_away_from_the_site_do_not_alarm(samples: Path) -> None:
    lay = load_layout("osong")
    job = whole_job([samples / "ws4_subsecond.log"], SpeedSettings())
    down_site = WorkSite("behind", "WS4", -150.0, 20.0)
    rows = approach_timeline(job.analysis.passages, lay, down_site)
    assert [r.t_detect_ns for r in rows] == [int(job.analysis.passages.iloc[2]["start_ns"])]  # the down tram only


def test_a_site_too_close_for_the_warning_time_is_flagged(samples: Path) -> None:
    lay = load_layout("osong")
    job = whole_job([samples / "ws4_subsecond.log"], SpeedSettings())
    (row,) = approach_timeline(job.analysis.passages, lay, WorkSite("close", "WS4", 60.0, 30.0))
    assert row.saved_s == 0.0 and "move the warning point further out" in row.note


def test_approach_cli(samples: Path) -> None:
    res = CliRunner().invoke(app, ["approach", str(samples / "example_station.log"), "--layout", "example", "--json"])
    assert res.exit_code == 0
    rows = json.loads(res.stdout)["warnings"]
    assert len(rows) == 3  # the three up trains past WS2; the down train and the trolley do not alarm
    assert all(r["lead_speed_s"] >= 30 and r["saved_s"] > 0 for r in rows)
    bad = CliRunner().invoke(
        app,
        ["approach", str(samples / "example_station.log"), "--layout", "example", "--head", "WS9", "--distance", "5"],
    )
    assert bad.exit_code == 2


def test_approach_without_a_layout_says_it_needs_one(samples: Path) -> None:
    """It read any log against the shipped osong layout: example_station's WS4 (another line's head) gave
    three "switch-works" warnings, exit 0, without a word."""
    res = subprocess.run(
        [TRACKSIDE, "approach", str(samples / "example_station.log")], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr == "trackside: error: Missing option '--layout'. (see trackside approach --help)\n"
    helped = subprocess.run([TRACKSIDE, "approach", "--help"], capture_output=True, text=True, timeout=120)
    assert "--layout is required" in helped.stdout and "[required]" in helped.stdout


def _warnings(samples: Path, *extra: str) -> list[dict[str, object]]:
    res = CliRunner().invoke(
        app, ["approach", str(samples / "example_station.log"), "--layout", "example", "--json", *extra]
    )
    assert res.exit_code == 0, res.output
    return list(json.loads(res.stdout)["warnings"])


def test_warning_time_applies_to_the_layouts_sites_too(samples: Path) -> None:
    """--warning-time was read for an ad-hoc site only: with the layout's sites 90 (or 1e9) changed nothing."""
    own = _warnings(samples)  # gang-11+400: 30 s, and the trains give it 42-45 s from detection
    assert own and all(r["saved_s"] > 0 and r["note"] == "" for r in own)
    longer = _warnings(samples, "--warning-time", "90")
    assert [r["t_detect"] for r in longer] == [r["t_detect"] for r in own]
    assert all(r["saved_s"] == 0 and "move the warning point further out" in str(r["note"]) for r in longer)


@pytest.mark.parametrize(
    ("extra", "said"),
    [
        (["--warning-time", "1e6"], "Invalid value for '--warning-time': 1000000.0 is not in the range 1<=x<=86400"),
        (["--head", "WS3", "--distance", "1e8"], "--distance: expected at most 1e+07 m either way, got 1e+08"),
    ],
)
def test_approach_options_beyond_what_a_layout_takes_are_refused(samples: Path, extra: list[str], said: str) -> None:
    """The bounds a layout's [[work_sites]] have (a warning time up to a day, a distance up to 10 000 km): a
    site 1e9 m out was a table of three-year leads."""
    res = subprocess.run(
        [TRACKSIDE, "approach", str(samples / "example_station.log"), "--layout", "example", *extra],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 2 and res.stdout == ""
    assert said in res.stderr and len(res.stderr.splitlines()) == 1, res.stderr


def test_an_arrival_after_midnight_is_marked_a_day_later() -> None:
    """The Arrives column is a time of day beside Detected's date: a train detected at 23:59:50 that arrives
    40 s after midnight read as arriving before it was detected."""
    import datetime as dt

    from rich.console import Console

    from console.analysis.crossing.approach import ApproachRow
    from console.analysis.timefmt import time_ns
    from console.sinks.tables.approach_tables import approach_table

    def row(detect: dt.datetime, arrive_s: float) -> ApproachRow:
        t = time_ns(detect)
        arrival = t + int(arrive_s * 1e9)
        return ApproachRow("WS1", "H1", t, 80.0, "measured", arrival, t, arrive_s, arrive_s, 0.0, "")

    day = dt.datetime(2026, 3, 2, 23, 59, 50)  # naive UTC, as parse_time gives
    out = Console(width=160, record=True)
    out.print(approach_table([row(day, 50.0), row(day - dt.timedelta(hours=1), 50.0)]))
    text = out.export_text()
    assert "2026-03-02 23:59:50" in text and "00:00:40+1" in text
    assert "23:00:40" in text and "23:00:40+" not in text  # the same day: no mark
