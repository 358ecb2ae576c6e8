"""The archive's ingest and query as a user runs them: once per file, growing files, read-only SQL."""

from __future__ import annotations

import fcntl
import gzip
import json
import os
from pathlib import Path

import pytest
from typer.testing import CliRunner, Result

from console.archive.store import read_current
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()
STATION = SAMPLES / "example_station.log"


def _ingest(archive: Path, *paths: Path | str, extra: tuple[str, ...] = (), stdin: bytes | None = None) -> Result:
    return runner.invoke(app, ["ingest", *map(str, paths), "--archive", str(archive), *extra], input=stdin)


def _query(archive: Path, sql: str, *extra: str) -> Result:
    return runner.invoke(app, ["query", sql, "--archive", str(archive), "--format", "json", *extra])


def _rows(archive: Path, sql: str) -> list[dict[str, object]]:
    res = _query(archive, sql)
    assert res.exit_code == 0, res.output
    return list(json.loads(res.stdout))


def _count(archive: Path, table: str = "records") -> int:
    return int(_rows(archive, f"SELECT count(*) AS n FROM {table}")[0]["n"])  # type: ignore[call-overload]


def test_ingesting_the_same_file_twice_adds_nothing(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    first = _ingest(arc, STATION)
    assert first.exit_code == 0, first.output
    n = _count(arc)
    assert n == 3385  # every record of the sample
    gen = read_current(arc).generation
    again = _ingest(arc, STATION)
    assert again.exit_code == 0
    assert "already ingested" in again.stdout and "archive unchanged" in again.stdout
    assert read_current(arc).generation == gen
    assert _count(arc) == n
    # The same content under another name is the same file.
    copy = tmp_path / "copy.log"
    copy.write_bytes(STATION.read_bytes())
    assert "already ingested" in _ingest(arc, copy).stdout
    assert _count(arc) == n


def test_records_keep_their_file_and_line(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    rows = _rows(arc, "SELECT file, line, counting_head, value FROM records ORDER BY line")
    assert [r["line"] for r in rows] == list(range(1, 35))
    assert {r["file"] for r in rows} == {str((SAMPLES / "osong_ws4_0932_detection.log").resolve())}


def test_a_grown_file_is_read_from_where_the_last_ingest_stopped(tmp_path: Path) -> None:
    lines = STATION.read_bytes().splitlines(keepends=True)
    log = tmp_path / "growing.log"
    # The first piece ends in the middle of a line: that line waits for its end.
    log.write_bytes(b"".join(lines[:1000]) + lines[1000][:20])
    arc = tmp_path / "arc"
    _ingest(arc, log)
    assert _count(arc) == 1000
    with log.open("ab") as f:
        f.write(lines[1000][20:] + b"".join(lines[1001:]))
    res = _ingest(arc, log)
    assert "grown: read from byte" in res.stdout
    assert _count(arc) == len(lines)
    got = _rows(arc, "SELECT min(line) AS a, max(line) AS b, count(DISTINCT line) AS n FROM records")[0]
    assert got == {"a": 1, "b": len(lines), "n": len(lines)}
    notes = _rows(arc, "SELECT action, byte_start FROM ingests ORDER BY generation")
    assert [n["action"] for n in notes] == ["new", "grown"]
    assert notes[1]["byte_start"] == len(b"".join(lines[:1000]))


def test_each_ingest_of_a_growing_file_leaves_one_part_per_day_and_board(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from console.archive import ingest_finish
    from console.archive.ingest import run_ingest

    lines = STATION.read_bytes().splitlines(keepends=True)
    log = tmp_path / "growing.log"
    arc = tmp_path / "arc"
    cuts = [0, 700, 1500, 2600, len(lines)]
    for end in cuts[1:]:
        log.write_bytes(b"".join(lines[:end]))
        assert _ingest(arc, log).exit_code == 0
        m = read_current(arc)
        folders = [str(Path(rel).parent) for rel in m.parts("records")]
        # Compaction: the pieces of one partition are merged into one part, under a fresh name.
        assert len(folders) == len(set(folders)), folders
        assert _count(arc) == end
    got = _rows(arc, "SELECT count(DISTINCT line) AS n, min(line) AS a, max(line) AS b FROM records")[0]
    assert got == {"n": len(lines), "a": 1, "b": len(lines)}
    # The merged pieces this ingest wrote are deleted at once (no manifest lists them); older ones
    # stay for the kept manifests and leave with the clean-up of a later ingest.
    gen = read_current(arc).generation
    on_disk = {str(p.relative_to(arc)) for p in (arc / "data" / "records").rglob(f"g{gen:06d}-*.parquet")}
    assert on_disk == {rel for rel in read_current(arc).parts("records") if f"g{gen:06d}-" in rel}
    # A partition whose parts would exceed the compaction limit keeps them apart.
    monkeypatch.setattr(ingest_finish, "COMPACT_MAX_ROWS", 10)
    more = tmp_path / "more.log"
    more.write_bytes(b"".join(lines[:50]).replace(b"Diag_id:", b"Diag_id:9", 1))
    run = run_ingest([more], arc)
    assert run.published
    folders = [str(Path(rel).parent) for rel in read_current(arc).parts("records")]
    assert len(folders) > len(set(folders))
    assert _count(arc) == len(lines) + 50


def test_a_rotated_file_is_ingested_as_a_new_file_and_the_ledger_says_why(tmp_path: Path) -> None:
    lines = STATION.read_bytes().splitlines(keepends=True)
    log = tmp_path / "station.log"
    log.write_bytes(b"".join(lines[:500]))
    arc = tmp_path / "arc"
    _ingest(arc, log)
    log.write_bytes(b"".join(lines[500:900]))  # rotated: other content under the same name
    res = _ingest(arc, log)
    assert res.exit_code == 0
    assert _count(arc) == 900
    notes = _rows(arc, "SELECT action, note FROM ingests ORDER BY generation")
    assert notes[-1]["action"] == "new" and "rotated or rewritten" in str(notes[-1]["note"])


def test_gzip_and_stdin_are_ingested(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    gz = tmp_path / "ws4.log.gz"
    gz.write_bytes(gzip.compress((SAMPLES / "ws4_subsecond.log").read_bytes()))
    assert _ingest(arc, gz).exit_code == 0
    res = _ingest(arc, "-", stdin=(SAMPLES / "osong_ws4_0932_detection.log").read_bytes())
    assert res.exit_code == 0, res.output
    files = {r["file"] for r in _rows(arc, "SELECT DISTINCT file FROM records")}
    assert files == {str(gz.resolve()), "<stdin>"}
    assert _count(arc) == 100 + 34


def test_rejected_lines_are_kept_with_file_line_and_reason(tmp_path: Path) -> None:
    log = tmp_path / "bad.log"
    good = (SAMPLES / "osong_ws4_0932_detection.log").read_bytes().splitlines(keepends=True)
    log.write_bytes(good[0] + b"not a record\n" + good[1] + b"\n")
    arc = tmp_path / "arc"
    res = _ingest(arc, log)
    assert "1 rejected" in res.stdout
    rows = _rows(arc, "SELECT file, line, reason FROM rejected")
    assert len(rows) == 1 and rows[0]["line"] == 2 and rows[0]["file"] == str(log.resolve())
    assert rows[0]["reason"]


def test_every_rejected_line_of_a_mostly_bad_file_is_archived(tmp_path: Path) -> None:
    # More rejections than a parse report lists (1000) and than one batch to the writer: every one is
    # stored, in line order, beside the good records; none is lost when the in-memory list is capped.
    from console.archive.parse_pass import REJECTED_BATCH_ROWS

    good = (SAMPLES / "osong_ws4_0932_detection.log").read_bytes().splitlines(keepends=True)
    bad = [f"junk {i}\n".encode() for i in range(2 * REJECTED_BATCH_ROWS + 7)]
    log = tmp_path / "mostly_bad.log"
    log.write_bytes(b"".join(good[:3] + bad + good[3:]))
    arc = tmp_path / "arc"
    res = _ingest(arc, log)
    assert res.exit_code == 0, res.output
    rows = _rows(arc, "SELECT count(*) AS n, min(line) AS first, max(line) AS last FROM rejected")
    assert rows == [{"n": len(bad), "first": 4, "last": 3 + len(bad)}]
    assert _count(arc) == len(good)


def test_query_schema_and_presets(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, STATION, extra=("--layout", "example"))
    schema = runner.invoke(app, ["query", "--schema", "--archive", str(arc), "--format", "csv"])
    assert schema.exit_code == 0
    for needle in ("records,counting_head,VARCHAR", "records,day,DATE", "axles,", "section_states,", "ingests,"):
        assert needle in schema.stdout
    axles = json.loads(
        runner.invoke(
            app, ["query", "--preset", "axles-per-head-per-day", "--archive", str(arc), "--format", "json"]
        ).stdout
    )
    direct = int(_rows(arc, "SELECT count(*) AS n FROM axles")[0]["n"])  # type: ignore[call-overload]
    assert sum(int(r["axles"]) for r in axles) == direct > 0
    for preset in ("late-warnings", "failing-sensors"):
        res = runner.invoke(app, ["query", "--preset", preset, "--archive", str(arc)])
        assert res.exit_code == 0, res.output


@pytest.mark.parametrize(
    "sql",
    [
        "COPY records TO '{arc}/x.csv'",
        "ATTACH '{arc}/x.db'",
        "CREATE TABLE t AS SELECT 1",
        "DROP VIEW records",
        "SELECT 1; SELECT 2",
        "SELECT * FROM read_csv('/etc/passwd')",
        "INSTALL httpfs",
    ],
)
def test_a_query_cannot_modify_the_archive_or_reach_other_files(tmp_path: Path, sql: str) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    before = sorted(p.relative_to(arc) for p in arc.rglob("*"))
    res = runner.invoke(app, ["query", sql.format(arc=arc), "--archive", str(arc)])
    assert res.exit_code == 2
    assert res.stderr.startswith("trackside: error: ") and res.stderr.count("\n") == 1
    assert sorted(p.relative_to(arc) for p in arc.rglob("*")) == before


def test_bad_sql_is_duckdbs_message_in_one_line_exit_2(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    res = runner.invoke(app, ["query", "SELECT nope FROM records WHERE", "--archive", str(arc)])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and "Parser Error" in res.stderr
    missing = runner.invoke(app, ["query", "SELECT 1", "--archive", str(tmp_path / "none")])
    assert missing.exit_code == 2 and "no archive here yet" in missing.stderr


def test_log_text_in_a_query_result_is_not_markup(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    res = runner.invoke(app, ["query", "SELECT '[bold red]x[/]' || chr(27) || '[2J' AS t", "--archive", str(arc)])
    assert res.exit_code == 0
    assert "[bold red]x[/]\\x1b[2J" in res.stdout and "\x1b" not in res.stdout


def test_a_second_ingest_with_no_wait_fails_clearly_while_one_writes(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    fd = os.open(arc / "lock", os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        res = _ingest(arc, STATION, extra=("--no-wait",))
        assert res.exit_code == 2
        assert "another ingest is writing this archive" in res.stderr
    finally:
        os.close(fd)
    assert _ingest(arc, STATION).exit_code == 0


def test_a_full_disk_is_one_line_exit_2_and_the_archive_stays_as_it_was(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    import pyarrow.parquet as pq

    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    before = (arc / "CURRENT").read_text()
    n = _count(arc)

    def full(*_a: object, **_k: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pq.ParquetWriter, "write_table", full)
    res = _ingest(arc, STATION)
    monkeypatch.undo()
    assert res.exit_code == 2
    assert res.stderr == f"trackside: error: {arc}: no space left on device: archive unchanged\n"
    assert (arc / "CURRENT").read_text() == before
    assert _count(arc) == n
    # The next ingest cleans up and succeeds.
    assert _ingest(arc, STATION).exit_code == 0
    assert _count(arc) == n + 3385


def test_a_full_disk_in_the_derivation_leaves_no_part_of_the_failed_ingest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The records parts, the derived parts and the pipeline's state are written when the derivation's last
    step runs out of space: they are removed at once."""
    import errno

    import console.archive.derive as derive

    arc = tmp_path / "arc"
    _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log")
    files_before = sorted(p.relative_to(arc) for p in (arc / "data").rglob("*") if p.is_file())

    def full(*_a: object, **_k: object) -> list[str]:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(derive.Derivation, "_at_end", full)
    res = _ingest(arc, STATION)
    monkeypatch.undo()
    assert res.exit_code == 2, res.output
    assert "no space left on device" in res.stderr
    assert sorted(p.relative_to(arc) for p in (arc / "data").rglob("*") if p.is_file()) == files_before


def test_an_ingest_leaves_a_reading_reports_spill_folder_alone_and_removes_a_dead_ones(tmp_path: Path) -> None:
    """An ingest's clean-up removed every folder under tmp/, the spill folder of a report or replay still
    reading the records too (DuckDB spills there past its 160 MB)."""
    from console.archive.reader import record_batches

    arc = tmp_path / "arc"
    assert _ingest(arc, SAMPLES / "osong_ws4_0932_detection.log").exit_code == 0
    dead = arc / "tmp" / "duckdb-killed"  # a reader killed mid-read: its lock went with it
    dead.mkdir()
    (dead / ".reading").touch()
    reading = record_batches(arc, read_current(arc))
    next(reading)
    live = sorted(p for p in (arc / "tmp").iterdir() if p != dead)
    assert len(live) == 1
    assert _ingest(arc, STATION).exit_code == 0
    assert sorted((arc / "tmp").iterdir()) == live
    assert list(reading) == []  # read to its end: its folder goes with it
    assert list((arc / "tmp").iterdir()) == []


def test_what_a_directory_holds_but_ingest_does_not_read_is_said(tmp_path: Path) -> None:
    """A dangling link, a FIFO and hidden files in an ingested directory vanished without a word (the report says
    why it skips each); now the summary and --json name each, as the report does."""
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "station.log").write_bytes((SAMPLES / "osong_ws4_0932_detection.log").read_bytes())
    (logs / "gone.log").symlink_to(tmp_path / "nowhere.log")
    os.mkfifo(logs / "feed.fifo")
    (logs / ".hidden.log").write_bytes((SAMPLES / "osong_ws4_1032_detection.log").read_bytes())
    expected = [
        f"{logs / 'feed.fifo'}: a FIFO, not a regular file: skipped",
        f"{logs / 'gone.log'}: a symlink to nothing: skipped",
        f"{logs}: 1 hidden entries (names starting with '.') not read",
    ]
    res = _ingest(tmp_path / "arc", logs, extra=("--json",))
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["warnings"] == expected
    res = _ingest(tmp_path / "arc", logs)
    assert res.exit_code == 0, res.output
    assert [line.removeprefix("warning  ") for line in res.stdout.splitlines() if line.startswith("warning")] == (
        expected
    )
