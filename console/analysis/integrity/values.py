"""The integrity monitor's values: the states and witnesses' names, its settings, a train's consist,
the events it gives (:class:`IntegrityEvent`) and their per-train timelines (:func:`timelines`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from console.analysis.integrity.gnss import BEHIND, SLOWER, STRONG, GnssLimits
from console.analysis.timefmt import iso

WHOLE, DOUBTFUL, PARTED = "whole", "doubtful", "parted"
HEAD, EOT = "head", "eot"
GNSS = "gnss"
SEPARATION = (BEHIND, SLOWER, STRONG)
AROUND = 2  # head fixes each side of an EOT fix's time that bound the head there


@dataclass(frozen=True)
class IntegritySettings:
    noise_m: float = 5.0  # σ of a fix along the track (the receivers' figure)
    speed_noise_mps: float = 0.2  # σ of a reported (Doppler) speed
    k_sigma: float = 3.5  # allowances are this many σ (each fix: a difference of two gets twice)
    max_accel_mps2: float = 1.5  # no train changes speed faster, emergency braking included
    max_speed_mps: float = 45.0
    clock_offset_s: float = 0.2  # each unit's clock may be this far off
    coupling_slack_m: float = 5.0  # EOT mount beyond the last wheel, couplers' play
    report_period_s: float = 10.0  # the units' report period
    latency_s: float = 2.0  # radio and processing delay allowance
    stale_after_s: float = 30.0  # at least this long without a fix: the unit is stale
    counter_lag_s: float = 5.0  # axle events and section changes reach the monitor within this
    history_s: float = 240.0  # fixes and axle events kept
    emergency_hold_s: float = 30.0  # an emergency brake application is held at least this long

    @property
    def stale_s(self) -> float:
        """A unit is stale after several missed reports (never after one lost packet) and the latency."""
        return max(self.stale_after_s, 4 * self.report_period_s) + self.latency_s

    def gnss_limits(self) -> GnssLimits:
        return GnssLimits(
            self.noise_m,
            self.speed_noise_mps,
            self.k_sigma,
            self.max_accel_mps2,
            self.max_speed_mps,
            self.clock_offset_s,
            self.coupling_slack_m,
        )


@dataclass(frozen=True)
class ConsistSpec:
    """What the console knows of a train: its length and, where the layout or the simulator
    knows it, its axle count."""

    train: str
    length_m: float  # first to last wheel; the EOT rides on the last vehicle
    axles: int | None = None
    # False: the length is only the layout's guess; the monitor learns it from the first fixes
    # (head–EOT distance while running whole) and judges by speed alone until then.
    length_known: bool = True


@dataclass(frozen=True)
class IntegrityEvent:
    """A change of a train's integrity state, with the evidence for it."""

    t_ns: int
    train: str
    state: str  # whole | doubtful | parted
    previous: str | None  # None: the first state known
    witnesses: tuple[str, ...]  # gnss | axles | sections: who gave the evidence
    evidence: tuple[str, ...]
    rear_m: float | None = None  # the rear part's (EOT's) last chainage, when parted

    def to_dict(self) -> dict[str, Any]:
        return {
            "train": self.train,
            "state": self.state,
            "previous": self.previous,
            "witnesses": list(self.witnesses),
            "evidence": list(self.evidence),
            "rear_m": None if self.rear_m is None else round(self.rear_m, 1),
            "time_ns": self.t_ns,
            "time": iso(self.t_ns),
        }


def timelines(events: list[IntegrityEvent]) -> list[dict[str, Any]]:
    """Per train (in the order they were first judged): its last state and every change, with evidence.

    What ``crossing --json``, the report and the tables show."""
    per: dict[str, list[IntegrityEvent]] = {}
    for e in sorted(events, key=lambda e: e.t_ns):
        per.setdefault(e.train, []).append(e)
    return [
        {"train": train, "state": evs[-1].state, "changes": [e.to_dict() for e in evs]} for train, evs in per.items()
    ]
