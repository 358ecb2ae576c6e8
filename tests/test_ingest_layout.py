"""`ingest DIR` of a `simulate` output uses the directory's layout.toml, by the rule `report DIR` uses."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from console.archive.store import read_current
from console.cli.app import app

runner = CliRunner()


def _count(archive: Path, table: str) -> int:
    res = runner.invoke(
        app, ["query", f"SELECT count(*) AS n FROM {table}", "--archive", str(archive), "--format", "json"]
    )
    assert res.exit_code == 0, res.output
    return int(json.loads(res.stdout)[0]["n"])


def test_ingest_of_a_simulated_run_derives_sections_and_crossings_from_its_layout(tmp_path: Path) -> None:
    run = tmp_path / "run"
    sim = runner.invoke(app, ["simulate", "-o", str(run), "--duration", "20m", "--trains-per-hour", "12"])
    assert sim.exit_code == 0, sim.output
    arc = tmp_path / "arc"
    res = runner.invoke(app, ["ingest", str(run), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    assert f"{run / 'layout.toml'}: the layout used" in res.stdout
    assert read_current(arc).derived["layout"] == str((run / "layout.toml").resolve())
    assert _count(arc, "section_states") > 0
    assert _count(arc, "crossing_timelines") > 0


def test_a_layout_option_wins_over_the_directorys_as_in_report(tmp_path: Path) -> None:
    run = tmp_path / "run"
    assert runner.invoke(app, ["simulate", "-o", str(run), "--duration", "5m"]).exit_code == 0
    arc = tmp_path / "arc"
    res = runner.invoke(app, ["ingest", str(run), "--archive", str(arc), "--layout", "osong"])
    assert res.exit_code == 0, res.output
    assert read_current(arc).derived["layout"] == "osong"
    assert "not used: --layout given" in res.stdout
