"""Dask clusters for the fleet tests: loopback only, always closed, no process left behind.

A cluster takes a few seconds to start on a loaded machine, so the tests
share one per worker count (module scope) and reach it as an existing
scheduler (``--scheduler``), the way a real fleet is used; one test per
module starts its own LocalCluster through ``--workers``.
"""

from __future__ import annotations

import logging
import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import dask
import psutil  # type: ignore[import-untyped]  # (distributed depends on it; no stubs installed)
from distributed import Client, LocalCluster

from console.fleet.options import WORKER_MEMORY_LIMIT_BYTES
from console.sim.faults import Fault

# Dask's own diagnostics, which no test reads, off in the tests' clusters: each worker's statistical profiler
# (a stack sample every 10 ms) and each server's event-loop check (every 20 ms). An idle pair of clusters
# (1 and 3 workers) took 0.16 s of CPU a second with them, 0.07 without; busy workers pay the profiler too.
QUIET_CLUSTER = {"distributed.worker.profile.enabled": False, "distributed.admin.tick.interval": "1s"}


@contextmanager
def local_cluster(workers: int) -> Iterator[tuple[LocalCluster, Client]]:
    """A LocalCluster on 127.0.0.1 with a client; closed on exit, its worker processes checked gone."""
    before = children_pids()
    with dask.config.set(QUIET_CLUSTER):  # read when the scheduler and the nannies are made; passed to workers
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


# 2026-03-03 00:00 UTC: the simulated logs run over this midnight.
MIDNIGHT_S = 1_772_496_000


def simulate_over_midnight(
    path: Path, seed: int, before_s: int, minutes: int, nights: int = 1, faults: tuple[Fault, ...] = ()
) -> None:
    """A diagnostic log of ``minutes`` from ``before_s`` before midnight, on ``nights`` consecutive nights.

    Busy (40 trains an hour, the first 30 s in), so passages run over
    midnight; ``faults`` (their times from each night's start) as the
    simulator injects them.
    """
    from console.layout import load_layout
    from console.sim.line_values import SimConfig
    from console.sim.station import StationSim
    from console.sim.writers import write_diagnostic

    lines: list[str] = []
    for night in range(nights):
        start_ns = (MIDNIGHT_S + night * 86_400 - before_s) * 1_000_000_000
        cfg = SimConfig(seed=seed + night, trains_per_hour=40, first_train_s=30, start_ns=start_ns, faults=faults)
        sim = StationSim(load_layout("example"), cfg)
        sim.run(minutes * 60)
        part = path.with_suffix(f".{night}")
        write_diagnostic(sim, part)
        lines += part.read_text(encoding="utf-8").splitlines()
        part.unlink()
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def archive_snapshot(root: Path) -> dict[str, bytes]:
    """What readers of an archive see: relative path → bytes of its manifests and of every data part the
    current manifest names (data files it does not name are invisible to every reader)."""
    from console.archive.store import read_current

    named = {rel for parts in read_current(root).tables.values() for rel in parts}
    out: dict[str, bytes] = {}
    for p in sorted(root.rglob("*")):
        rel = p.relative_to(root).as_posix()
        if not p.is_file() or rel == "lock" or rel.startswith("tmp/"):
            continue
        if rel.startswith("data/") and rel not in named:
            continue
        out[rel] = p.read_bytes()
    return out


def kill_a_busy_worker(client: Client, prefix: str, timeout_s: float = 60.0) -> int | None:
    """SIGKILL the process of the first worker seen running a task whose key starts with ``prefix``.

    Returns its pid, or None when no such task ran within ``timeout_s``.
    """
    pids = worker_pids(client)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for addr, keys in client.processing().items():
            if any(str(k).startswith(prefix) for k in keys) and addr in pids:
                os.kill(pids[addr], signal.SIGKILL)
                return pids[addr]
        time.sleep(0.005)
    return None
