"""Where a passage has no wheel onset on one system (or none), no axle can be paired: its axles are
shown "–" with one line saying why; JSON says why in ``axles_unknown_reason`` (``axles`` stays the number
of pairs found, as version 1 documents always had it)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
OSONG = sorted(str(p) for p in SAMPLES.glob("osong_*.log"))
runner = CliRunner()


def _axles_cells(output: str) -> list[str]:
    rows = [line.split() for line in output.splitlines() if line.strip().startswith("WS4 ")]
    return [r[5] for r in rows]  # Head, date, time, Dur s, Recs, Axles


def test_quick_start_shows_no_axle_count_where_none_can_be_paired() -> None:
    # The paper's whole-second excerpts (Kim You-Ho et al.) log wheel onsets on Sys1 only, or none.
    result = runner.invoke(app, ["analyze", *OSONG], env={"COLUMNS": "100"})
    assert result.exit_code == 0, result.output
    assert _axles_cells(result.output) == ["–", "–", "–"]
    why = [line for line in result.output.splitlines() if "Axles –" in line]
    assert why and "no axle can be paired" in " ".join(result.output.split())
    assert "wheel detections on one system only" not in result.output  # explained by that line


def test_json_gives_the_reason_beside_the_pairs_found() -> None:
    result = runner.invoke(app, ["analyze", *OSONG, "--json"])
    assert result.exit_code == 0, result.output
    passages = json.loads(result.output)["passages"]
    assert [(p["axles"], p["axles_unknown_reason"]) for p in passages] == [
        (0, "wheel onsets on Sys1 only"),
        (0, "wheel onsets on Sys1 only"),
        (0, "no wheel onset"),
    ]


def test_counted_axles_are_unchanged_and_have_no_reason() -> None:
    # ws4_subsecond.log: two trams of 8 axles; the trolley damps Sys1 only (sample_logs/README.md).
    result = runner.invoke(app, ["speeds", str(SAMPLES / "ws4_subsecond.log"), "--json"])
    assert result.exit_code == 0, result.output
    got = [(p["axles"], p["axles_unknown_reason"]) for p in json.loads(result.output)["passages"]]
    assert got == [(8, None), (0, "wheel onsets on Sys1 only"), (8, None)]


def test_jsonl_and_json_agree() -> None:
    lines = runner.invoke(app, ["analyze", *OSONG, "--jsonl"]).output.splitlines()
    from_lines = [json.loads(x) for x in lines if '"type":"passage"' in x.replace(" ", "")]
    whole = json.loads(runner.invoke(app, ["analyze", *OSONG, "--json"]).output)["passages"]
    assert [p["axles_unknown_reason"] for p in from_lines] == [p["axles_unknown_reason"] for p in whole]
