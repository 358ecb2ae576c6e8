"""Dask clusters for the fleet tests: loopback only, always closed, no process left behind.

A cluster takes a few seconds to start on a loaded machine, so the tests
share one per worker count (module scope) and reach it as an existing
scheduler (``--scheduler``), the way a real fleet is used; one test per
module starts its own LocalCluster through ``--workers``.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager

import psutil  # type: ignore[import-untyped]  # (distributed depends on it; no stubs installed)
from distributed import Client, LocalCluster

from console.fleet.options import WORKER_MEMORY_LIMIT_BYTES


@contextmanager
def local_cluster(workers: int) -> Iterator[tuple[LocalCluster, Client]]:
    """A LocalCluster on 127.0.0.1 with a client; closed on exit, its worker processes checked gone."""
    before = children_pids()
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        memory_limit=WORKER_MEMORY_LIMIT_BYTES,
        silence_logs=logging.CRITICAL,
    )
    client = Client(cluster, set_as_default=False)
    try:
        yield cluster, client
    finally:
        pids = children_pids() - before  # the workers, and any restarted after a kill
        client.close()
        cluster.close()
        assert_gone(pids)


def children_pids() -> set[int]:
    """This process's descendants, but multiprocessing's resource tracker (one per session, by design)."""
    out = set()
    for p in psutil.Process().children(recursive=True):
        try:
            if p.status() != psutil.STATUS_ZOMBIE and not any("resource_tracker" in part for part in p.cmdline()):
                out.add(p.pid)
        except psutil.Error:
            continue
    return out


def worker_pids(client: Client) -> dict[str, int]:
    """Worker address → its process id (the process a nanny restarts when it dies)."""
    return dict(client.run(os.getpid))


def assert_gone(pids: set[int], timeout_s: float = 15.0) -> None:
    """Every process in ``pids`` has exited (zombies reaped or not, none is still running)."""
    deadline = time.monotonic() + timeout_s
    alive = set(pids)
    while alive and time.monotonic() < deadline:
        alive = {p for p in alive if _running(p)}
        if alive:
            time.sleep(0.1)
    assert not alive, f"processes left behind: {sorted(alive)}"


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False
