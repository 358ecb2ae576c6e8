"""Several sources on one command line: `follow A B`, `station --live A --live B` and `--live A B`."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from tests.live_fixtures import read_jsonl, trackside

pytestmark = pytest.mark.timeout(60)

SAMPLE = Path(__file__).resolve().parent.parent / "sample_logs" / "example_station.log"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(trackside(*args), capture_output=True, text=True, timeout=40, stdin=subprocess.DEVNULL)


@pytest.mark.parametrize(
    "live",
    [
        ["--live", "file:{log}", "--live", "can:nosuchbus:x"],
        ["--live", "file:{log}", "can:nosuchbus:x"],
        ["--live", "can:nosuchbus:x", "file:{log}"],
    ],
)
def test_station_takes_every_live_source_in_either_form(tmp_path: Path, live: list[str]) -> None:
    # The second source is checked before the view starts: its error proves it was taken.
    log = tmp_path / "a.log"
    log.write_text("")
    out = run("station", *(a.format(log=log) for a in live))
    assert out.returncode == 2, out
    assert "unknown python-can interface 'nosuchbus'" in out.stderr
    assert len(out.stderr.strip().splitlines()) == 1 and "Traceback" not in out.stderr


def test_a_uri_after_live_keeps_its_double_slash(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_text("")
    out = run("station", "--live", f"file:{log}", "mqtt://127.0.0.1:1883/")
    assert out.returncode == 2
    assert "mqtt://127.0.0.1:1883/: expected a topic" in out.stderr


def test_live_and_replay_together_are_refused(tmp_path: Path) -> None:
    out = run("station", "--live", f"file:{tmp_path / 'a.log'}", "--replay", str(SAMPLE))
    assert out.returncode == 2 and "give one or the other" in out.stderr


def test_follow_reads_every_source_given(tmp_path: Path) -> None:
    lines = SAMPLE.read_bytes().splitlines(keepends=True)
    a, b = tmp_path / "a.log", tmp_path / "b.log"
    a.write_bytes(b"".join(lines[:40]))
    b.write_bytes(b"".join(lines[40:100]) + b"junk line\n")
    out = run("follow", f"file:{a}", str(b), "--from-start", "--jsonl", "--idle-exit", "0.5")
    assert out.returncode == 0, out.stderr
    events = read_jsonl(out.stdout)
    summary = events[-1]
    assert {f["file"]: (f["records"], f["rejected"]) for f in summary["files"]} == {
        str(a): (40, 0),
        str(b): (60, 1),
    }
    assert [s["uri"] for s in summary["sources"]] == [f"file:{a}", str(b)]
    assert all(s["connected"] for s in summary["sources"]) or all(s["messages"] for s in summary["sources"])


@pytest.mark.parametrize("uri", ["mqqt://127.0.0.1:1883/application/+/device/+/event/up", "gspd://127.0.0.1:2947"])
def test_a_misspelt_source_type_is_named_not_taken_for_a_missing_directory(uri: str) -> None:
    # It read as a file path and said "mqqt:/127.0.0.1:1883/application/+/…: no such directory mqqt:/127.0…".
    out = run("follow", uri, "--idle-exit", "0.5")
    assert out.returncode == 2, out
    (line,) = out.stderr.strip().splitlines()
    assert uri in line and f"unknown source type '{uri.split(':')[0]}'" in line and "mqtt://" in line, line
