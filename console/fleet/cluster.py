"""The Dask client's lifecycle: a LocalCluster started and always stopped, or an existing scheduler.

A LocalCluster listens on the loopback interface only, runs worker
*processes* (one thread each: the partition work holds the GIL in pandas
and the parsers), each bounded to ``memory_limit_bytes`` — its nanny
restarts a worker that goes over, and the scheduler gives its partitions
to another worker.  The dashboard address is printed to stderr when bokeh
is installed (it is what draws the dashboard); otherwise we say there is none.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

from console.fleet.options import EngineSpec, EngineUsageError, FleetError
from console.plural import count
from console.safe_text import one_line

if TYPE_CHECKING:
    from distributed import Client

LOOPBACK = "127.0.0.1"
CONNECT_TIMEOUT_S = 10
# An existing scheduler with no worker would leave the job waiting forever.
WORKERS_TIMEOUT_S = 30
_QUIET = ("distributed", "tornado", "asyncio")
# glibc's heap in the workers we start.  Dask sets MALLOC_TRIM_THRESHOLD_=64 KiB, which also fixes the mmap
# threshold at its 128 KiB default: every chunk's arrays are then mapped, faulted in and unmapped again.  On the
# ingest of 24 files (0.9 M records, 1 worker) that was 410 k page faults and 1.2 s of system time against 95 k
# and 0.5 s with these, for 30 MB more peak (benchmarks/bench_fleet.py; a process of our own gets glibc's
# defaults, which adapt).
WORKER_MALLOC_ENV = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": 8 << 20,
    "distributed.nanny.pre-spawn-environ.MALLOC_MMAP_THRESHOLD_": 32 << 20,
}


def require_dask() -> None:
    """The fleet extra is optional: say how to get it rather than fail on an import."""
    missing = [m for m in ("dask", "distributed") if importlib.util.find_spec(m) is None]
    if missing:
        raise EngineUsageError(f"--engine dask needs {' and '.join(missing)}: pip install 'trackside[fleet]'")


def has_dashboard() -> bool:
    return importlib.util.find_spec("bokeh") is not None


@contextlib.contextmanager
def quiet_logs() -> Iterator[None]:
    """Distributed's INFO/WARNING chatter (connections closing at shutdown, a worker restarted) off the terminal.

    The failures that matter reach the caller as exceptions, said in one line there.
    """
    loggers = [logging.getLogger(name) for name in _QUIET]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


@contextlib.contextmanager
def open_client(spec: EngineSpec, say: Callable[[str], None] | None = None) -> Iterator[Client]:
    """A connected client for ``spec`` (kind dask); the LocalCluster, if one was started, is closed on exit."""
    require_dask()
    import dask
    from distributed import Client, LocalCluster

    tell = say or (lambda _line: None)
    with quiet_logs():
        if spec.scheduler is not None:
            try:
                client = Client(spec.scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            except (OSError, TimeoutError) as exc:
                raise FleetError(f"cannot reach the dask scheduler {spec.scheduler}: {one_line(exc)}") from None
            try:
                try:
                    client.wait_for_workers(1, timeout=WORKERS_TIMEOUT_S)
                except (OSError, TimeoutError):
                    raise FleetError(
                        f"the dask scheduler {spec.scheduler} has no worker (waited {WORKERS_TIMEOUT_S} s)"
                    ) from None
                tell(f"dask scheduler {spec.scheduler}: {count(len(client.scheduler_info()['workers']), 'worker')}")
                yield client
            finally:
                client.close()
            return
        dashboard = has_dashboard()
        try:
            with dask.config.set(WORKER_MALLOC_ENV):
                cluster = LocalCluster(
                    n_workers=spec.workers or 1,
                    threads_per_worker=1,
                    processes=True,
                    host=LOOPBACK,
                    dashboard_address=f"{LOOPBACK}:0",  # loopback, a free port (never 8787 of another cluster)
                    memory_limit=spec.memory_limit_bytes,
                    silence_logs=logging.CRITICAL,
                )
        except (OSError, TimeoutError) as exc:
            raise FleetError(f"cannot start a local dask cluster: {one_line(exc)}") from None
        try:
            client = Client(cluster, set_as_default=False)
            try:
                where = f"dashboard {cluster.dashboard_link}" if dashboard else "no dashboard (install bokeh for one)"
                n = spec.workers or 1
                tell(f"dask local cluster {cluster.scheduler_address}: {n} worker{'s' if n != 1 else ''}; {where}")
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
