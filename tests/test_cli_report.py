"""`trackside report` through the command line, as cron runs it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from console.cli import app

ROOT = Path(__file__).resolve().parents[1]
LOGS = [str(ROOT / "sample_logs" / "example_station.log"), str(ROOT / "sample_logs" / "crossing_example.csv")]


def test_report_writes_markdown_quietly_and_fails_on_warning(tmp_path: Path) -> None:
    out = tmp_path / "r.md"
    res = CliRunner().invoke(app, ["report", *LOGS, "--layout", "example", "-o", str(out)])
    assert res.exit_code == 0, res.stderr
    assert res.stdout == ""  # with -o nothing is printed
    text = out.read_text(encoding="utf-8")
    assert text.startswith("# trackside report")
    # The sample ends with B1 and B2 disturbed (a missed axle at WS3): failing, not unsafe.
    res = CliRunner().invoke(app, ["report", *LOGS, "--layout", "example", "--fail-on", "warning", "-o", str(out)])
    assert res.exit_code == 1
    res = CliRunner().invoke(app, ["report", *LOGS, "--layout", "example", "--fail-on", "critical", "-o", str(out)])
    assert res.exit_code == 0


def test_report_usage_errors_exit_2() -> None:
    for args in (["--format", "pdf"], ["--fail-on", "loud"], ["--layout", "nowhere.toml"]):
        res = CliRunner().invoke(app, ["report", *LOGS, *args])
        assert res.exit_code == 2, args
        assert res.stderr.startswith("trackside: error:")
        assert "Traceback" not in res.stderr
    res = CliRunner().invoke(app, ["report", "no_such_dir"])
    assert res.exit_code == 2


def test_report_json_as_a_subprocess() -> None:
    exe = Path(sys.executable).with_name("trackside")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli import app; app()"]
    proc = subprocess.run(
        [*cmd, "report", *LOGS, "--layout", "example", "--format", "json"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""  # quiet when not on a terminal
    doc = json.loads(proc.stdout)
    assert doc["schema"].startswith("trackside.report/")
