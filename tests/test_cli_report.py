"""`trackside report` through the command line, as cron runs it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app
from tests.conftest import record

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
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-c", "from console.cli.app import app; app()"]
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


BIDI = "\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069\u200e\u200f\u061c"


def _hostile_log(tmp_path: Path) -> Path:
    """A small log whose name and one rejected line carry a right-to-left override and a non-UTF-8 byte."""
    name = os.fsdecode(b"ws4-\xff-\xe2\x80\xaegol.log")  # U+202E in the name, and a byte that is not UTF-8
    p = tmp_path / name
    p.write_text(record() + "\n" + "junk \u2066spoof\u2069 \u202etxt.exe\n", encoding="utf-8")
    return p


def test_report_shows_bidi_controls_and_undecodable_names_escaped_in_every_format(tmp_path: Path) -> None:
    log = _hostile_log(tmp_path)
    for fmt in ("md", "html", "json"):
        res = CliRunner().invoke(app, ["report", str(log), "--layout", "osong", "--format", fmt])
        assert res.exit_code == 0, res.stderr
        text = res.stdout_bytes.decode("utf-8")  # strict: no lone surrogate reached the output
        assert not set(BIDI) & set(text), fmt
        assert "u202e" in text and "u2066" in text and "xff" in text, fmt
        if fmt == "json":
            doc = json.loads(text)
            # JSON is data: the override stays a character (sent as the inert escape \u202e), the bad byte shown.
            assert doc["inputs"]["files"][0]["file"] == str(tmp_path / "ws4-\\xff-\u202egol.log")


def test_report_reads_standard_input_and_writes_stdout_with_dash(samples_dir: Path = ROOT / "sample_logs") -> None:
    data = (samples_dir / "example_station.log").read_bytes()
    res = CliRunner().invoke(app, ["report", "-", "--layout", "example", "--format", "json", "-o", "-"], input=data)
    assert res.exit_code == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["inputs"]["files"][0]["file"] == "-" and doc["inputs"]["files"][0]["records"] == 3385


def test_report_into_its_input_directory_refuses_to_replace_a_log(tmp_path: Path) -> None:
    log = tmp_path / "station.log"
    log.write_bytes((ROOT / "sample_logs" / "example_station.log").read_bytes())
    res = CliRunner().invoke(app, ["report", str(tmp_path), "--layout", "example", "-o", str(log)])
    assert res.exit_code == 2 and "refusing to write the report over it" in res.stderr
    assert log.read_bytes() == (ROOT / "sample_logs" / "example_station.log").read_bytes()
    # A new report file in the same directory is fine, and is not read back the next time.
    out = tmp_path / "report.md"
    for _ in range(2):
        res = CliRunner().invoke(app, ["report", str(tmp_path), "--layout", "example", "-o", str(out)])
        assert res.exit_code == 0, res.stderr
    assert "report.md" not in out.read_text(encoding="utf-8").split("## Devices")[0].split("not read")[0]


def test_report_over_files_of_every_kind_with_names_that_are_not_utf8(tmp_path: Path) -> None:
    """Each reader keeps its file names in a table: none may need them to be valid UTF-8."""
    prefix = os.fsdecode(b"\xff\xe2\x80\xae")  # a byte that is not UTF-8, then U+202E
    for sample in ("ws4_subsecond.log", "sensor_frames.txt", "can_counts.log", "crossing_example.csv"):
        (tmp_path / (prefix + sample)).write_bytes((ROOT / "sample_logs" / sample).read_bytes())
    for fmt in ("md", "json"):
        res = CliRunner().invoke(app, ["report", str(tmp_path), "--layout", "example", "--format", fmt])
        assert res.exit_code == 0, res.stderr
        text = res.stdout_bytes.decode("utf-8")
        assert "\u202e" not in text and "xff" in text
    formats = {f["file"].rsplit("/", 1)[1]: f["format"] for f in json.loads(text)["inputs"]["files"]}
    assert formats == {
        "\\xff\u202ews4_subsecond.log": "diagnostic",
        "\\xff\u202esensor_frames.txt": "frames",
        "\\xff\u202ecan_counts.log": "can",
        "\\xff\u202ecrossing_example.csv": "gnss-csv",
    }


def test_a_window_on_files_says_it_goes_with_the_archive() -> None:
    # report FILE --from 2026-03-02 said "give input files or --archive, not both": no --archive was given.
    for extra in (["--from", "2026-03-02"], ["--to", "2026-03-03"], ["--head", "WS2"], ["--device", "4082"]):
        res = CliRunner().invoke(app, ["report", LOGS[0], *extra])
        assert res.exit_code == 2, (extra, res.output)
        (line,) = res.stderr.strip().splitlines()
        assert f"{extra[0]} goes with --archive" in line and "not both" not in line, line
    res = CliRunner().invoke(app, ["report", LOGS[0], "--archive", "arc"])
    assert res.exit_code == 2 and "give input files or --archive, not both" in res.stderr
