"""A device whose heads give one identity register different values (two serial numbers): the latest
reading is the device's, in the batch whatever the order of the files, and in the report of an archive,
the same from run to run (DuckDB gave the archive's registers in a different order from run to run)."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app

LINE = (
    "Diag_id:00002\tID:4084\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:1\tAdr:016\tLabel:Seriennum"
    "\tData:{serial}\tDate:2015-10-31\tTime:{time}\n"
)


def _log(path: Path, head: str, serial: int, times: list[str]) -> Path:
    path.write_text("".join(LINE.format(head=head, serial=serial, time=t) for t in times), encoding="utf-8")
    return path


def _serials(args: list[str]) -> list[str | None]:
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    return [d["serial_number"] for d in doc["devices"]]


def test_the_latest_reading_of_a_register_is_the_devices(tmp_path: Path) -> None:
    older = _log(tmp_path / "ws5.log", "WS5", 4804, ["05:59:31.024", "06:10:00.000"])
    newer = _log(tmp_path / "ws4.log", "WS4", 4803, ["06:00:00.000", "06:20:00.500"])
    # In the batch: the same device whichever file comes first (it was the register read first).
    assert _serials(["analyze", "--json", str(older), str(newer)]) == ["4803"]
    assert _serials(["analyze", "--json", str(newer), str(older)]) == ["4803"]
    # The archive's report: the batch's answer, every run.
    arc = tmp_path / "arc"
    ingest = CliRunner().invoke(app, ["ingest", str(older), str(newer), "--archive", str(arc)])
    assert ingest.exit_code == 0, ingest.output
    out = tmp_path / "r.json"
    runs = set()
    for _ in range(8):
        report = CliRunner().invoke(app, ["report", "--archive", str(arc), "--format", "json", "-o", str(out)])
        assert report.exit_code == 0, report.output
        runs.add(out.read_bytes())
        assert [d["serial_number"] for d in json.loads(out.read_text())["devices"]] == ["4803"]
    assert len(runs) == 1
    # The later reading moves the answer: WS5 read again after WS4's last.
    later = _log(tmp_path / "ws5b.log", "WS5", 4804, ["06:30:00.000"])
    assert _serials(["analyze", "--json", str(older), str(newer), str(later)]) == ["4804"]
