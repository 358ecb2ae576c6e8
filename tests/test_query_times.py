"""`trackside query`'s times: a few rows formatted one by one (no numpy import), many vectorized, the same text."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from console.analysis.timefmt import iso, iso_array
from console.cli.app import app
from console.cli.commands import query as query_cmd
from parsers.units import ALL_TIME, NO_TIME
from tests.conftest import SAMPLES

runner = CliRunner()
LOG = SAMPLES / "osong_ws4_0932_detection.log"
# Times of every precision around now, before 1970 and at int64's two ends, and nulls between them.
TIMES_SQL = (
    "SELECT i, CASE WHEN i % 7 = 0 THEN NULL ELSE make_timestamp_ns(t) END AS t, "
    "CASE WHEN i % 5 = 0 THEN NULL ELSE make_timestamp_ns(t // 1000 * 1000) END AS t_us "
    "FROM (SELECT i, (CASE i % 4 WHEN 0 THEN 1772409613250125001 WHEN 1 THEN -86400250000000 "
    "WHEN 2 THEN 1772409613000000000 ELSE 1772409613250000000 END) + i * 1000003 AS t FROM range(0, 3000) r(i)) "
    "ORDER BY i"
)


def test_the_scalar_iso_is_the_vectorized_one() -> None:
    """:func:`iso` per value equals :func:`iso_array` on random epoch ns of every precision (query's two paths)."""
    rng = np.random.default_rng(28)
    raw = rng.integers(-(2**62), 2**62, 20_000, dtype=np.int64)
    values = np.concatenate(
        [
            raw,
            raw // 10**9 * 10**9,  # whole seconds
            raw // 10**6 * 10**6,  # milliseconds
            raw // 10**3 * 10**3,  # microseconds
            # Not int64's least (NO_TIME): numpy reads it as NaT, and DuckDB's epoch_ns never gives it (its
            # -infinity comes out NULL).
            np.array([0, -1, 1, ALL_TIME, NO_TIME + 1, ALL_TIME - 999_999_999], np.int64),
        ]
    )
    assert [iso(int(v)) for v in values] == iso_array(values).tolist()


def test_int64_bounds_are_numpy_s() -> None:
    assert (int(np.iinfo(np.int64).min), int(np.iinfo(np.int64).max)) == (NO_TIME, ALL_TIME)


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    arc = tmp_path_factory.mktemp("query_times") / "arc"
    res = runner.invoke(app, ["ingest", str(LOG), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    return arc


@pytest.mark.parametrize("fmt", ["csv", "json", "jsonl"])
def test_few_rows_print_as_many_rows_do(archive: Path, fmt: str, monkeypatch: pytest.MonkeyPatch) -> None:
    def run() -> str:
        res = runner.invoke(app, ["query", TIMES_SQL, "--archive", str(archive), "--format", fmt])
        assert res.exit_code == 0, res.output
        return str(res.stdout)

    scalar = run()
    monkeypatch.setattr(query_cmd, "ARROW_AFTER_ROWS", 0)  # every row from Arrow batches, times by iso_array
    assert run() == scalar
    # i = 1: -86,400.248999997 s, a second before 1970 counted down, its fraction up (as numpy's floor does).
    assert "1969-12-30T23:59:59.751000003Z" in scalar


def test_a_heads_hour_imports_no_numpy(archive: Path) -> None:
    """The commonest query (records of a head in a time window) starts without numpy (a tenth of a second)."""
    sql = (
        "SELECT * FROM records WHERE counting_head = 'WS4' AND time >= TIMESTAMP '2000-01-01' "
        "AND time < TIMESTAMP '2100-01-01'"
    )
    launch = (
        "import sys; sys.argv[0] = 'trackside'; from console.cli.app import app\n"
        "try:\n    app()\nfinally:\n    print('numpy' in sys.modules, file=sys.stderr)"
    )
    p = subprocess.run(
        [sys.executable, "-c", launch, "query", sql, "--archive", str(archive), "--format", "csv"],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=Path(__file__).resolve().parent.parent,
    )
    assert p.returncode == 0, p.stderr
    assert p.stdout.count("\n") > 10 and "Z," in p.stdout
    assert p.stderr.strip().splitlines()[-1] == "False"
