"""`trackside query` output: times as ISO 8601 UTC with Z in every format, nanoseconds kept; still read-only."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.analysis.timefmt import iso
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()
LOG = SAMPLES / "osong_ws4_0932_detection.log"


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    arc = tmp_path_factory.mktemp("query") / "arc"
    res = runner.invoke(app, ["ingest", str(LOG), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    return arc


def _run(arc: Path, sql: str, fmt: str) -> str:
    res = runner.invoke(app, ["query", sql, "--archive", str(arc), "--format", fmt])
    assert res.exit_code == 0, res.output
    return str(res.stdout)


# A naive log time with nanoseconds, a zone-aware one (+02:00 → UTC), a null, and a date (no Z: not a time).
TIMES_SQL = (
    "SELECT TIMESTAMP_NS '2026-03-02 08:00:13.250125001' AS t_ns, "
    "TIMESTAMPTZ '2026-03-02 10:00:00+02' AS t_tz, NULL::TIMESTAMP AS t_null, DATE '2026-03-02' AS d"
)
EXPECTED = {
    "t_ns": "2026-03-02T08:00:13.250125001Z",
    "t_tz": "2026-03-02T08:00:00.000Z",
    "t_null": None,
    "d": "2026-03-02",
}


def test_times_are_iso_utc_with_z_in_json_and_jsonl(archive: Path) -> None:
    assert json.loads(_run(archive, TIMES_SQL, "json")) == [EXPECTED]
    assert [json.loads(line) for line in _run(archive, TIMES_SQL, "jsonl").splitlines()] == [EXPECTED]


def test_times_are_iso_utc_with_z_in_csv(archive: Path) -> None:
    rows = list(csv.DictReader(io.StringIO(_run(archive, TIMES_SQL, "csv"))))
    assert rows == [{k: "" if v is None else v for k, v in EXPECTED.items()}]


def test_times_are_iso_utc_with_z_in_the_table(archive: Path) -> None:
    out = _run(archive, "SELECT TIMESTAMP '2026-03-02 08:00:13.5' AS t", "table")
    assert "2026-03-02T08:00:13.500Z" in out


def test_record_times_keep_their_nanoseconds_and_match_timefmt(archive: Path) -> None:
    # The archive's own column: what the query prints is timefmt.iso of the stored ns.
    sql = "SELECT time, epoch_ns(time) AS ns FROM records ORDER BY file_seq, line LIMIT 50"
    rows = json.loads(_run(archive, sql, "json"))
    assert rows and all(r["time"] == iso(r["ns"]) and r["time"].endswith("Z") for r in rows)


def test_times_inside_lists_and_structs_get_z_too(archive: Path) -> None:
    sql = "SELECT [TIMESTAMP '2026-01-01 00:00:00.123456'] AS l, {'a': TIMESTAMP '2026-01-01 00:00:00'} AS s"
    assert json.loads(_run(archive, sql, "json")) == [
        {"l": ["2026-01-01T00:00:00.123456Z"], "s": {"a": "2026-01-01T00:00:00.000Z"}}
    ]


def test_presets_print_utc_times(archive: Path) -> None:
    rows = json.loads(_run(archive, "SELECT min(time) AS first FROM records", "json"))
    assert rows[0]["first"].endswith("Z")
    res = runner.invoke(app, ["query", "--preset", "axles-per-head-per-day", "--archive", str(archive)])
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize(
    "sql",
    [
        "COPY (SELECT 1) TO '{arc}/data/x.parquet'",
        "CREATE VIEW v AS SELECT 1",
        "SET enable_external_access = true",
        "SELECT * FROM read_parquet('{arc}/../*.parquet')",
        "SELECT 1; DROP VIEW records",
    ],
)
def test_still_read_only(archive: Path, sql: str) -> None:
    before = sorted((p.relative_to(archive), p.stat().st_mtime_ns) for p in archive.rglob("*"))
    res = runner.invoke(app, ["query", sql.format(arc=archive), "--archive", str(archive)])
    assert res.exit_code == 2
    assert res.stderr.startswith("trackside: error: ") and res.stderr.count("\n") == 1
    assert sorted((p.relative_to(archive), p.stat().st_mtime_ns) for p in archive.rglob("*")) == before


# Plain types: rows fetched as Python values (no Arrow); the same text as through Arrow.
PLAIN_SQL = (
    "SELECT 3::BIGINT AS n, 2.5::DECIMAL(4, 2) AS dec, 'WS4' AS head, DATE '2026-03-02' AS d, "
    "[1, 2] AS l, {'a': 1} AS s, NULL::INTEGER AS nothing, INTERVAL 90 SECOND AS iv"
)


def test_plain_results_skip_arrow_and_print_as_arrow_would(archive: Path) -> None:
    from console.archive.query import run_query_result

    plain = run_query_result(archive, "SELECT count(*) AS n, min(counting_head) AS head FROM records")
    assert plain.arrow is None and plain.rows is not None and plain.rows[0][0] > 0
    # A time column comes as epoch nanoseconds, no Arrow either; a time inside a list still needs Arrow.
    timed = run_query_result(archive, "SELECT min(time) AS t, 1 AS one FROM records")
    assert timed.arrow is None and timed.ns_columns == {0} and isinstance((timed.rows or [])[0][0], int)
    assert run_query_result(archive, "SELECT [min(time)] AS t FROM records").arrow is not None
    expected = {"n": 3, "dec": 2.5, "head": "WS4", "d": "2026-03-02", "l": [1, 2], "s": {"a": 1}, "nothing": None}
    assert json.loads(_run(archive, PLAIN_SQL, "json")) == [{**expected, "iv": 90.0}]
    rows = list(
        csv.DictReader(io.StringIO(_run(archive, PLAIN_SQL.replace(", [1, 2] AS l, {'a': 1} AS s", ""), "csv")))
    )
    assert rows == [{"n": "3", "dec": "2.5", "head": "WS4", "d": "2026-03-02", "nothing": "", "iv": "90.0"}]


def test_a_time_column_with_nulls_between_values_keeps_each_row(archive: Path) -> None:
    sql = (
        "SELECT i, CASE i % 3 WHEN 1 THEN NULL WHEN 0 THEN TIMESTAMP_NS '2026-03-02 08:00:00.000000001' "
        "ELSE TIMESTAMP_NS '2026-03-02 09:00:00.000000002' END AS t FROM range(0, 5000) r(i) ORDER BY i"
    )
    rows = [json.loads(line) for line in _run(archive, sql, "jsonl").splitlines()]
    assert [r["i"] for r in rows] == list(range(5000))
    midnight_ns = 1772409600 * 10**9  # 2026-03-02T00:00Z
    expected = {0: iso(midnight_ns + 8 * 3600 * 10**9 + 1), 1: None, 2: iso(midnight_ns + 9 * 3600 * 10**9 + 2)}
    assert expected[0] == "2026-03-02T08:00:00.000000001Z"
    assert all(r["t"] == expected[r["i"] % 3] for r in rows)


@pytest.mark.parametrize(
    ("sql", "expected"),
    [
        (
            "SELECT * FROM records WHERE head = 'WS1' AND day = DATE '2026-03-02' AND device_id = 5001",
            {"records": {"day": "2026-03-02", "device_id": "5001"}},
        ),
        ("SELECT count(*) FROM records r WHERE r.day = '2026-03-02'", {"records": {"day": "2026-03-02"}}),
        ("SELECT * FROM records WHERE '2026-03-02' = day", {"records": {"day": "2026-03-02"}}),
        # Not certain: nothing pruned.
        ("SELECT * FROM records WHERE day = DATE '2026-03-02' OR device_id = 5001", {}),
        ("SELECT * FROM records WHERE day = DATE '2026-03-02' AND time > (SELECT min(time) FROM records)", {}),
        ("WITH x AS (SELECT 1) SELECT * FROM records WHERE day = DATE '2026-03-02'", {}),
        ("SELECT * FROM records JOIN axles USING (day) WHERE day = DATE '2026-03-02'", {}),
        ("SELECT * FROM records WHERE day = TIMESTAMP '2026-03-02 10:00'", {}),
        ("SELECT * FROM axles WHERE day = DATE '2026-03-02'", {}),
    ],
)
def test_partition_filter_only_when_certain(sql: str, expected: dict[str, dict[str, str]]) -> None:
    import duckdb

    from console.archive.partition_filter import partition_filter

    assert partition_filter(duckdb.connect(), sql) == expected


@pytest.fixture(scope="module")
def two_days(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Records of 2 boards over 2 days, written as the ingest writes them (4 partitions)."""
    import numpy as np
    import pyarrow as pa

    from console.archive import parts
    from console.archive.store import Manifest, ensure_layout, publish
    from parsers.units import NS_PER_DAY

    root = tmp_path_factory.mktemp("days") / "arc"
    ensure_layout(root)
    n = 4000
    time_ns = 20_000 * NS_PER_DAY + np.arange(n, dtype=np.int64) * 40 * 10**9  # 40 s apart: ~2 days
    device = 5000 + np.arange(n) % 2
    table = pa.table(
        {
            "time": pa.array(time_ns.view("datetime64[ns]")),
            "counting_head": pa.array([f"WS{d - 4999}" for d in device]),
            "line": pa.array(np.arange(n)),
        }
    )
    w = parts.PartWriter(root, "records", 1, "r")
    w.add(table, time_ns // NS_PER_DAY, device)
    written = w.close()
    assert len(written) == 4
    publish(root, Manifest(generation=1, tables={"records": written}), written)
    return root


@pytest.mark.parametrize(
    "sql",
    [
        "SELECT count(*), min(line), max(line) FROM records WHERE day = DATE '2024-10-04' AND device_id = 5001",
        "SELECT * FROM records WHERE day = '2024-10-05' ORDER BY line",
        "SELECT * FROM records WHERE day = DATE '1999-01-01'",  # no such day: no rows, every column
    ],
)
def test_a_pruned_view_gives_what_the_whole_view_gives(two_days: Path, sql: str) -> None:
    from console.archive.partition_filter import partition_filter
    from console.archive.query import check_read_only
    from console.archive.views import connect

    assert partition_filter(connect(two_days)[0], sql)  # pruned indeed
    pruned, _ = connect(two_days, sql=sql)
    whole, _ = connect(two_days)
    check_read_only(pruned, sql)
    a, b = pruned.sql(sql), whole.sql(sql)
    assert a.columns == b.columns
    assert a.fetchall() == b.fetchall()


# Statements whose every column is a plain value: answered by DuckDB's engine alone (duck.engine).
ENGINE_ONLY_SQL = [
    "SELECT count(*) AS n, min(counting_head) AS head FROM records",
    "SELECT 1 AS a, 2 AS a",
    "SELECT counting_head, count(*) FROM axles GROUP BY ALL ORDER BY 1 -- a comment",
    "SELECT 3::BIGINT AS n, 2.5::DECIMAL(4, 2) AS dec, [1, 2] AS l, {'a': 1} AS s, DATE '2026-03-02' AS d;",
    "VALUES (1, 'a'), (2, NULL)",
    "FROM range(3)",
    "DESCRIBE records",
    "SUMMARIZE SELECT 1 AS x",
    "SHOW TABLES",
    # Top-level times, as epoch nanoseconds (the statement read as a subquery, its order kept).
    "SELECT time, counting_head FROM records ORDER BY time DESC, line DESC -- newest first",
    "SELECT min(time) AS t, TIMESTAMPTZ '2026-03-02 10:00:00+02' AS tz FROM records;",
]
# The package's relations answer these: times, Arrow types, or a statement DESCRIBE cannot take.
RELATION_SQL = ["SELECT [min(time)] AS t FROM records", "SELECT INTERVAL 90 SECOND AS iv", "EXPLAIN SELECT 1"]


def test_the_engine_alone_answers_plain_queries_as_the_relations_do(archive: Path) -> None:
    import duckdb

    from console.archive.query import _query_connection, plain_result

    for sql in ENGINE_ONLY_SQL + RELATION_SQL:
        con = _query_connection(archive, sql, engine_only=True)
        try:
            plain = plain_result(con, sql)
            assert (plain is not None) == (sql in ENGINE_ONLY_SQL), sql
            if plain is not None:
                rel = con.sql(sql)
                assert plain.names == list(rel.columns), sql
                # The relations' own projection of times as epoch nanoseconds (what the query command did before).
                times = [i for i, t in enumerate(rel.types) if str(t).startswith("TIMESTAMP")]
                picked = [f"epoch_ns(#{i + 1})" if i in times else f"#{i + 1}" for i in range(len(rel.types))]
                assert plain.rows == (rel.project(", ".join(picked)) if times else rel).fetchall(), sql
                assert plain.arrow is None and plain.ns_columns == frozenset(times), sql
        finally:
            con.close()
    with pytest.raises(duckdb.Error):  # a bad statement still fails (through the relation, as before)
        con = _query_connection(archive, "SELECT nope FROM records", engine_only=True)
        try:
            assert plain_result(con, "SELECT nope FROM records") is None
            con.sql("SELECT nope FROM records")
        finally:
            con.close()


def test_a_plain_query_does_not_import_the_duckdb_package(archive: Path) -> None:
    import importlib.util
    import subprocess
    import sys

    if importlib.util.find_spec("_duckdb") is None:
        pytest.skip("this DuckDB has no engine module apart from the package (1.x)")
    code = (
        "import sys; from pathlib import Path; from console.archive.query import run_query_result; "
        "r = run_query_result(Path(sys.argv[1]), 'SELECT counting_head, count(*) FROM records GROUP BY ALL'); "
        "print(len(r.rows or []), 'duckdb' in sys.modules, 'pyarrow' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code, str(archive)], capture_output=True, text=True, check=True)
    n, package, arrow = out.stdout.split()
    assert int(n) > 0 and package == "False" and arrow == "False"
    # A time column too; a time inside a list takes the package's relations and Arrow, as before.
    timed = code.replace("counting_head, count(*)", "counting_head, min(time)")
    out = subprocess.run([sys.executable, "-c", timed, str(archive)], capture_output=True, text=True, check=True)
    assert out.stdout.split()[1] == "False"
    nested = code.replace("counting_head, count(*)", "counting_head, [min(time)]")
    out = subprocess.run([sys.executable, "-c", nested, str(archive)], capture_output=True, text=True, check=True)
    assert out.stdout.split()[1:] == ["True", "True"]


def test_a_big_result_comes_in_batches_with_its_times(archive: Path) -> None:
    from console.archive.query import run_query_batches

    sql = "SELECT range AS i, TIMESTAMP_NS '2026-03-02 08:00:00' + to_microseconds(range) AS t FROM range(250000)"
    batches = list(run_query_batches(archive, sql, batch_rows=100_000))
    assert [len(b.rows or []) for b in batches] == [100_000, 100_000, 50_000]
    assert batches[2].ns_columns == frozenset({1}) and batches[2].rows is not None
    assert batches[2].rows[-1] == (249_999, 1772438400_000000000 + 249_999_000)


def test_millions_of_rows_to_a_reader_that_leaves_end_quietly_in_bounded_memory(archive: Path) -> None:
    """`query … --format csv | head` read the whole result into Python rows first: 3 M rows took 0.9 GB."""
    import subprocess
    import sys

    # A process of its own whose one child is the query: its children's peak memory is the query's.
    code = (
        "import resource, subprocess, sys\n"
        "p = subprocess.Popen(sys.argv[1:], stdout=subprocess.PIPE)\n"
        "head = [p.stdout.readline() for _ in range(3)]\n"
        "p.stdout.close()\n"
        "rc = p.wait()\n"
        "print(rc, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss // 1024, head[1].decode().strip())\n"
    )
    sql = "SELECT range AS i, repeat('x', 50) AS s FROM range(3000000)"
    for fmt in ("csv", "jsonl"):
        command = [sys.executable, "-c", "from console.cli.app import app; app()", "query", sql]
        command += ["--archive", str(archive), "--format", fmt]
        out = subprocess.run([sys.executable, "-c", code, *command], capture_output=True, text=True, timeout=120)
        rc, peak_mb, first = out.stdout.strip().split(maxsplit=2)
        assert (rc, out.stderr) == ("0", "")
        assert first == ("0," + "x" * 50 if fmt == "csv" else json.dumps({"i": 1, "s": "x" * 50}))  # the 2nd line
        assert int(peak_mb) < 300, peak_mb


def test_a_part_cut_short_or_deleted_on_disk_is_named_not_an_internal_error(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    assert runner.invoke(app, ["ingest", str(LOG), "--archive", str(arc)]).exit_code == 0
    part = next((arc / "data" / "records").rglob("*.parquet"))
    data = part.read_bytes()
    part.write_bytes(data[:100])  # bit rot, a copy cut short
    for command in (["query", "SELECT count(*) FROM records"], ["report", "--format", "json"], ["forecast"]):
        res = runner.invoke(app, [*command, "--archive", str(arc)])
        assert res.exit_code == 2, res.output
        assert res.stderr.startswith(f"trackside: error: {arc}: the archive is damaged: its records cannot be read (")
        assert res.stderr.count("\n") == 1 and "internal error" not in res.stderr, res.stderr
    part.unlink()
    res = runner.invoke(app, ["report", "--archive", str(arc), "--format", "json"])
    assert res.exit_code == 2
    assert res.stderr == f"trackside: error: {arc}: the archive is damaged: {part.relative_to(arc)} is missing\n"


@pytest.mark.parametrize("fmt", ["table", "csv", "jsonl"])
def test_ctrl_c_stops_a_long_query_at_once_with_130(archive: Path, fmt: str) -> None:
    """Ctrl-C in a query that runs for minutes: the table said "internal error: RuntimeError: Query interrupted"
    (exit 2); csv, json and jsonl (DuckDB's engine alone, which does not look for Ctrl-C) ran on to the end."""
    import signal
    import subprocess
    import sys
    import time

    sql = "SELECT sum(hash(a.range * b.range)) AS s FROM range(400000) a, range(400000) b"  # minutes of work
    command = [sys.executable, "-c", "from console.cli.app import app; app()", "query", sql]
    proc = subprocess.Popen(
        [*command, "--archive", str(archive), "--format", fmt],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as from a shell: Ctrl-C not ignored
    )
    try:
        time.sleep(3)  # started, and inside the statement
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    finally:
        proc.kill()
    assert (proc.returncode, err) == (130, "")
    assert out == ""
