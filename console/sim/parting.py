"""A train parting: the rear part, with the EOT unit, separates and brakes to a stop.

When a coupling breaks, the brake pipe parts with it and vents: the rear
part's brakes apply in full and it stops on its own, while the head part
runs on until its driver learns of it (here: it runs on as planned; the
console must see the parting from what the units and counters report).

The rear part is simulated as a train of its own on the force model
(:mod:`console.sim.dynamics`): the seed-001 train scaled to the rear part's
length (:func:`console.sim.dynamics.scaled_train`), full braking command,
level track.  Where a train parts: between the front and the rear half of
its axles (for the shipped consists, the coupling between two cars).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

from console.analysis.timefmt import iso
from console.layout import Consist
from console.sim.dynamics import LEVEL_LINE, TrainModel, TrainState, scaled_train, step


@dataclass
class PartingTruth:
    """What really happened: when the train parted, the rear part's axles, where it stopped."""

    train: str
    t_parting_ns: int
    speed_mps: float  # at the parting
    head_m: float  # the head's chainage at the parting
    rear_first_axle: int  # in the whole consist's numbering (0 = the first axle)
    rear_axles: int
    t_rear_stopped_ns: int | None = None
    rear_stop_front_m: float | None = None  # the rear part's first axle where it stopped
    rear_stop_tail_m: float | None = None  # its last axle (the EOT unit) where it stopped

    def to_dict(self) -> dict[str, Any]:
        def m(x: float | None) -> float | None:
            return None if x is None else round(x, 2)

        return {
            "train": self.train,
            "time": iso(self.t_parting_ns),
            "speed_mps": round(self.speed_mps, 3),
            "head_m": m(self.head_m),
            "rear_first_axle": self.rear_first_axle,
            "rear_axles": self.rear_axles,
            "rear_stopped": iso(self.t_rear_stopped_ns),
            "rear_stop_front_m": m(self.rear_stop_front_m),
            "rear_stop_tail_m": m(self.rear_stop_tail_m),
        }


def split_axles(consist: Consist) -> int:
    """The index of the rear part's first axle: the rear half of the axles."""
    return max(1, len(consist.axles_m) // 2)


def part_consist(consist: Consist, k: int) -> tuple[Consist, Consist]:
    """(front part, rear part) of a consist parted before axle ``k``; each measured from its first wheel."""
    front = consist.axles_m[:k]
    rear = consist.axles_m[k:]
    base = rear[0]
    return (
        Consist(f"{consist.id}/front", front[-1], front, consist.name),
        Consist(f"{consist.id}/rear", rear[-1] - base, tuple(a - base for a in rear), consist.name),
    )


def braking_step(consist: Consist, travelled_m: float, v_mps: float, dt_s: float) -> tuple[float, float]:
    """(distance run so far, speed) of a parted rear part after ``dt_s`` more of full braking."""
    state = step(_model(consist), LEVEL_LINE, TrainState(travelled_m, v_mps), -1.0, dt_s)
    return state.x_m, state.v_mps


@functools.cache
def _model(consist: Consist) -> TrainModel:
    # A rear part of one axle has no length; the model's mass scales with length.
    return scaled_train(max(consist.length_m, 1.0))
