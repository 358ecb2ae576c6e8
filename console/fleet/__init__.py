"""The fleet: the archive's per-partition analysis run in-process or on a Dask cluster, with the same answer.

``--engine local`` (the default) runs every partition in this process;
``--engine dask`` ships the same partition function to a ``distributed``
cluster — a LocalCluster started and stopped here (``--workers N``) or an
existing scheduler (``--scheduler tcp://HOST:PORT``).  The partitions are the
archive's own unit of work (a device's records of one day, with the
neighbouring days it needs, see :mod:`console.archive.partition`); this
package never derives anything itself, it only decides where a partition
runs and gives the results back in partition order, so the combined answer
cannot depend on the engine or the number of workers.

Nothing here writes to the archive: results come back to the caller, which
publishes them through the archive's manifest (:func:`console.archive.store.publish`),
so a worker killed mid-run can never leave half a result behind.
"""

from console.fleet.engine import engine_scope, fleet_mapper, map_partitions, run_with_engine
from console.fleet.options import EngineOpt, EngineSpec, FleetError, SchedulerOpt, WorkersOpt, engine_spec

__all__ = [
    "EngineOpt",
    "EngineSpec",
    "FleetError",
    "SchedulerOpt",
    "WorkersOpt",
    "engine_scope",
    "engine_spec",
    "fleet_mapper",
    "map_partitions",
    "run_with_engine",
]
