"""The archive on the fleet engine: the same rows and the same report bytes on Dask as here, whatever the workers.

Random simulator archives (busy nights, passages over midnight, a sensor
fault), each in two pieces, are ingested and reported through the commands
with ``--engine local`` and with ``--engine dask`` on clusters of 1 and 3
workers: the same rows and the same report bytes.  A worker killed while it
runs a task costs a retry, never the answer, and the archive is never half
written.  More examples with ``TRACKSIDE_FLEET_EXAMPLES=20``.
"""

from __future__ import annotations

import json
import os
import re
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.archive.store import read_current
from console.cli.app import app
from console.sim.faults import Fault
from tests.fleet_fixtures import (
    archive_snapshot,
    kill_a_busy_worker,
    local_cluster,
    simulate_over_midnight,
)

pytestmark = pytest.mark.timeout(600)

EXAMPLES = int(os.environ.get("TRACKSIDE_FLEET_EXAMPLES", 2))
MINUTES = 12
SENSOR_FAULTS = ("dead_channel", "isolated_pulse", "damped_head", "power_loss", "missed_detections")
runner = CliRunner()


@pytest.fixture(scope="module")
def cluster1() -> Iterator[tuple[Any, Any]]:
    with local_cluster(1) as pair:
        yield pair


@pytest.fixture(scope="module")
def cluster3() -> Iterator[tuple[Any, Any]]:
    with local_cluster(3) as pair:
        yield pair


def _fault(kind: str | None, head: int, at_s: int) -> tuple[Fault, ...]:
    if kind is None:
        return ()
    return (Fault(kind, f"WS{head}", float(at_s), float(at_s + 300)),)


def _invoke(args: list[str]) -> Any:
    res = runner.invoke(app, args)
    assert res.exit_code == 0, (args, res.stdout, res.stderr)
    return res


def _derived(archive: Path) -> dict[str, Any]:
    """The derived passages and axles of an archive, as ``query --format json`` prints them."""
    out = {}
    for table, order in (
        ("passages", "device_id, counting_head, start_ns"),
        ("axles", "device_id, counting_head, time_ns"),
    ):
        sql = f"SELECT * EXCLUDE (day) FROM {table} ORDER BY {order}"
        res = _invoke(["query", sql, "--archive", str(archive), "--format", "json"])
        out[table] = json.loads(res.stdout)
    return out


def _day_rows(archive: Path) -> dict[str, list[dict[str, Any]]]:
    """The per-day inventory rows stored at ingest (head_days, identity_days: not query views), by day."""
    import pyarrow.parquet as pq

    from console.archive.head_days import TABLES, days_of_parts

    m = read_current(archive)
    out = {}
    for table in TABLES:
        rows = []
        for rel in sorted(m.parts(table), key=lambda r: sorted(days_of_parts([r]))):
            rows += [{"day": sorted(days_of_parts([rel])), **r} for r in pq.read_table(archive / rel).to_pylist()]
        out[table] = rows
    return out


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    seed=st.integers(1, 1000),
    before_s=st.integers(30, MINUTES * 60 - 60),  # the log runs over midnight
    nights=st.integers(1, 2),
    fault=st.sampled_from((None, *SENSOR_FAULTS)),
    fault_head=st.integers(1, 5),
    fault_at_s=st.integers(0, MINUTES * 60 - 300),
)
def test_the_same_rows_and_report_bytes_on_every_engine(
    tmp_path_factory: pytest.TempPathFactory,
    cluster1: tuple[Any, Any],
    cluster3: tuple[Any, Any],
    seed: int,
    before_s: int,
    nights: int,
    fault: str | None,
    fault_head: int,
    fault_at_s: int,
) -> None:
    tmp = tmp_path_factory.mktemp("fleet")
    log = tmp / "sim.log"
    simulate_over_midnight(log, seed, before_s, MINUTES, nights, _fault(fault, fault_head, fault_at_s))
    # The log in two pieces, ingested one after the other: the second ingest resumes from the state saved.
    lines = log.read_bytes().splitlines(keepends=True)
    first, second = tmp / "first.log", tmp / "second.log"
    first.write_bytes(b"".join(lines[: len(lines) // 2]))
    second.write_bytes(b"".join(lines[len(lines) // 2 :]))

    local_arc = tmp / "local"
    for piece in (first, second):
        _invoke(["ingest", str(piece), "--archive", str(local_arc), "--layout", "example"])
    want = _derived(local_arc)
    assert want["passages"]
    assert all(_day_rows(local_arc).values())
    local_json = _invoke(["report", "--archive", str(local_arc), "--format", "json"]).stdout
    assert json.loads(local_json)["passages"]  # a report with something in it
    # Through the commands on Dask, 1 and 3 workers: each group of heads a task, its state carried from
    # the first ingest to the second; the rows and the report's bytes are those of the local engine.
    for name, (cluster, _client) in (("1 worker", cluster1), ("3 workers", cluster3)):
        dask_arc = tmp / f"dask-{name[0]}"
        address = cluster.scheduler_address
        for piece in (first, second):
            args = ["ingest", str(piece), "--archive", str(dask_arc), "--layout", "example"]
            _invoke([*args, "--engine", "dask", "--scheduler", address])
        assert "*" not in read_current(dask_arc).derived["states"], name  # each group its own state
        assert _derived(dask_arc) == want, name
        assert _day_rows(dask_arc) == _day_rows(local_arc), name
        dask_json = _invoke(
            ["report", "--archive", str(dask_arc), "--format", "json", "--engine", "dask", "--scheduler", address]
        ).stdout
        assert dask_json == local_json, name


def test_a_local_cluster_started_by_the_command_gives_the_same_report(tmp_path: Path) -> None:
    log = tmp_path / "sim.log"
    simulate_over_midnight(log, 7, 400, MINUTES, 1, _fault("missed_detections", 2, 120))
    local_arc, dask_arc = tmp_path / "local", tmp_path / "dask"
    _invoke(["ingest", str(log), "--archive", str(local_arc), "--layout", "example"])
    res = _invoke(
        ["ingest", str(log), "--archive", str(dask_arc), "--layout", "example", "--engine", "dask", "--workers", "2"]
    )
    # The cluster and its dashboard said on stderr, one line.
    assert re.search(
        r"^dask local cluster tcp://127\.0\.0\.1:\d+: 2 workers; dashboard http://127\.0\.0\.1:\d+/status$",
        res.stderr,
        re.M,
    )
    assert _derived(dask_arc) == _derived(local_arc)
    local_json = _invoke(["report", "--archive", str(local_arc), "--format", "json"]).stdout
    dask_json = _invoke(
        ["report", "--archive", str(dask_arc), "--format", "json", "--engine", "dask", "--workers", "1"]
    ).stdout
    assert dask_json == local_json


def _ingest_with_a_worker_killed(tmp_path: Path, cluster: Any, client: Any) -> tuple[Any, Path, Path, dict[str, bytes]]:
    """A second night ingested on Dask while one worker is SIGKILLed in the middle of a partition.

    Returns the command's result, the archive, a reference archive (the same two ingests, local)
    and the archive's files before the second ingest.
    """
    first, second = tmp_path / "night1.log", tmp_path / "night2.log"
    simulate_over_midnight(first, 21, 500, MINUTES, 1)
    simulate_over_midnight(second, 22, 300, MINUTES, 1)
    ref, arc = tmp_path / "ref", tmp_path / "arc"
    for root in (ref, arc):
        _invoke(["ingest", str(first), "--archive", str(root), "--layout", "example"])
    _invoke(["ingest", str(second), "--archive", str(ref), "--layout", "example"])
    before = archive_snapshot(arc)
    killed: list[int | None] = []
    killer = threading.Thread(target=lambda: killed.append(kill_a_busy_worker(client, "trackside-derive-")))
    killer.start()
    try:
        args = ["ingest", str(second), "--archive", str(arc), "--layout", "example"]
        res = runner.invoke(app, [*args, "--engine", "dask", "--scheduler", cluster.scheduler_address])
    finally:
        killer.join()
    assert killed[0] is not None  # a worker died while it derived a partition
    return res, arc, ref, before


def test_a_worker_killed_during_ingest_is_retried_and_the_archive_is_right(
    tmp_path: Path, cluster3: tuple[Any, Any]
) -> None:
    res, arc, ref, _before = _ingest_with_a_worker_killed(tmp_path, *cluster3)
    assert res.exit_code == 0, res.stderr
    assert _derived(arc) == _derived(ref)


@pytest.fixture
def fragile_cluster() -> Iterator[tuple[Any, Any]]:
    """A cluster whose scheduler gives up on a partition at the first worker that dies with it."""
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), local_cluster(2) as pair:
        yield pair


def test_a_run_the_cluster_gives_up_is_one_line_and_the_archive_as_before(
    tmp_path: Path, fragile_cluster: tuple[Any, Any]
) -> None:
    res, arc, _ref, before = _ingest_with_a_worker_killed(tmp_path, *fragile_cluster)
    assert res.exit_code == 2
    note, error = res.stderr.splitlines()  # the cluster it used, then the one-line error
    assert note.startswith("dask scheduler tcp://127.0.0.1:")
    assert re.fullmatch(
        r"trackside: error: partition (sections:\S+|device:\d+): the workers running it died"
        r" repeatedly \(out of memory or killed\); archive unchanged",
        error,
    ), error
    assert archive_snapshot(arc) == before  # never half written


def test_engine_failures_are_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import socket

    from console.fleet import cluster as fleet_cluster

    monkeypatch.setattr(fleet_cluster, "CONNECT_TIMEOUT_S", 2)

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    log = tmp_path / "sim.log"
    simulate_over_midnight(log, 3, 60, 5, 1)
    arc = tmp_path / "arc"
    cases = [
        (
            ["ingest", str(log), "--archive", str(arc), "--engine", "dask", "--workers", "0"],
            "--workers: expected 1 to 64, found 0",
        ),
        (["ingest", str(log), "--archive", str(arc), "--engine", "spark"], "--engine: expected local or dask"),
        (["report", "--archive", str(arc), "--workers", "2"], "--workers needs --engine dask"),
        (["report", str(log), "--engine", "dask"], "--engine dask needs --archive"),
        (
            ["ingest", str(log), "--archive", str(arc), "--engine", "dask", "--scheduler", f"tcp://127.0.0.1:{port}"],
            f"cannot reach the dask scheduler tcp://127.0.0.1:{port}",
        ),
    ]
    for args, message in cases:
        res = runner.invoke(app, args)
        assert res.exit_code == 2, args
        assert res.stderr.startswith(f"trackside: error: {message}") and res.stderr.count("\n") == 1, res.stderr
    assert not (arc / "CURRENT").exists()  # nothing was ingested by any of them


def test_dask_not_installed_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "distributed" else real(name, *a))
    res = runner.invoke(app, ["report", "--archive", str(tmp_path), "--engine", "dask"])
    assert res.exit_code == 2
    assert res.stderr == "trackside: error: --engine dask needs distributed: pip install 'trackside[fleet]'\n"
