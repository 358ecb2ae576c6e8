"""``report --archive`` over a window without health registers, frames, voltages or fixes imports neither
pandas nor ``pyarrow.compute``: the passages are read into numpy columns and written by the byte encoder, no
empty table is made for the health rules, the analog summary or the trends, and the records parts' labels are
looked at through their dictionaries (pandas and its import are a quarter of such a report's time)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from benchmarks.gen_realistic_diag import generate
from console.archive.store import read_current
from console.cli.app import app

runner = CliRunner()

# The report in a process of its own: what it imported is what the command needs (pytest imports pandas).
REPORT = """
import sys
from console.cli.app import app
sys.argv = ["trackside", "report", *sys.argv[1:]]
try:
    app()
except SystemExit as exc:
    assert not exc.code, exc.code
print(" ".join(m for m in ("pandas", "pyarrow.compute") if m in sys.modules), file=sys.stderr)
"""


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A realistic multi-board log (wheel, diagnosis and counter registers): no health register."""
    d = tmp_path_factory.mktemp("nopandas")
    log = d / "a.log"
    generate(6000, log, boards=6, seed=3)
    arc = d / "arc"
    res = runner.invoke(app, ["ingest", str(log), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    return arc


def _report(archive: Path, out: Path, *args: str) -> set[str]:
    """Runs the report into ``out``; which of pandas and pyarrow.compute it imported."""
    done = subprocess.run(
        [sys.executable, "-c", REPORT, "--archive", str(archive), "-o", str(out), *args],
        capture_output=True,
        text=True,
        check=True,
    )
    lines = done.stderr.splitlines()
    return set(lines[-1].split()) if lines else set()


def test_a_report_over_a_window_without_health_registers_imports_no_pandas(archive: Path, tmp_path: Path) -> None:
    day = sorted(p.split("day=")[1][:10] for p in read_current(archive).parts("records"))[0]
    window = ["--from", f"{day}T00:00:00", "--to", f"{day}T23:59:59"]
    for fmt in ("json", "md"):
        out = tmp_path / f"r.{fmt}"
        assert _report(archive, out, "--format", fmt, *window) == set(), fmt
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["passages"] and doc["devices"] and doc["trends"]["axles_per_head_per_day"]
    assert doc["health"]["analog"] == [] and doc["trends"]["analog_margin_per_head_per_day"] == []


def test_the_same_report_with_pandas_loaded_is_the_same_text(archive: Path, tmp_path: Path) -> None:
    # In this process pandas is loaded (pytest's plugins, the other tests): the report must not depend on it.
    import pandas  # noqa: F401

    assert _report(archive, tmp_path / "a.json", "--format", "json") == set()
    res = runner.invoke(app, ["report", "--archive", str(archive), "--format", "json"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "a.json").read_text() == res.stdout
