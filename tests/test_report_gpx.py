"""A GPX track among a report's inputs is read as GNSS, not listed as 'not read'."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app

GPX = Path(__file__).resolve().parent / "data" / "gnss" / "track_gpx11_garmin.gpx"


def test_report_reads_a_gpx_track_as_gnss(tmp_path: Path) -> None:
    shutil.copy(GPX, tmp_path / GPX.name)
    result = CliRunner().invoke(app, ["report", str(tmp_path), "--layout", "example", "--format", "json"])
    assert result.exit_code == 0, result.output
    files = json.loads(result.output)["inputs"]["files"]
    (entry,) = [f for f in files if f["file"].endswith(GPX.name)]
    assert entry["format"] == "gpx" and entry["read"] is True
    assert entry["records"] > 0 and entry["rejected"] == 0
