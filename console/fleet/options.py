"""The engine options every archive command shares: ``--engine``, ``--workers``, ``--scheduler``.

Typer option types (one place, so ``ingest`` and ``report --archive`` spell
them the same) and :func:`engine_spec`, which checks their combination
before any work starts: a usage mistake is one line and exit 2, never a
cluster started for nothing.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Annotated, Literal

import typer

from console.plural import count

ENGINES = ("local", "dask")
# A worker's memory is bounded: the nanny restarts a worker that goes over
# (its task is then retried elsewhere).  An ingest task parses a whole group
# of heads' files: 2.5 M records (56 days of a device) peaked at 400-450 MB,
# against 512 MB's pause at 410 and restart at 486.  The rest is the
# interpreter, pandas, pyarrow and DuckDB loaded once per worker.
WORKER_MEMORY_LIMIT_BYTES = 1 << 30
MAX_LOCAL_WORKERS = 64
_SCHEDULER = re.compile(r"^(tcp|tls)://[^\s/:]+(:\d{1,5})?$|^(tcp|tls)://\[[0-9A-Fa-f:.]+\](:\d{1,5})?$")

EngineOpt = Annotated[
    str,
    typer.Option(
        "--engine",
        metavar="local|dask",
        help="Where the archive's tasks (the diagnostic logs of a group of linked heads, parsed and derived) run: "
        "local (this process) or dask.",
    ),
]
WorkersOpt = Annotated[
    int | None,
    typer.Option(
        "--workers",
        metavar="N",
        help="With --engine dask: start a local cluster of N worker processes (1 GiB each) [default: 2].",
        show_default=False,
    ),
]
SchedulerOpt = Annotated[
    str | None,
    typer.Option(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="With --engine dask: an existing distributed scheduler, tcp://HOST:PORT (workers must see the archive).",
        show_default=False,
    ),
]


class EngineUsageError(ValueError):
    """An impossible combination of engine options: one line for the user, exit 2."""


class FleetError(Exception):
    """The cluster could not finish the run: one line for the user, exit 2 (the archive is unchanged)."""


@dataclass(frozen=True)
class EngineSpec:
    """Where the work runs: in this process, a LocalCluster of ``workers`` processes, or ``scheduler``."""

    kind: Literal["local", "dask"] = "local"
    workers: int | None = None
    scheduler: str | None = None
    memory_limit_bytes: int = WORKER_MEMORY_LIMIT_BYTES

    @property
    def starts_cluster(self) -> bool:
        return self.kind == "dask" and self.scheduler is None

    def describe(self) -> str:
        if self.kind == "local":
            return "local engine (this process)"
        if self.scheduler is not None:
            return f"dask scheduler {self.scheduler}"
        return f"dask local cluster, {count(self.workers or 0, 'worker')} of {self.memory_limit_bytes >> 20} MB"


def engine_spec(engine: str = "local", workers: int | None = None, scheduler: str | None = None) -> EngineSpec:
    """Check the options' combination; :class:`EngineUsageError` names what is wrong."""
    engine = engine.strip().lower()
    if engine not in ENGINES:
        raise EngineUsageError(f"--engine: expected local or dask, found {engine!r}")
    if engine == "local":
        if workers is not None or scheduler is not None:
            given = "--workers" if workers is not None else "--scheduler"
            raise EngineUsageError(f"{given} needs --engine dask")
        return EngineSpec()
    if workers is not None and scheduler is not None:
        raise EngineUsageError("give --workers N (a local cluster) or --scheduler tcp://HOST:PORT, not both")
    if scheduler is not None:
        if not _SCHEDULER.match(scheduler):
            raise EngineUsageError(f"--scheduler: expected tcp://HOST:PORT, found {scheduler!r}")
        return EngineSpec(kind="dask", scheduler=scheduler)
    n = 2 if workers is None else workers
    if not 1 <= n <= MAX_LOCAL_WORKERS:
        raise EngineUsageError(f"--workers: expected 1 to {MAX_LOCAL_WORKERS}, found {n}")
    return EngineSpec(kind="dask", workers=n)
