"""The faults the simulator injects on demand: their kinds and their one record, :class:`Fault`.

Kept apart from the station and the slow faults' growth, which both read them (a cut that leaves
the simulator's modules without an import circle)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from console.analysis.counting.wheels import SYS2

SLOW_FAULT_KINDS = ("analog_drift", "disturbance_growth", "gnss_decay")
FAULT_KINDS = (
    "dead_channel",
    "isolated_pulse",
    "damped_head",
    "power_loss",
    "missed_detections",
    "eot_loss",
    "head_loss",
    *SLOW_FAULT_KINDS,
    "train_parting",
)
TRAIN_FAULTS = ("eot_loss", "head_loss", "train_parting")  # their target is a train, the others' a head


@dataclass(frozen=True)
class Fault:
    """A fault on demand.  ``target``: a head id (sensor faults), a train id (GNSS unit losses,
    ``train_parting``: from ``start_s``, or the first moment after it the train runs, its rear half
    separates with the EOT unit and brakes to a stop) or a unit (``gnss_decay``: ``T3-eot``).  Slow faults
    (console.sim.slow_faults) grow at ``rate``."""

    kind: str
    target: str
    start_s: float
    end_s: float = math.inf
    channel: int = SYS2
    probability: float = 0.2  # missed_detections: the share of one system's wheels missed
    rate: float | None = None  # slow faults: growth per day (None: the kind's default)

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s
