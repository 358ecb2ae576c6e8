"""station --replay --archive: history from the archive plays through the same replay source as the files."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.cli.commands.station import archive_replay_source
from console.layout import load_layout
from console.tui.sources import ReplaySource

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
LOGS = [SAMPLES / "example_station.log", SAMPLES / "crossing_example.csv"]
runner = CliRunner()


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("archive")
    result = runner.invoke(app, ["ingest", *map(str, LOGS), "--archive", str(root), "--layout", "example"])
    assert result.exit_code == 0, result.output
    return root


def test_archive_replay_equals_the_replay_of_the_files(archive: Path) -> None:
    lay = load_layout("example")
    from_files = ReplaySource(LOGS, lay)
    from_archive = archive_replay_source(archive, lay, None, None)
    assert [(e.time_ns, e.kind, e.head) for e in from_archive.events] == [
        (e.time_ns, e.kind, e.head) for e in from_files.events
    ]
    assert [(f.t_ns, f.train, f.role, round(f.chainage_m, 6)) for f in from_archive.fixes] == [
        (f.t_ns, f.train, f.role, round(f.chainage_m, 6)) for f in from_files.fixes
    ]
    assert from_archive.fixes, "the crossing sample has placeable fixes"
    assert (from_archive.start_ns, from_archive.end_ns) == (from_files.start_ns, from_files.end_ns)
    # Played forward the same distance, both reach the same section states.
    from_files.advance(3600, skip_quiet=False)
    from_archive.advance(3600, skip_quiet=False)
    assert {s: from_archive.engine.state(s) for s in [x.id for x in lay.sections]} == {
        s: from_files.engine.state(s) for s in [x.id for x in lay.sections]
    }


def test_a_window_replays_only_its_history(archive: Path) -> None:
    lay = load_layout("example")
    whole = archive_replay_source(archive, lay, None, None)
    first = whole.events[0].time_ns
    cut = archive_replay_source(archive, lay, None, None)
    later = [e for e in cut.events if e.time_ns > first]
    assert later, "the sample has more than one detection time"
    import datetime as dt

    start = dt.datetime.fromtimestamp(later[len(later) // 2].time_ns / 1e9, dt.UTC).isoformat()
    windowed = archive_replay_source(archive, lay, start, None)
    assert 0 < len(windowed.events) < len(whole.events)
    assert min(e.time_ns for e in windowed.events) >= later[len(later) // 2].time_ns - 1_000_000


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
