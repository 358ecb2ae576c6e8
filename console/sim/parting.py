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
The brake pipe's pressure, step by step, is here too: a parting is what
vents it, and the EOT unit's emergency status follows from the venting.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from console.analysis.crossing.values import EOT, HEAD
from console.analysis.timefmt import iso
from console.layout import Consist
from console.sim import brake_pipe as bp
from console.sim.dynamics import LEVEL_LINE, TrainModel, TrainState, scaled_train, step
from console.sim.faults import Fault
from console.sim.line_values import SimTrain
from parsers.units import NS


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


def part_train(
    tr: SimTrain, t_s: float, faults: Sequence[Fault], start_ns: int
) -> tuple[SimTrain, PartingTruth] | None:
    """Part ``tr`` now if a ``train_parting`` fault says so (it parts while running, under pull): the rear
    part, a train of its own, and the truth of the parting; ``tr`` keeps the front part.  None: no parting."""
    if not any(f.kind == "train_parting" and f.target == tr.id and f.start_s <= t_s for f in faults):
        return None
    k = split_axles(tr.consist)
    front, rear_consist = part_consist(tr.consist, k)
    rear_front_m = tr.x_m - tr.direction * tr.consist.axles_m[k]
    rear = SimTrain(
        tr.id,
        rear_consist,
        tr.direction,
        rear_front_m,
        tr.v_mps,
        t_s,
        controller="parted",
        units=(EOT,),
        axle_offset=k,
        next_eot_fix_s=tr.next_eot_fix_s,
        pipe_bar=tr.pipe_bar,
        # The hoses part: the rear part's pipe vents from the break, the wave reaching its EOT unit
        # after the rear part's length.
        vent_from_s=t_s + rear_consist.length_m / bp.WAVE_MPS,
    )
    tr.consist, tr.units, tr.rear = front, (HEAD,), rear
    truth = PartingTruth(tr.id, start_ns + round(t_s * NS), tr.v_mps, tr.x_m, k, len(rear_consist.axles_m))
    return rear, truth


def brake_pipe_step(tr: SimTrain, accel_mps2: float, t1: float, dt_s: float) -> None:
    """The train's brake pipe after a step: lowered for service braking, vented from ``vent_from_s``;
    the EOT unit, seeing it vent, queues its emergency status (sent at once, repeated)."""
    before = tr.pipe_bar
    if tr.vent_from_s is not None and t1 >= tr.vent_from_s:
        tr.pipe_bar = max(0.0, before - bp.VENT_BAR_S * dt_s)
    else:
        service = min(1.0, max(0.0, -accel_mps2 / bp.FULL_SERVICE_MPS2))
        want = bp.NOMINAL_BAR - bp.FULL_SERVICE_DROP_BAR * service
        rate = bp.SERVICE_BAR_S if want < before else bp.RECHARGE_FRONT_BAR_S
        tr.pipe_bar = max(want, before - rate * dt_s) if want < before else min(want, before + rate * dt_s)
    seen = dt_s > 0 and (before - tr.pipe_bar) / dt_s > bp.ALARM_FALL_BAR_S
    if seen and EOT in tr.units and not tr.alarms_s and tr.vent_from_s is not None:
        tr.alarms_s = [t1 + k * bp.ALARM_GAP_S for k in range(bp.ALARM_REPEATS)]
