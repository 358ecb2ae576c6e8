"""Ingest on Dask, each set of files sharing a group of heads parsed and derived in one pass by one task.

The plan joins files by the heads a few blocks of each name (a hint); the
task's parse decides.  Where the hint misses a head two files share, two
tasks meet its group: the archive then derives that group from its records,
and the rows and the report are still the local engine's.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from console.archive import group_ingest
from console.archive.derive_groups import group_key_of
from console.archive.group_ingest import heads_hint, plan_tasks
from console.archive.store import read_current
from console.cli.app import app
from console.layout import load_layout
from tests.fleet_fixtures import local_cluster, simulate_over_midnight

pytestmark = pytest.mark.timeout(600)
runner = CliRunner()


@pytest.fixture(scope="module")
def cluster2() -> Iterator[tuple[Any, Any]]:
    with local_cluster(2) as pair:
        yield pair


def _invoke(args: list[str]) -> Any:
    res = runner.invoke(app, args)
    assert res.exit_code == 0, (args, res.stdout, res.stderr)
    return res


def _rows(archive: Path) -> dict[str, str]:
    """Every derived table and the records, as ``query --format csv`` prints them in one order."""
    out = {}
    # The section history's seq (the order of rows made at one time) is not compared: the start rows are written
    # once per ingest on Dask, at the line's first event, so their seq is the last ingest's (as before this path).
    # Passages and axles with the day they are stored under (an axle's is its passage's, on every engine).
    excluded = {
        "health_findings": "",
        "passages": "",
        "axles": "",
        "section_states": "EXCLUDE (day, seq)",
        "count_ledger": "EXCLUDE (day, seq)",
    }
    for table in ("passages", "axles", "section_states", "count_ledger", "health_findings", "records"):
        sql = f"SELECT * {excluded.get(table, 'EXCLUDE (day)')} FROM {table} ORDER BY ALL"
        out[table] = _invoke(["query", sql, "--archive", str(archive), "--format", "csv"]).stdout
    return out


def test_files_sharing_a_group_are_one_task() -> None:
    key_of = group_key_of(load_layout("example"))
    hints = [
        {(7, "WS1")},  # a section's head
        {(8, "XX")},  # a device's own head
        {(9, "WS2")},  # WS1's group of sections (WS1 and WS2 bound one section), on another device
        set(),  # nothing seen: a task of its own
        {(8, "YY"), (5, "ZZ")},  # device 8 again, and device 5
        {(5, "QQ")},
    ]
    assert key_of(9, "WS2") == key_of(7, "WS1") != key_of(8, "XX") == "device:8"
    assert plan_tasks(hints, key_of) == [[0, 2], [1, 4, 5], [3]]


def test_the_hint_names_the_heads_of_a_file(tmp_path: Path) -> None:
    log = tmp_path / "sim.log"
    simulate_over_midnight(log, 5, 300, 6)
    hint = heads_hint(log)
    assert hint and all(isinstance(d, int) and name.startswith("WS") for d, name in hint)
    assert heads_hint(tmp_path / "missing.log") == set()
    # Cut lines (a file of the damaged lines of many devices) name nothing: they would join every group.
    whole = log.read_bytes().splitlines(keepends=True)[:50]
    cut = tmp_path / "cut.log"
    cut.write_bytes(b"".join(line[: len(line) * 2 // 3] + b"\n" for line in whole))
    assert heads_hint(cut) == set()


@pytest.mark.parametrize("hinted", [True, False], ids=["hint right", "hint missed every shared group"])
def test_the_same_rows_whatever_the_plan(
    tmp_path: Path, cluster2: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch, hinted: bool
) -> None:
    log = tmp_path / "sim.log"
    simulate_over_midnight(log, 11, 400, 10, 2)
    # Three pieces in one ingest (each holds every head), then a fourth in a second ingest (resumed).
    lines = log.read_bytes().splitlines(keepends=True)
    n = len(lines) // 4
    pieces = []
    for i in range(4):
        piece = tmp_path / "in" / f"p{i}.log"
        piece.parent.mkdir(exist_ok=True)
        piece.write_bytes(b"".join(lines[i * n : (i + 1) * n if i < 3 else len(lines)]))
        pieces.append(piece)
    local, dask = tmp_path / "local", tmp_path / "dask"
    for root in (local, dask):
        engine = ["--engine", "dask", "--scheduler", cluster2[0].scheduler_address] if root == dask else []
        if not hinted and root == dask:
            # The hints (the workers' now) as if they named no head: every file a task of its own.
            monkeypatch.setattr(group_ingest, "plan_tasks", lambda hints, _key_of: [[i] for i in range(len(hints))])
        for batch in (pieces[:3], pieces[3:]):
            _invoke(["ingest", *map(str, batch), "--archive", str(root), "--layout", "example", *engine])
            if root == dask and batch[0] == pieces[0]:
                # The states a task saved name it (-pN); a group derived from its records afterwards does not.
                states = read_current(dask).derived["states"].values()
                assert all(("-p" in Path(rel).name) == hinted for rel in states), states
    assert "*" not in read_current(dask).derived["states"]
    want = _rows(local)
    assert want["passages"].count("\n") > 10 and want["section_states"].count("\n") > 10
    assert _rows(dask) == want
    report = ["report", "--archive"]
    assert (
        _invoke([*report, str(dask), "--format", "json"]).stdout
        == _invoke([*report, str(local), "--format", "json"]).stdout
    )
