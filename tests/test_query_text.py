"""`trackside query`'s CSV, JSON and JSONL: Arrow batches written column by column give the very text that Python
rows written value by value give (console.sinks.query_text), whatever the values and wherever the batches cut."""

from __future__ import annotations

import io
import json
import random
from pathlib import Path

import duckdb
import pyarrow as pa
import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.cli.commands import query as query_cmd
from console.sinks.query_text import ResultWriter, arrow_values
from tests.conftest import SAMPLES

runner = CliRunner()
FORMATS = ("csv", "json", "jsonl")

# Values as the world's logs and queries hold them: text a spreadsheet or terminal would act on, quotes, commas and
# line ends, bidi and zero-width characters, non-ASCII; floats at repr's exponent thresholds and beyond.
TEXTS = [
    "WS1",
    "",
    'a "quoted" label',
    "a, b",
    "two\nlines",
    "cr\r",
    "\x1b[31mred",
    "tab\there",
    "back\\slash",
    "Zähler 1-Fl",
    "\u202eevil",
    "WS1\u200b",
    "=1+1",
    "日本",
    "\x7f\x85",
    " lead",
]
FLOATS = [
    0.0,
    -0.0,
    0.1,
    1.5,
    46.71,
    1e-4,
    9.99e-5,
    1e-5,
    1e15,
    9999999999999998.0,
    1e16,
    1.2345e22,
    5e-324,
    -3.25e-8,
    123456789.123,
    float("inf"),
    float("-inf"),
    float("nan"),
]
# (SQL type, values) pairs; each column of a random table takes one.
KINDS: list[tuple[str, list[object]]] = [
    ("VARCHAR", TEXTS),
    ("DOUBLE", FLOATS),
    ("FLOAT", [0.1, 1.5, -2.75, 3.4e38, 1e-40, float("nan")]),
    ("BIGINT", [0, -1, 2**63 - 1, -(2**63), 1772409613250125001]),
    ("INTEGER", [0, 7, -2_000_000_000]),
    ("TINYINT", [0, -128, 127]),
    ("UBIGINT", [0, 2**64 - 1]),
    ("BOOLEAN", [True, False]),
    ("DATE", ["2026-03-02", "1969-12-31", "0001-01-01", "9999-12-31"]),
    ("TIMESTAMP_NS", ["2026-03-02 08:00:00.250125001", "1969-12-31 23:59:59.999999999", "2026-03-02 08:00:00"]),
    ("TIMESTAMP", ["2026-03-02 08:00:00.250125", "2026-03-02 08:00:00.250"]),
    ("TIMESTAMPTZ", ["2026-03-02 10:00:00+02"]),
    ("DECIMAL(9,2)", ["2.50", "-0.01"]),
    ("DOUBLE[]", ["[1.5, 2.0]", "[]"]),
    ("VARCHAR[]", ["['a', 'b,c']"]),
    ("BLOB", ["\\x01\\xFF"]),
    ("INTERVAL", ["1 second", "2 months"]),
    ("TIME", ["01:02:03.25"]),
]


def _literal(sql_type: str, value: object) -> str:
    if value is None:
        return f"NULL::{sql_type}"
    if isinstance(value, float | int):  # quoted: -128::TINYINT is -(128::TINYINT)
        return f"'{value!r}'::{sql_type}"
    if isinstance(value, str) and sql_type not in ("DOUBLE[]", "VARCHAR[]"):
        return "'" + value.replace("'", "''") + f"'::{sql_type}"
    return f"{value}::{sql_type}"


def _random_select(rng: random.Random, rows: int, kinds: list[tuple[str, list[object]]]) -> str:
    ncols = rng.choice([1, 1, 2, 3, 5, 8])
    picked = [rng.choice(kinds) for _ in range(ncols)]
    names = [rng.choice(["a", "b", "time", "x y", 'q"', "a"]) for _ in range(ncols)]  # names repeat at times
    lines = []
    quoted = ['"' + n.replace('"', '""') + '"' for n in names]
    for _ in range(rows):
        cells = [
            _literal(t, None if rng.random() < 0.15 else rng.choice(values)) + f" AS {q}"
            for (t, values), q in zip(picked, quoted, strict=True)
        ]
        lines.append("SELECT " + ", ".join(cells))
    return "\nUNION ALL\n".join(lines)


def _texts(table: pa.Table, fmt: str, cut: int) -> tuple[str, str]:
    """(value by value, column by column in batches of ``cut`` rows) of one table."""
    names = table.column_names
    by_value, by_column = io.StringIO(), io.StringIO()
    rows = list(zip(*[arrow_values(c) for c in table.columns], strict=True))
    w = ResultWriter(by_value, names, fmt)
    w.rows(rows)
    w.close()
    w = ResultWriter(by_column, names, fmt)
    for batch in table.to_batches(max_chunksize=cut):
        w.batch(batch, frozenset())
    w.close()
    return by_value.getvalue(), by_column.getvalue()


@pytest.mark.parametrize("seed", range(12))
def test_arrow_batches_write_what_python_values_write(seed: int) -> None:
    rng = random.Random(seed)
    con = duckdb.connect()
    for _ in range(6):
        sql = _random_select(rng, rng.randrange(1, 40), KINDS)
        table = con.sql(sql).to_arrow_table()
        for fmt in FORMATS:
            by_value, by_column = _texts(table, fmt, cut=rng.randrange(1, 50))
            assert by_column == by_value, (fmt, sql)
            if fmt == "json":  # strict JSON (no Infinity or NaN), every row
                assert len(json.loads(by_value, parse_constant=_refuse)) == len(table)


def _refuse(name: str) -> None:
    raise AssertionError(f"{name} is not JSON")


def test_floats_are_written_as_repr_writes_them() -> None:
    rng = random.Random(7)
    values = [rng.uniform(-1, 1) * 10.0 ** rng.randrange(-30, 30) for _ in range(20_000)] + FLOATS
    table = pa.table({"v": pa.array(values, pa.float64(), from_pandas=False)})
    for fmt in FORMATS:
        by_value, by_column = _texts(table, fmt, cut=4_096)
        assert by_column == by_value
    lines = _texts(table, "csv", cut=10_000)[1].splitlines()[1:]
    assert lines[:3] == [repr(v) for v in values[:3]]
    assert lines[-3:] == ["inf", "-inf", '""']  # NaN: no value (a row's only cell, quoted by the csv module)
    rows = _texts(table, "jsonl", cut=10_000)[1].splitlines()
    assert rows[-3:] == ['{"v": null}'] * 3  # JSON has no infinity


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    arc = tmp_path_factory.mktemp("query_text") / "arc"
    res = runner.invoke(app, ["ingest", str(SAMPLES / "ws4_health.log"), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    return arc


@pytest.mark.parametrize("fmt", FORMATS)
def test_a_long_result_prints_as_a_short_one_does(archive: Path, fmt: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The command end to end: DuckDB's Python rows (a short result) against its Arrow batches (the rest of a long
    one), over the archive's records and values made to be awkward."""
    plain = {"TINYINT", "BIGINT", "UBIGINT", "BOOLEAN", "DOUBLE", "FLOAT", "VARCHAR", "DATE", "TIMESTAMP_NS"}
    plain |= {"TIMESTAMP", "TIMESTAMPTZ"}
    rng = random.Random(48)
    made = _random_select(rng, 30, [k for k in KINDS if k[0] in plain])

    def run(sql: str) -> str:
        res = runner.invoke(app, ["query", sql, "--archive", str(archive), "--format", fmt])
        assert res.exit_code == 0, res.output
        return str(res.stdout)

    for sql in ("SELECT * FROM records ORDER BY file_seq, line", made, "SELECT * FROM records WHERE false"):
        monkeypatch.setattr(query_cmd, "ARROW_AFTER_ROWS", 10**9)
        by_value = run(sql)
        for first in (0, 7):
            monkeypatch.setattr(query_cmd, "ARROW_AFTER_ROWS", first)
            assert run(sql) == by_value, (sql, first)
        assert by_value.count("\n") >= (0 if "false" in sql else 1 if fmt == "json" else 30)
