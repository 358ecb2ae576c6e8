"""The axles-per-head-per-day preset (counted per direction, then summed) gives exactly what the plain
one-pass count with FILTERs gives: the same rows, the same column types, the same bytes through `query`."""

from __future__ import annotations

from pathlib import Path

import duckdb
import numpy as np
import pyarrow as pa
import pytest
from typer.testing import CliRunner

from console.archive.presets import PRESETS
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()

# The preset as first written: one pass, three counts.  The reference the rewritten preset must equal.
ONE_PASS = """
SELECT day, device_id, counting_head, count(*) AS axles,
       count(*) FILTER (WHERE direction = 'sys1_to_sys2') AS axles_sys1_first,
       count(*) FILTER (WHERE direction = 'sys2_to_sys1') AS axles_sys2_first
FROM axles GROUP BY ALL ORDER BY day, device_id, counting_head
"""
PRESET = PRESETS["axles-per-head-per-day"].sql


def _axles(rng: np.random.Generator, n: int) -> pa.Table:
    """Axles as the archive stores them, with what a real table can hold: heads with one direction only, a
    direction of neither kind, NULL directions, heads and days."""
    directions = np.array(["sys1_to_sys2", "sys2_to_sys1", "unknown", None], dtype=object)
    heads = np.array(["WS1", "WS2", "WS10", "é", None], dtype=object)
    head = heads[rng.integers(0, len(heads), n)]
    # WS2 runs one way only: its other direction's count is 0, not NULL.
    direction = np.where(head == "WS2", "sys1_to_sys2", directions[rng.choice(4, n, p=[0.45, 0.45, 0.05, 0.05])])
    day = rng.integers(20_000, 20_004, n)
    day_null = rng.random(n) < 0.02
    return pa.table(
        {
            "device_id": pa.array(rng.integers(5001, 5004, n), pa.int64()),
            "counting_head": pa.array(head.tolist(), pa.large_string()),
            "direction": pa.array(direction.tolist(), pa.large_string()),
            "day": pa.array(np.where(day_null, 0, day).astype(np.int32), pa.date32(), mask=day_null),
        }
    )


@pytest.mark.parametrize("seed", range(8))
def test_preset_equals_the_one_pass_count(seed: int) -> None:
    rng = np.random.default_rng(seed)
    axles = _axles(rng, int(rng.integers(0, 5_000)) if seed else 0)  # seed 0: no axles at all
    con = duckdb.connect()
    con.register("axles", axles)
    want, got = con.sql(ONE_PASS), con.sql(PRESET)
    assert got.columns == want.columns
    assert got.types == want.types
    assert got.fetchall() == want.fetchall()


def test_preset_through_the_command_is_byte_identical(tmp_path: Path) -> None:
    arc = tmp_path / "arc"
    logs = [SAMPLES / "osong_ws4_0932_detection.log", SAMPLES / "example_station.log"]
    res = runner.invoke(app, ["ingest", *map(str, logs), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    for fmt in ("csv", "json", "jsonl", "table"):
        where = ["--archive", str(arc), "--format", fmt]
        got = runner.invoke(app, ["query", "--preset", "axles-per-head-per-day", *where])
        want = runner.invoke(app, ["query", ONE_PASS, *where])
        assert got.exit_code == want.exit_code == 0, got.output + want.output
        assert got.stdout == want.stdout
        assert fmt != "csv" or len(got.stdout.splitlines()) > 1  # the samples have axles
