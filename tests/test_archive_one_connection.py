"""The reads of a report share one DuckDB database (views.one_connection): the same rows as connections of
their own, each view made once, and a read of another manifest generation still on its own connection."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.archive import views
from console.archive.store import read_current
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()
QUERIES = (
    ("records", "SELECT counting_head, count(*), min(time), max(time) FROM records GROUP BY ALL ORDER BY 1"),
    ("passages", "SELECT count(*), sum(axles) FROM passages"),
    ("fixes", "SELECT count(*), min(time) FROM fixes"),
)


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    arc = tmp_path_factory.mktemp("one") / "arc"
    res = runner.invoke(app, ["ingest", str(SAMPLES), "--archive", str(arc), "--layout", "example"])
    assert res.exit_code == 0, res.output
    return arc


def _rows(root: Path, table: str, sql: str) -> list[tuple[object, ...]]:
    con, _ = views.connect(root, tables=(table,))
    try:
        return con.execute(sql).fetchall()
    finally:
        con.close()


def test_shared_reads_are_the_reads_of_their_own(archive: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    alone = [_rows(archive, t, sql) for t, sql in QUERIES]
    assert all(alone)
    made: list[str] = []
    real_view = views._view

    def view(table: str, keys: tuple[str, ...], parts: list[str]) -> str:
        if parts:
            made.append(table)
        return real_view(table, keys, parts)

    with views.one_connection(archive):
        monkeypatch.setattr(views, "_view", view)
        shared = [_rows(archive, t, sql) for t, sql in QUERIES]
        again = [_rows(archive, t, sql) for t, sql in QUERIES]  # cursors closed, the database kept
        relative = _rows(archive / ".." / archive.name, *QUERIES[0])  # another spelling of the root: the same database
        monkeypatch.undo()
        database = views._SHARED[archive.resolve()].con
    assert shared == alone and again == alone and relative == alone[0]
    assert sorted(made) == sorted(t for t, _ in QUERIES)  # each table's view made once
    assert archive.resolve() not in views._SHARED
    with pytest.raises(Exception, match="closed"):
        database.execute("SELECT 1")


def test_another_generation_reads_on_its_own(archive: Path) -> None:
    m = read_current(archive)
    newer = type(m)(generation=m.generation + 1, tables=m.tables, files=m.files, derived=m.derived)
    sql = QUERIES[0][1]
    with views.one_connection(archive):
        con, _ = views.connect(archive, m, tables=("records",))
        con.close()
        shared = views._SHARED[archive.resolve()]
        shared.con.execute("CREATE VIEW marker AS SELECT 1 AS x")  # seen by every cursor of the shared database
        cursor, _ = views.connect(archive, m, tables=("records",))
        own, _ = views.connect(archive, newer, tables=("records",))
        try:
            assert cursor.execute("SELECT x FROM marker").fetchall() == [(1,)]
            with pytest.raises(Exception, match="marker"):
                own.execute("SELECT x FROM marker")
            assert own.execute(sql).fetchall() == cursor.execute(sql).fetchall()
        finally:
            cursor.close()
            own.close()


# Run outside pytest: under it, DuckDB's Python client starts with the progress bar off already.
PROGRESS_BARS = """
import json, sys
from pathlib import Path
from console.archive import views
archive, spill = Path(sys.argv[1]), Path(sys.argv[2])
setting = "SELECT current_setting('enable_progress_bar')"
cons = [views.connect(archive, tables=("records",))[0], views.connect(archive, spill_dir=spill)[0],
        views.connect(archive, sql="SELECT count(*) FROM records")[0]]
seen = [con.execute(setting).fetchone()[0] for con in cons]
with views.one_connection(archive):
    seen.append(views.connect(archive, tables=("records",))[0].execute(setting).fetchone()[0])
try:
    cons[0].execute("SET enable_progress_bar = true")
    seen.append("set")
except Exception as exc:
    seen.append(type(exc).__name__)
print(json.dumps(seen))
"""


def test_no_connection_draws_a_progress_bar(archive: Path, tmp_path: Path) -> None:
    # DuckDB draws its progress bar on standard output after two seconds of a query: inside the JSON or CSV a
    # report or a query writes there (seen on a one-day report of a 30 M-record archive). Every kind of archive
    # connection turns it off, and the lock keeps a query from turning it on again.
    out = subprocess.run(
        [sys.executable, "-c", PROGRESS_BARS, str(archive), str(tmp_path)], capture_output=True, text=True, check=True
    )
    assert json.loads(out.stdout) == [False, False, False, False, "InvalidInputException"]
