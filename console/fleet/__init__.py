"""The fleet: the archive's tasks run in-process or on a Dask cluster, with the same answer.

``--engine local`` (the default) runs every task in this process;
``--engine dask`` ships the same task function to a ``distributed``
cluster — a LocalCluster started and stopped here (``--workers N``) or an
existing scheduler (``--scheduler tcp://HOST:PORT``).  The tasks are the
archive's own units of work (the files of a group of linked sections, parsed
and derived in one pass: :mod:`console.archive.group_ingest`; a group to
derive from its records: :mod:`console.archive.derive`); this
package never derives anything itself, it only decides where a task
runs and gives the results back in task order, so the combined answer
cannot depend on the engine or the number of workers.

Nothing here writes to the archive.  The ingest tasks write parts under fresh
names, which no reader sees until the caller publishes a manifest naming them
(:func:`console.archive.store.publish`): a worker killed mid-run leaves parts
no manifest names, which the next ingest removes, never half a result.
"""

from __future__ import annotations

from typing import Any

from console.fleet.options import EngineOpt, EngineSpec, FleetError, SchedulerOpt, WorkersOpt, engine_spec

_ENGINE_NAMES = frozenset({"engine_scope", "map_partitions", "run_with_engine"})


def __getattr__(name: str) -> Any:
    # The engine (Rich progress, the partition runner) loads when used, not when a command's options
    # are declared: every command's start-up would pay for it.
    if name in _ENGINE_NAMES:
        from console.fleet import engine

        return getattr(engine, name)
    raise AttributeError(f"module 'console.fleet' has no attribute {name!r}")


__all__ = [
    "EngineOpt",
    "EngineSpec",
    "FleetError",
    "SchedulerOpt",
    "WorkersOpt",
    "engine_scope",
    "engine_spec",
    "map_partitions",
    "run_with_engine",
]
