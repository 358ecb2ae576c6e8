"""`report --archive … --head H` / `--device D` is about that head or device: verdict, findings, inputs, sections."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.layout import load_layout

runner = CliRunner()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run whose WS3 loses a channel: sections B1 and B2 (between WS2-WS3 and WS3-WS4) end disturbed."""
    tmp = tmp_path_factory.mktemp("scope")
    run = tmp / "run"
    res = runner.invoke(
        app,
        ["simulate", "-o", str(run), "--duration", "20m", "--trains-per-hour", "12", "--fault", "dead_channel:WS3:5m"],
    )
    assert res.exit_code == 0, res.output
    arc = tmp / "arc"
    res = runner.invoke(app, ["ingest", str(run), "--archive", str(arc), "--layout", str(run / "layout.toml")])
    assert res.exit_code == 0, res.output
    return arc


def _report(arc: Path, *scope: str) -> dict[str, Any]:
    res = runner.invoke(app, ["report", "--archive", str(arc), "--format", "json", *scope])
    assert res.exit_code == 0, res.output
    return dict(json.loads(res.stdout))


def _bounded(arc: Path, head: str) -> set[str]:
    layout = load_layout(str(arc.parent / "run" / "layout.toml"))
    return {s.id for s in layout.sections if head in s.heads}


def test_the_whole_archive_fails_on_ws3(archive: Path) -> None:
    doc = _report(archive)
    assert doc["verdict"] == "failing"
    subjects = {i["subject"] for i in doc["safety"]["items"]}
    assert {"section B1", "section B2", "WS3 Sys1"} <= subjects


def test_a_head_away_from_the_fault_is_ok_and_only_about_itself(archive: Path) -> None:
    doc = _report(archive, "--head", "WS5")
    assert doc["verdict"] == "ok", doc["safety"]
    assert doc["scope"].startswith("counting head WS5")
    assert [d["counting_heads"] for d in doc["devices"]] == [["WS5"]]
    assert {s["sensor"] for s in doc["sensors"]} == {"WS5"}
    assert {p["counting_head"] for p in doc["passages"]} == {"WS5"}
    # Only the files that hold its records: the diagnostic log and the sensor frames, not the GNSS streams.
    files = {Path(f["file"]).name for f in doc["inputs"]["files"]}
    assert files == {"diagnostic.log", "sensor_frames.txt"}
    assert doc["inputs"]["totals"]["files"] == 2
    secs = doc["sections"]
    assert {r["section"] for r in secs["final"]} == _bounded(archive, "WS5")
    assert {r["section"] for r in secs["timeline"]} <= _bounded(archive, "WS5")
    assert {r["head"] for r in secs["ledger_summary"]} == {"WS5"}
    assert not doc["crossings"]["timelines"] if isinstance(doc["crossings"], dict) else not doc["crossings"]
    assert "crossings" in doc["notes"]
    assert all(f["counting_head"] == "WS5" for f in doc["health"]["findings"])


def test_a_head_that_bounds_a_disturbed_section_fails_on_that_section_only(archive: Path) -> None:
    doc = _report(archive, "--head", "WS2")
    assert doc["verdict"] == "failing"
    assert {i["subject"] for i in doc["safety"]["items"]} == {"section B1"}  # B2 is not WS2's
    assert {r["section"] for r in doc["sections"]["final"]} == _bounded(archive, "WS2")
    assert {r["head"] for r in doc["sections"]["ledger_summary"]} == {"WS2"}


def test_a_device_scope_is_its_heads(archive: Path) -> None:
    by_head = _report(archive, "--head", "WS5")
    device = by_head["devices"][0]["device_id"]
    doc = _report(archive, "--device", str(device))
    assert doc["scope"].startswith(f"device {device}")
    for key in ("verdict", "safety", "devices", "sensors", "passages", "sections", "health"):
        assert doc[key] == by_head[key], key
    assert doc["inputs"] == by_head["inputs"]


def test_the_markdown_says_what_the_report_is_about(archive: Path) -> None:
    res = runner.invoke(app, ["report", "--archive", str(archive), "--head", "WS5"])
    assert res.exit_code == 0
    assert "About: counting head WS5" in res.stdout
    assert "Verdict: OK" in res.stdout
    assert "WS3" not in res.stdout.split("## 2.")[0]


def test_a_scope_with_nothing_in_the_archive_is_an_error_not_an_ok(archive: Path) -> None:
    for scope in (["--device", "999"], ["--head", "WS9"]):
        res = runner.invoke(app, ["report", "--archive", str(archive), *scope])
        assert res.exit_code == 2, res.output
        assert res.stderr.startswith("trackside: error: ") and res.stderr.count("\n") == 1
        assert "no record, frame or voltage of it" in res.stderr


def test_the_report_says_its_window_and_refuses_an_empty_one(archive: Path) -> None:
    """The simulated run starts 2026-03-02 08:00 (SimConfig): a window over its first ten minutes."""
    doc = _report(archive, "--from", "2026-03-02T08:00", "--to", "2026-03-02T08:10")
    assert doc["scope"] == "the archive's history from 2026-03-02 08:00:00 until 2026-03-02 08:10:00 (excluded)"
    assert "scope" not in _report(archive)  # the whole archive: nothing to say
    head = _report(archive, "--head", "WS5", "--from", "2026-03-02T08:00")
    assert head["scope"].startswith("counting head WS5") and head["scope"].endswith("from 2026-03-02 08:00:00")
    for window in (
        ["--from", "2026-03-02T09:00", "--to", "2026-03-02T08:00"],
        ["--from", "2026-03-02", "--to", "2026-03-02"],
    ):
        for command in (["report", "--archive", str(archive)], ["station", "--replay", "--archive", str(archive)]):
            res = runner.invoke(app, [*command, *window])
            assert res.exit_code == 2, res.output
            assert res.stderr.count("\n") == 1 and "is not before to" in res.stderr


@pytest.mark.parametrize("window", [["--from", "9999-01-01"], ["--to", "1600-01-01"], ["--from", "2262-04-12"]])
def test_a_window_beyond_the_times_a_log_holds_is_one_line(archive: Path, window: list[str]) -> None:
    # It was "internal error: ConversionException: ... Could not convert Timestamp to higher precision".
    for command in (["report", "--archive", str(archive)], ["station", "--replay", "--archive", str(archive)]):
        res = runner.invoke(app, [*command, *window])
        assert res.exit_code == 2, res.output
        assert res.stderr.startswith("trackside: error: --from/--to: ") and res.stderr.count("\n") == 1
        assert "outside the times a log can hold (1677 to 2262)" in res.stderr
        assert "internal error" not in res.stderr


@pytest.mark.parametrize("window", [["--from", "2030-01-01"], ["--to", "2026-03-01"]])
def test_a_window_with_nothing_of_the_archive_is_refused_not_reported_ok(archive: Path, window: list[str]) -> None:
    # It gave "Verdict: OK", listed every archived file as read, and warned that no GNSS unit was named
    # <train>-head / -eot (the run's units are; they were outside the window).
    res = runner.invoke(app, ["report", "--archive", str(archive), "--format", "json", *window])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("trackside: error: --from/--to: the archive holds no record, frame or fix")
    assert res.stdout == ""


def test_a_scoped_report_warns_only_of_its_own_heads(tmp_path: Path) -> None:
    """The README's archive: the Osong logs' WS4/WS5 devices differ from the example layout's; a report on WS2
    does not carry those warnings, nor the GNSS one (it judges no crossing)."""
    from tests.conftest import SAMPLES

    arc = tmp_path / "arc"
    res = runner.invoke(app, ["ingest", str(SAMPLES), "--archive", str(arc), "--layout", "example"])
    assert res.exit_code == 0, res.output
    whole = _report(arc)["warnings"]
    assert any(w.startswith("counting head WS4:") for w in whole)
    ws2 = _report(arc, "--head", "WS2")["warnings"]
    assert not any(w.startswith(("counting head WS4", "counting head WS5", "no GNSS")) for w in ws2), ws2
    ws4 = _report(arc, "--head", "WS4")["warnings"]
    assert any(w.startswith("counting head WS4:") for w in ws4)
