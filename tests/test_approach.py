"""Work-site approach warnings (seed 003's purpose): from detection vs from speed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.analysis.crossing.approach import approach_timeline
from console.analysis.crossing.controller import earliest_arrival_s
from console.analysis.passages.diagnostics import SpeedSettings
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
