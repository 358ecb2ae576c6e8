"""Messages that count things agree with the count: "1 record", never "1 records"."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app
from console.plural import count, plural

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
runner = CliRunner()


def test_plural_helper() -> None:
    assert count(1, "record") == "1 record"
    assert count(0, "record") == "0 records"
    assert count(2, "fix") == "2 fixes"
    assert count(1204, "finding", sep=True) == "1,204 findings"
    assert plural(1, "passage") == "passage"


def test_analyze_overlap_note_of_one_record_is_singular() -> None:
    # The quick start: the 09:32 passage excerpt repeats one record of the detection excerpt.
    files = sorted(str(p) for p in SAMPLES.glob("osong_*.log"))
    result = runner.invoke(app, ["analyze", *files], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert "1 record repeats another file's records (overlapping exports) and was counted once" in " ".join(
        result.output.split()
    )
    assert "1 records" not in result.output


def test_follow_summary_counts_are_singular_for_one() -> None:
    from console.cli.commands.follow import _summary_lines

    summary = {
        "passages": 1,
        "section_changes": 1,
        "crossing_events": 1,
        "integrity_events": 1,
        "health_findings": 1,
        "status_only_passages": 1,
        "files": [{"file": "a.log", "lines_read": 1, "records": 1, "blank": 1, "rejected": 1}],
        "sources": [{"uri": "x", "messages": 1, "lost": 1, "malformed": 1, "duplicates": 1, "detail": "d"}],
        "sections": {},
    }
    first, file_line, source_line = _summary_lines(summary)
    assert first.startswith(
        "followed: 1 passage, 1 section change, 1 crossing event, 1 integrity change, 1 health finding;"
    )
    assert "1 status-only record burst (no wheel onset) not listed" in first
    assert file_line.strip() == "a.log: 1 line = 1 record + 1 blank + 1 rejected"
    assert "1 message, 1 lost, 1 malformed, 1 duplicate" in source_line


def test_ingest_summary_of_one_file(tmp_path: Path) -> None:
    log = tmp_path / "one.log"
    log.write_bytes((SAMPLES / "osong_ws4_1732_passage.log").read_bytes().splitlines(keepends=True)[0])
    result = runner.invoke(app, ["ingest", str(log), "--archive", str(tmp_path / "arc")])
    assert result.exit_code == 0, result.output
    assert ": 1 record, 0 rejected" in result.output
    assert "1 file added, 0 skipped; 1 record, 0 rejected lines" in result.output


def test_one_hidden_info_finding_is_singular() -> None:
    # analyze --layout on the example morning hides one info finding (the health command lists it).
    log = SAMPLES / "example_station.log"
    result = runner.invoke(app, ["analyze", str(log), "--layout", "example"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert "1 info finding not shown" in result.output


def test_follow_summary_says_what_a_second_interrupt_left_unanalysed() -> None:
    from console.cli.commands.follow import _summary_lines

    summary = {
        "passages": 0,
        "section_changes": 0,
        "crossing_events": 0,
        "health_findings": 0,
        "files": [{"file": "a.log", "lines_read": 41, "records": 41, "blank": 0, "rejected": 0}],
        "not_analysed": [{"file": "a.log", "from_line": 42}],
        "items_not_analysed": 1,
        "sources": [],
        "sections": {},
    }
    lines = _summary_lines(summary)
    assert "  a.log: not analysed from line 42 on (stopped at a second interrupt)" in lines
    assert "  1 item read but not analysed (stopped at a second interrupt)" in lines
