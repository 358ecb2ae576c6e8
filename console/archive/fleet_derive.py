"""The archive's per-partition derivation on the current fleet engine (in-process or Dask).

:func:`derive_partitions` runs :func:`console.archive.partition.derive_partition`
— one device's records of one day, with the neighbouring days it needs
named in its :class:`~console.archive.partition.Carried` — for every
partition of a manifest through :func:`console.fleet.map_partitions`, and
combines the rows in partition order.  Each task reads the archive's
published parts and writes nothing, so the combined tables are the same on
every engine and every number of workers, and a worker killed mid-run costs
a retry, never a partial write.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from console.archive.partition import PartitionKey, carried_state, combine, derive_partition, partitions
from console.archive.store import Manifest

if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.diagnostics import SpeedSettings


def derive_partitions(
    root: Path,
    manifest: Manifest,
    settings: SpeedSettings | None = None,
    keys: Sequence[PartitionKey] | None = None,
    label: str = "derive",
) -> dict[str, pd.DataFrame]:
    """Passages, axles, wheel records and heads of ``keys`` (default: every partition), one table each.

    The neighbours a partition carries come from all the manifest's
    partitions, so a subset gives the same rows as the whole for its keys.
    """
    from console.archive.history import speed_settings
    from console.fleet import map_partitions

    every = partitions(manifest)
    carried = carried_state(every)
    chosen = every if keys is None else sorted(keys)
    missing = [k.name for k in chosen if k not in carried]
    if missing:
        raise ValueError(f"no records for partition {missing[0]}")
    s = settings if settings is not None else speed_settings(manifest)
    rows = map_partitions(
        derive_partition,
        [{"key": k, "carried": carried[k]} for k in chosen],
        common={"root": root, "manifest": manifest, "settings": s},
        label=label,
    )
    return combine(rows)
