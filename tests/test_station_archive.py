"""station --replay --archive: history from the archive plays through the same replay source as the files."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.cli.commands.station import archive_replay_source
from console.layout import load_layout
from console.tui.replay_source import ReplaySource

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
LOGS = [SAMPLES / "example_station.log", SAMPLES / "crossing_example.csv"]
runner = CliRunner()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("archive")
    result = runner.invoke(app, ["ingest", *map(str, LOGS), "--archive", str(root), "--layout", "example"])
    assert result.exit_code == 0, result.output
    return root


def _played(source: ReplaySource) -> list[dict[str, Any]]:
    """Every event the replay's engine gave, played to the end a minute at a time."""
    events: list[dict[str, Any]] = []
    source.sink = events.append
    while source.now_ns < source.end_ns:
        source.advance(60, skip_quiet=False)
    return [e for e in events if e["type"] != "source"]


def test_archive_replay_equals_the_replay_of_the_files(archive: Path) -> None:
    lay = load_layout("example")
    from_files = ReplaySource(LOGS, lay)
    from_archive = archive_replay_source(archive, lay, None, None)
    assert (from_archive.start_ns, from_archive.end_ns) == (from_files.start_ns, from_files.end_ns)
    assert from_archive.fixes, "the crossing sample has placeable fixes"
    # Played forward the same distance, both reach the same section states.
    from_files.advance(3600, skip_quiet=False)
    from_archive.advance(3600, skip_quiet=False)
    assert {s: from_archive.engine.state(s) for s in [x.id for x in lay.sections]} == {
        s: from_files.engine.state(s) for s in [x.id for x in lay.sections]
    }
    # Played to the end, both gave the same events: passages, section changes, crossings, integrity.
    files_events = _played(ReplaySource(LOGS, lay))
    assert {e["type"] for e in files_events} >= {"passage", "section", "crossing"}
    assert _played(archive_replay_source(archive, lay, None, None)) == files_events


def test_a_window_replays_only_its_history(archive: Path) -> None:
    lay = load_layout("example")
    whole = archive_replay_source(archive, lay, None, None)
    passages = [e for e in _played(whole) if e["type"] == "passage"]
    assert len(passages) > 2, "the sample has several passages"
    cut_at = passages[len(passages) // 2]["start"]
    windowed = archive_replay_source(archive, lay, cut_at, None)
    assert windowed.first_record_ns is not None and whole.first_record_ns is not None
    assert windowed.first_record_ns > whole.first_record_ns
    later = [e for e in _played(windowed) if e["type"] == "passage"]
    assert 0 < len(later) < len(passages)
    assert min(e["start"] for e in later) >= cut_at


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--archive", "ARCH"], "add --replay"),
        (["--replay", "--archive", "ARCH", str(LOGS[0])], "not both"),
        (["--replay", "--archive", "ARCH", "--from", "yesterday-ish"], "--from/--to"),
        (["--replay", "--archive", "MISSING"], "MISSING"),
    ],
)
def test_archive_replay_errors_are_one_line(archive: Path, tmp_path: Path, args: list[str], message: str) -> None:
    argv = [
        "station",
        *[str(archive) if a == "ARCH" else str(tmp_path / "nope") if a == "MISSING" else a for a in args],
    ]
    result = runner.invoke(app, argv)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "internal error" not in lines[0]
    assert message.replace("MISSING", "nope") in lines[0]


def test_a_good_archive_replay_gets_as_far_as_the_terminal_check(archive: Path) -> None:
    # Under CliRunner there is no terminal: reaching that check means the history was read.
    result = runner.invoke(app, ["station", "--replay", "--archive", str(archive)])
    assert result.exit_code == 2
    assert "needs a terminal" in result.output
