"""A file of the wrong kind is refused with one line naming it and what it looks like (exit 2),
by every command, not read as every line rejected."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.cli import app

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
runner = CliRunner()

DIAG = SAMPLES / "example_station.log"
WRONG_FOR_DIAG = {
    "gnss device CSV": (SAMPLES / "gnss_devices.csv", "GNSS device CSV"),
    "gnss JSON lines": (SAMPLES / "gnss_devices.jsonl", "JSON lines"),
    "monitoring-centre table": (SAMPLES / "co_nhu_van_2026_centre_table.tsv", "monitoring-centre table"),
    "sensor frames": (SAMPLES / "sensor_frames.txt", "frame log"),
    "voltages": (SAMPLES / "am_thuong_2021-06-06_voltages.csv", "voltage table"),
}
DIAG_COMMANDS = {
    "analyze": [],
    "speeds": [],
    "sections": ["--layout", "example"],
    "health": [],
    "approach": ["--layout", "example"],
}


@pytest.mark.parametrize("command", list(DIAG_COMMANDS))
@pytest.mark.parametrize("kind", list(WRONG_FOR_DIAG))
def test_diag_commands_refuse_another_kind_of_file(command: str, kind: str) -> None:
    path, looks_like = WRONG_FOR_DIAG[kind]
    result = runner.invoke(app, [command, str(path), *DIAG_COMMANDS[command]])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1
    assert path.name in lines[0] and "not an axle-counter diagnostic log" in lines[0]
    assert looks_like in lines[0]


@pytest.mark.parametrize("command", ["gnss", "crossing"])
def test_gnss_commands_refuse_a_diagnostic_log(command: str) -> None:
    extra = ["--layout", "example"] if command == "crossing" else []
    result = runner.invoke(app, [command, str(DIAG), *extra])
    assert result.exit_code == 2, result.output
    assert "nothing readable as GNSS: looks like an axle-counter diagnostic log" in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_a_damaged_diagnostic_log_is_still_read_line_by_line(tmp_path: Path) -> None:
    # Refusal is for files that plainly hold something else; damage is rejected per line.
    damaged = tmp_path / "damaged.log"
    good = DIAG.read_bytes().splitlines(keepends=True)
    damaged.write_bytes(b"".join(good[:200]) + b"\x00\xff garbage line\n" + b"".join(good[200:400]))
    result = runner.invoke(app, ["analyze", str(damaged), "--json"])
    assert result.exit_code == 0, result.output
    assert '"rejected":1' in result.output.replace(" ", "")
