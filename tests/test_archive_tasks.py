"""Partition tasks are cut by records as well as by days, and how they are cut does not change the rows."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.archive import partition
from console.archive.history import _layout, speed_settings
from console.archive.partition import _records_in, carried_state, make_tasks, partitions
from console.archive.store import read_current
from console.cli import app
from tests.fleet_fixtures import simulate_over_midnight

runner = CliRunner()
TABLES = {
    "passages": "device_id, counting_head, start_ns",
    "axles": "device_id, counting_head, time_ns",
    "section_states": "time_ns, section",
    "count_ledger": "time_ns, section",
}


def _tables(archive: Path) -> dict[str, object]:
    out = {}
    for table, order in TABLES.items():
        res = runner.invoke(
            app, ["query", f"SELECT * FROM {table} ORDER BY {order}", "--archive", str(archive), "--format", "json"]
        )
        assert res.exit_code == 0, res.stdout
        out[table] = json.loads(res.stdout)
    return out


def test_tasks_bounded_by_records_give_the_rows_of_whole_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    log = tmp_path / "sim.log"
    simulate_over_midnight(log, seed=7, before_s=300, minutes=10, nights=4)

    whole = tmp_path / "whole"
    assert runner.invoke(app, ["ingest", str(log), "--archive", str(whole), "--layout", "example"]).exit_code == 0
    m = read_current(whole)
    keys = partitions(m)
    per_day = {
        k: _records_in(whole, [r for r in m.parts("records") if f"day={k.day}/device_id={k.device_id}/" in r])
        for k in keys
    }
    settings = speed_settings(m, _layout(m.derived.get("layout")))
    carried = carried_state(keys)
    assert len(make_tasks(whole, m, keys, carried, settings)) < len(keys)  # default: several days per task

    # A budget of two days' records: no task holds more, but for a day alone.
    budget = 2 * max(per_day.values())
    for task in make_tasks(whole, m, keys, carried, settings, max_records=budget):
        held = sum(per_day[k] for k in task.keys)
        assert held <= budget or len(task.keys) == 1

    # Every day its own task: the same derived tables as whole runs.
    monkeypatch.setattr(partition, "TASK_RECORDS", 1)
    assert all(len(t.keys) == 1 for t in make_tasks(whole, m, keys, carried, settings))
    split = tmp_path / "split"
    assert runner.invoke(app, ["ingest", str(log), "--archive", str(split), "--layout", "example"]).exit_code == 0
    assert _tables(split) == _tables(whole)
