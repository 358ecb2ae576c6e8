"""--jsonl wherever --json is: the same records, one typed object a line, then a summary with the rest.

For each command the lines are compared with its own ``--json`` document: every array the lines stand for,
item by item in order, and the summary equal to the rest of the document.
"""

from __future__ import annotations

import io
import json
import random
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.sinks.tables import section_history
from console.sinks.tables.section_history import _Spill

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
runner = CliRunner()

CASES = {
    "sections": (
        ["sections", str(SAMPLES / "example_station.log"), "--layout", "example"],
        {"sections": "section_end", "timeline": "section", "ledger": "ledger", "resets": "reset"},
    ),
    "health": (["health", str(SAMPLES / "ws4_health.log")], {"findings": "finding", "parse_reports": "parse_report"}),
    "frames": (
        ["frames", str(SAMPLES / "sensor_frames.txt"), str(SAMPLES / "can_counts.asc")],
        {"frames": "frame", "events": "event", "parse_reports": "parse_report"},
    ),
    "gnss": (["gnss", str(SAMPLES / "gnss_devices.csv"), str(SAMPLES / "gnss_devices.jsonl")], {"fixes": "fix"}),
    "crossing": (
        ["crossing", str(SAMPLES / "crossing_example.csv"), "--layout", "example"],
        {"timelines": "timeline", "events": "event", "trains": "train", "integrity": "integrity"},
    ),
    "approach": (
        ["approach", str(SAMPLES / "example_station.log"), "--layout", "example"],
        {"warnings": "approach_warning"},
    ),
}


def _run(argv: list[str]) -> str:
    result = runner.invoke(app, argv)
    assert result.exit_code == 0, result.output
    return result.stdout


@pytest.mark.parametrize("name", sorted(CASES))
def test_the_lines_hold_the_document(name: str) -> None:
    argv, arrays = CASES[name]
    doc = json.loads(_run([*argv, "--json"]))
    lines = [json.loads(line) for line in _run([*argv, "--jsonl"]).splitlines()]
    assert lines and lines[-1]["type"] == "summary" and all(x["type"] != "summary" for x in lines[:-1])
    kinds = {v: k for k, v in arrays.items()}
    got: dict[str, list[Any]] = {k: [] for k in arrays}
    for line in lines[:-1]:
        kind = line.pop("type")
        assert kind in kinds, f"{name}: a line of type {kind}"
        got[kinds[kind]].append(line)
    assert any(got.values()), f"{name}: the sample gives records"
    for key in arrays:
        assert got[key] == doc.pop(key), f"{name}: {key}"
    summary = lines[-1]
    summary.pop("type")
    assert summary == doc


@pytest.mark.parametrize("name", sorted(CASES))
def test_json_and_jsonl_together_is_a_one_line_error(name: str) -> None:
    argv, _ = CASES[name]
    result = runner.invoke(app, [*argv, "--json", "--jsonl"])
    assert result.exit_code == 2
    assert result.output.strip().splitlines() == ["trackside: error: --json and --jsonl: choose one"]


def test_spilled_rows_read_back_whole_across_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rows with commas, braces and quotes in their strings, read back through blocks of a few bytes."""
    monkeypatch.setattr(section_history, "SPILL_BLOCK_BYTES", 7)
    rng = random.Random(5)
    rows = [
        {
            "section": rng.choice(["B1", "a,b", "{x}", 'q"']),
            "count": rng.randint(-3, 99),
            "reason": "," * rng.randint(0, 9),
        }
        for _ in range(300)
    ]
    spill = _Spill()
    try:
        for r in rows:
            spill.add(json.dumps(r, separators=(",", ":")))
        assert [json.loads(t) for t in spill.read_back()] == rows
        out = io.StringIO()
        spill.copy_to(out)
        assert json.loads(out.getvalue()) == rows
    finally:
        spill.file.close()
