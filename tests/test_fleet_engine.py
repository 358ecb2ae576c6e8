"""The fleet engine: partitions give the same list here and on Dask, in the order given,
a killed worker costs time not answers, and every failure is one line."""

from __future__ import annotations

import io
import os
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from console.fleet import cluster as fleet_cluster
from console.fleet import map_partitions, run_with_engine
from console.fleet.options import EngineSpec, EngineUsageError, FleetError, engine_spec
from console.fleet.progress import task_progress
from tests.fleet_fixtures import children_pids, local_cluster, worker_pids

pytestmark = pytest.mark.timeout(180)

# Partitions: (head, day), each naming the day before it needs (as the archive's Carried does).
ITEMS = [
    {"key": (head, day), "day_before": day - 1 if day else None} for head in ("WS1", "WS2", "WS3") for day in range(8)
]


def axles_of(head: str, day: int) -> int:
    return (day * 37 + int(head[2:]) * 11) % 23


def partition_total(key: tuple[str, int], day_before: int | None, base: int) -> tuple[str, int, int]:
    """A partition's answer from its own data and its neighbour's (read, not passed along)."""
    head, day = key
    before = axles_of(head, day_before) if day_before is not None else 0
    return head, day, base + axles_of(head, day) + before


def slow_total(key: tuple[str, int], day_before: int | None, base: int, marks: str) -> tuple[str, int, int]:
    """As partition_total, slowly, leaving a mark per finished partition (the killer watches them)."""
    time.sleep(0.25)
    out = partition_total(key, day_before, base)
    Path(marks, f"{key[0]}-{key[1]}-{os.getpid()}").touch()
    return out


def broken(key: tuple[str, int], day_before: int | None, base: int) -> int:
    if key == ("WS2", 3):
        raise ValueError("WS2 day 3: part unreadable")
    return 0


EXPECTED = [partition_total(it["key"], it["day_before"], 100) for it in ITEMS]  # type: ignore[arg-type]


def _run(spec: EngineSpec, fn: Any = partition_total, **common: Any) -> list[Any]:
    return run_with_engine(spec, lambda: map_partitions(fn, ITEMS, common={"base": 100, **common}))


@pytest.fixture(scope="module")
def cluster2() -> Iterator[tuple[Any, Any]]:
    with local_cluster(2) as pair:
        yield pair


def test_local_engine_runs_every_partition_in_the_order_given() -> None:
    assert _run(engine_spec()) == EXPECTED
    assert map_partitions(partition_total, ITEMS, common={"base": 100}) == EXPECTED  # outside any engine: local
    assert EXPECTED[9] == ("WS2", 1, 100 + axles_of("WS2", 1) + axles_of("WS2", 0))


def test_dask_on_an_existing_scheduler_gives_the_local_list(cluster2: tuple[Any, Any]) -> None:
    cluster, _client = cluster2
    notes: list[str] = []
    spec = engine_spec("dask", scheduler=cluster.scheduler_address)
    got = run_with_engine(spec, lambda: map_partitions(partition_total, ITEMS, common={"base": 100}), say=notes.append)
    assert got == EXPECTED
    assert notes == [f"dask scheduler {cluster.scheduler_address}: 2 workers"]


def test_several_maps_share_one_cluster_and_empty_maps_are_empty(cluster2: tuple[Any, Any]) -> None:
    cluster, _client = cluster2

    def job() -> tuple[list[Any], list[Any], list[Any]]:
        return (
            map_partitions(partition_total, ITEMS, common={"base": 100}),
            map_partitions(partition_total, [], common={"base": 100}),
            map_partitions(partition_total, ITEMS[:3], common={"base": 5}),
        )

    first, empty, third = run_with_engine(engine_spec("dask", scheduler=cluster.scheduler_address), job)
    assert first == EXPECTED and empty == []
    assert third == [partition_total(it["key"], it["day_before"], 5) for it in ITEMS[:3]]  # type: ignore[arg-type]


def test_workers_are_bounded_to_1_gib(cluster2: tuple[Any, Any]) -> None:
    _cluster, client = cluster2
    limits = {w["memory_limit"] for w in client.scheduler_info()["workers"].values()}
    assert limits == {1 << 30}


def test_local_cluster_is_started_on_loopback_and_stopped() -> None:
    before = children_pids()
    notes: list[str] = []
    spec = engine_spec("dask", workers=2)
    got = run_with_engine(spec, lambda: map_partitions(partition_total, ITEMS, common={"base": 100}), say=notes.append)
    assert got == EXPECTED
    assert notes[0].startswith("dask local cluster tcp://127.0.0.1:")
    assert "2 workers" in notes[0] and "dashboard" in notes[0]  # its address, or why there is none
    deadline = time.monotonic() + 15
    while children_pids() - before and time.monotonic() < deadline:
        time.sleep(0.1)
    assert children_pids() - before == set()  # its worker processes are gone


def test_a_killed_worker_costs_time_not_the_answer(cluster2: tuple[Any, Any], tmp_path: Path) -> None:
    cluster, client = cluster2
    before = worker_pids(client)
    killed: list[int] = []
    done_at_kill: list[int] = []

    def killer() -> None:
        # Once a few partitions are done (the run is under way), SIGKILL one worker.
        deadline = time.monotonic() + 60
        while len(list(tmp_path.iterdir())) < 4 and time.monotonic() < deadline:
            time.sleep(0.05)
        pid = min(before.values())
        done_at_kill.append(len(list(tmp_path.iterdir())))
        os.kill(pid, signal.SIGKILL)
        killed.append(pid)

    t = threading.Thread(target=killer)
    t.start()
    try:
        got = _run(engine_spec("dask", scheduler=cluster.scheduler_address), slow_total, marks=str(tmp_path))
    finally:
        t.join()
    assert killed and 0 < done_at_kill[0] < len(EXPECTED)  # killed mid-run
    assert got == EXPECTED
    assert killed[0] not in worker_pids(client).values()  # the nanny started a new worker in its place


def test_an_error_in_a_partition_is_raised_as_itself(cluster2: tuple[Any, Any]) -> None:
    cluster, _client = cluster2
    with pytest.raises(ValueError, match="WS2 day 3: part unreadable"):
        _run(engine_spec("dask", scheduler=cluster.scheduler_address), broken)
    with pytest.raises(ValueError, match="WS2 day 3: part unreadable"):
        _run(engine_spec(), broken)


def test_an_unreachable_scheduler_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    import socket

    monkeypatch.setattr(fleet_cluster, "CONNECT_TIMEOUT_S", 2)
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(FleetError) as info:
        _run(engine_spec("dask", scheduler=f"tcp://127.0.0.1:{port}"))
    assert str(info.value).startswith(f"cannot reach the dask scheduler tcp://127.0.0.1:{port}")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("spark", None, None), "--engine: expected local or dask, found 'spark'"),
        (("local", 2, None), "--workers needs --engine dask"),
        (("local", None, "tcp://h:1"), "--scheduler needs --engine dask"),
        (("dask", 2, "tcp://h:1"), "not both"),
        (("dask", 0, None), "--workers: expected 1 to 64, found 0"),
        (("dask", None, "http://h:1"), "--scheduler: expected tcp://HOST:PORT"),
    ],
)
def test_impossible_engine_options_are_refused_before_any_work(args: tuple[Any, Any, Any], message: str) -> None:
    with pytest.raises(EngineUsageError, match=message.replace("(", r"\(").replace(")", r"\)")):
        engine_spec(*args)


def test_engine_defaults() -> None:
    assert engine_spec() == EngineSpec()
    assert engine_spec("dask") == EngineSpec(kind="dask", workers=2)
    assert engine_spec("DASK", scheduler="tcp://10.0.0.5:8786").scheduler == "tcp://10.0.0.5:8786"


def test_progress_counts_tasks_on_a_terminal_only() -> None:
    tty = io.StringIO()
    with task_progress(40, "derive", Console(file=tty, force_terminal=True, width=100)) as done:
        done(15)
        done(25)
    assert "40/40" in tty.getvalue() and "tasks" in tty.getvalue()
    pipe = io.StringIO()
    with task_progress(40, "derive", Console(file=pipe, force_terminal=False)) as done:
        done(40)
    assert pipe.getvalue() == ""


def test_progress_joins_the_bar_a_command_already_shows() -> None:
    """Rich shows one live display at a time: inside ingest's bar, the tasks get a line of their own, removed after."""
    from rich.progress import Progress

    tty = io.StringIO()
    host = Progress(console=Console(file=tty, force_terminal=True, width=100))
    with host:
        outer = host.add_task("ingest", total=None)
        lines: list[int] = []
        with task_progress(12, "derive", host=host) as done:
            lines.append(len(host.tasks))
            done(5)
            done(7)
            lines.append(int(next(t for t in host.tasks if t.id != outer).completed))
        lines.append(len(host.tasks))
    assert lines == [2, 12, 1]
    assert "derive (tasks)" in tty.getvalue()
