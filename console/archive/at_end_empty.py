"""Whether an ingest's at-end tables are known to be empty without reading the archive back.

:func:`console.archive.history.at_end_tables` reads the health registers' records of the whole archive
(a column of every records part), the stored channel events, frames, voltages and GNSS fixes, and runs the
report's health, frame and crossing steps over them; on a log of wheel and diagnosis registers alone, on no
layout, all of that finds nothing, and it costs the ingest's end the read-back and the report's imports
(pandas among them: a tenth of a plain ingest's CPU).  Each input of those steps is checked here instead,
from what the derivation holds already; any doubt answers False and the tables are computed as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from console.engine.pipeline import HEALTH_REGISTERS

if TYPE_CHECKING:
    from console.archive.store import Manifest
    from parsers.diag.registry import DiagRegistry

# The archive's tables the at-end steps read besides the records: the channel events health judges, the
# sensor frames (text and CAN), the voltage tables and the GNSS fixes.
AT_END_INPUTS = ("channel_events", "frames", "voltages", "fixes")


def at_end_is_empty(manifest: Manifest, layout_spec: str | None, registry: DiagRegistry | None) -> bool:
    """True when :func:`~console.archive.history.at_end_tables` would give no table at all.

    ``registry``: the local engine's pipeline's, which numbered every record the archive holds (its state is
    carried between ingests, and made again from all the records when the derivation is); None (the Dask
    engine's groups, each with a registry of its own heads) answers False.

    * no layout, now or derived: no section, no crossing;
    * none of the other inputs stored: no channel event, frame, voltage or fix;
    * no register whose stored canonical label (its canonical label, else its label, as the records part
      stores it) is a health register: no record health judges.  Strings are only added to the registry,
      so a register of a dropped file still answers False.
    """
    if registry is None or layout_spec is not None or manifest.derived.get("layout") is not None:
        return False
    if any(manifest.parts(table) for table in AT_END_INPUTS):
        return False
    if any(str(e.get("kind")) != "diagnostic" for e in manifest.files):
        return False
    return not any(label in HEALTH_REGISTERS for label in registry.canonicals.values)
