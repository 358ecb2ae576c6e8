"""`trackside query`: DuckDB's own box fitted to the terminal, and one type per kind of value in the archive."""

from __future__ import annotations

import json
import re
import unicodedata
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from console.analysis.timefmt import iso as iso_text
from console.archive.presets import PRESETS
from console.archive.store import read_current
from console.cli.app import app

runner = CliRunner()
DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated run with a dead channel (findings), GNSS (fixes, crossings), ingested with its layout."""
    tmp = tmp_path_factory.mktemp("q")
    run = tmp / "run"
    sim = runner.invoke(
        app,
        ["simulate", "-o", str(run), "--duration", "20m", "--trains-per-hour", "12", "--fault", "dead_channel:WS3:5m"],
    )
    assert sim.exit_code == 0, sim.output
    arc = tmp / "arc"
    res = runner.invoke(app, ["ingest", str(run), "--archive", str(arc), "--layout", str(run / "layout.toml")])
    assert res.exit_code == 0, res.output
    return arc


def _width(line: str) -> int:
    return sum(2 if unicodedata.east_asian_width(c) in "WF" else 0 if unicodedata.combining(c) else 1 for c in line)


def _table(arc: Path, *args: str, columns: int = 80) -> str:
    res = runner.invoke(app, ["query", *args, "--archive", str(arc)], env={"COLUMNS": str(columns)})
    assert res.exit_code == 0, res.output
    return res.stdout


def test_long_messages_fit_80_columns_one_line_per_row(archive: Path) -> None:
    sql = (
        "SELECT severity, rule, counting_head, channel, message, repeat('word ', 60) AS long_text FROM health_findings"
    )
    out = _table(archive, sql)
    lines = out.rstrip("\n").split("\n")
    assert max(_width(line) for line in lines) <= 80, out
    n = len(json.loads(runner.invoke(app, ["query", sql, "--archive", str(archive), "--format", "json"]).stdout))
    assert n > 0
    # One line per row (at most DuckDB's shown rows), the box's frame and header, and the count line.
    assert len(lines) <= min(n, 40) + 8, out
    assert "…" in out  # long text is cut, as the duckdb shell cuts it


def test_headers_are_not_cut_to_a_few_letters(archive: Path) -> None:
    out = _table(archive, "--preset", "late-warnings")
    assert re.search(r"\bcrossing\b", out), out
    assert "cross…" not in out


def test_a_wide_terminal_shows_more(archive: Path) -> None:
    sql = "SELECT message FROM health_findings"
    narrow, wide = _table(archive, sql, columns=80), _table(archive, sql, columns=200)
    assert max(map(_width, narrow.split("\n"))) <= 80
    assert max(map(_width, wide.split("\n"))) > 80
    # DuckDB's renderer is never narrower than 80 columns (as its shell).
    assert max(map(_width, _table(archive, sql, columns=60).split("\n"))) == 80


def test_log_text_stays_inert_in_the_box(archive: Path) -> None:
    out = _table(archive, "SELECT '[b]x' || chr(27) || '[2J' || chr(127) || chr(8238) || 'y' AS t")
    assert "[b]x\\x1b[2J\\x7f\\u202ey" in out
    assert "\x1b" not in out and "\u202e" not in out and "\x7f" not in out
    invisible = _table(archive, "SELECT 'WS1' || chr(8203) || chr(65279) || chr(917569) AS t")
    assert "WS1\\u200b\\ufeff\\U000e0041" in invisible and "\u200b" not in invisible


def test_list_presets_in_a_box_and_documented() -> None:
    res = runner.invoke(app, ["query", "--list-presets"], env={"COLUMNS": "80"})
    assert res.exit_code == 0
    text = (DOCS / "archive.md").read_text(encoding="utf-8")
    assert "--list-presets" in text
    for name in PRESETS:
        assert name in res.stdout
        assert f"`{name}`" in text
    assert "--list-presets" in runner.invoke(app, ["query", "--help"], env={"COLUMNS": "200"}).stdout


def _types(arc: Path) -> dict[tuple[str, str], str]:
    res = runner.invoke(app, ["query", "--schema", "--archive", str(arc), "--format", "json"])
    assert res.exit_code == 0, res.output
    return {(r["table"], r["column"]): r["type"] for r in json.loads(res.stdout)}


def test_one_time_type_throughout_and_integers_stored_as_integers(archive: Path) -> None:
    types = _types(archive)
    assert types[("health_findings", "time")] == "TIMESTAMP_NS"
    assert types[("fixes", "time")] == "TIMESTAMP_NS"
    assert types[("health_findings", "channel")] == types[("records", "channel")]
    for (table, col), typ in types.items():
        assert "TIME ZONE" not in typ and "TIMESTAMPTZ" not in typ, (table, col, typ)
        if col == "time" or (col.startswith("t_") and not col.endswith(("_ns", "_s"))):
            assert typ == "TIMESTAMP_NS", (table, col, typ)
        if col.endswith("_ns") or col in ("channel", "line", "records", "axles", "file_seq"):
            assert typ in ("TINYINT", "SMALLINT", "INTEGER", "BIGINT"), (table, col, typ)
        assert col != "records_in_detection_second" or typ == "BIGINT"


def test_fix_times_are_the_logs_utc_times_whatever_the_machine_zone(archive: Path) -> None:
    res = runner.invoke(
        app,
        ["query", "SELECT min(time) AS t FROM fixes", "--archive", str(archive), "--format", "json"],
        env={"TZ": "Asia/Seoul"},
    )
    first = json.loads(res.stdout)[0]["t"]
    nmea = sorted((archive.parent / "run" / "nmea").glob("*.nmea"))
    assert nmea
    assert first.startswith("2026-") and first.endswith("Z")
    hhmm = first[11:16]
    assert any(f",{hhmm[:2]}{hhmm[3:]}" in p.read_text() for p in nmea), first  # $GxRMC,HHMMSS… in UTC


def test_an_archive_written_with_the_old_types_reads_with_the_new(archive: Path, tmp_path: Path) -> None:
    """Parts written before the types were fixed (zone-aware fix times, text finding times, float channels)."""
    import shutil

    old = tmp_path / "old"
    shutil.copytree(archive, old)
    m = read_current(old)
    # Finding times in ns as floats kept only 53 bits: the old parts' time_ns is not compared.
    sql = {
        "fixes": "SELECT * FROM fixes ORDER BY ALL",
        "health_findings": "SELECT * EXCLUDE (time_ns) FROM health_findings ORDER BY ALL",
    }
    before = {
        t: runner.invoke(app, ["query", q, "--archive", str(old), "--format", "json"]).stdout for t, q in sql.items()
    }
    for rel in m.parts("fixes")[:1]:
        t = pq.read_table(old / rel)
        i = t.schema.get_field_index("time")
        t = t.set_column(i, "time", t.column("time").cast(pa.timestamp("ns", "UTC")))
        pq.write_table(t, old / rel)
    for rel in m.parts("health_findings"):
        t = pq.read_table(old / rel)
        stamps = t.column("time_ns").to_pylist()
        iso = pa.array([None if v is None else iso_text(v) for v in stamps], pa.string())
        t = t.set_column(t.schema.get_field_index("time"), "time", iso)
        for c in ("channel", "time_ns"):
            t = t.set_column(t.schema.get_field_index(c), c, t.column(c).cast(pa.float64(), safe=False))
        pq.write_table(t, old / rel)
    types = _types(old)
    assert types[("fixes", "time")] == types[("health_findings", "time")] == "TIMESTAMP_NS"
    assert types[("health_findings", "channel")] == types[("records", "channel")]
    for t, text in before.items():
        res = runner.invoke(app, ["query", sql[t], "--archive", str(old), "--format", "json"])
        assert res.stdout == text, t


def test_parts_are_written_with_the_one_types(archive: Path) -> None:
    """Stored so, not only shown so: other readers of the Parquet parts (pyarrow, pandas) see the same."""
    m = read_current(archive)
    fixes = pq.read_schema(archive / m.parts("fixes")[0])
    assert fixes.field("time").type == pa.timestamp("ns")
    findings = pq.read_schema(archive / m.parts("health_findings")[0])
    assert findings.field("time").type == pa.timestamp("ns")
    assert pa.types.is_integer(findings.field("channel").type) and pa.types.is_integer(findings.field("time_ns").type)
    passages = pq.read_schema(archive / m.parts("passages")[0])
    for c in ("detection_second_ns", "records_in_detection_second"):
        assert pa.types.is_integer(passages.field(c).type), c


def test_times_in_the_box_are_iso_utc_with_z_like_every_other_output(archive: Path) -> None:
    sql = (
        "SELECT TIMESTAMP_NS '2026-03-02 08:00:13.250125001' AS t_ns, TIMESTAMP '2026-03-02 08:00:13.5' AS t_us,"
        " TIMESTAMPTZ '2026-03-02 10:00:00+02' AS t_tz, NULL::TIMESTAMP AS t_null, TIMESTAMP '9999-01-01' AS far"
    )
    out = _table(archive, sql, columns=200)
    for text in ("2026-03-02T08:00:13.250125001Z", "2026-03-02T08:00:13.500Z", "2026-03-02T08:00:00.000Z"):
        assert text in out, out
    assert "9999-01-01T00:00:00.000000Z" in out


def test_csv_text_is_inert_like_the_table(tmp_path: Path) -> None:
    """A file named with a terminal escape and a bidi override: the CSV says it escaped, never raw."""
    from tests.conftest import SAMPLES

    log = tmp_path / "esc\x1b[2J\u202ename.log"
    log.write_bytes((SAMPLES / "ws4_subsecond.log").read_bytes())
    arc = tmp_path / "arc"
    assert CliRunner().invoke(app, ["ingest", "--archive", str(arc), str(log)]).exit_code == 0
    res = CliRunner().invoke(
        app, ["query", "--archive", str(arc), "SELECT DISTINCT file FROM records", "--format", "csv"]
    )
    assert res.exit_code == 0, res.output
    assert "\x1b" not in res.stdout and "\u202e" not in res.stdout
    assert "esc\\x1b[2J\\u202ename.log" in res.stdout
