"""The crossing unit's values: the trains and fixes it is given, its settings, what it says (events) and
what it knew when it turned a warning on (onsets).  The rules that use them are in
:mod:`console.analysis.crossing.controller` and the modules it names; the ETA bound itself in
:mod:`console.analysis.crossing.arrival`."""

from __future__ import annotations

import math
from dataclasses import dataclass

from console.analysis.crossing.arrival import earliest_s

HEAD, EOT = "head", "eot"
TRAIN = "train"  # the head's motion from both units: the EOT a second witness, its fixes moved on by the length


@dataclass(frozen=True)
class TrainSpec:
    train: str
    length_m: float  # first to last wheel; the EOT rides on the last vehicle


@dataclass(frozen=True)
class Fix:
    """One position report as the crossing unit sees it."""

    t_ns: int  # when it is received and processed
    t_fix_ns: int  # when it was measured
    train: str
    role: str  # head | eot
    chainage_m: float
    speed_mps: float = math.nan
    direction_hint: int = 0  # +1 up, -1 down, 0 unknown (e.g. course against the track bearing)
    valid: bool = True


@dataclass(frozen=True)
class ControllerSettings:
    guard_distance_m: float = 300.0  # warn inside this, whatever the speed
    # The ETA is the *earliest* arrival: the train may accelerate at up to
    # this to the line speed.  A train standing within reach of the crossing
    # inside the warning time therefore keeps the road closed: nothing here
    # knows when it will leave (a departure signal would).
    accel_mps2: float = 0.5
    line_speed_mps: float = 25.0
    report_period_s: float = 10.0  # expected time between two fixes of a device
    latency_s: float = 2.0  # radio and processing delay allowance
    stale_after_s: float = 30.0  # no fix for this long: the device is stale
    max_speed_mps: float = 45.0  # no train runs faster (plausibility; the speed assumed when none is known)
    jump_accel_mps2: float = 1.5  # no train changes speed faster (a fix implying more is a position jump)
    speed_window_s: float = 45.0  # how far back the speed bound from positions looks
    noise_m: float = 15.0  # GNSS noise allowance in the plausibility check (≈ 3 σ)
    crossing_half_width_m: float = 5.0  # the road's half width along the track
    baseline_margin_s: float = 10.0  # the fixed-time method's safety margin
    # Lights flash first; the barriers come down this much later (road users clear
    # the crossing) and rise with the lights going out.
    barrier_delay_s: float = 8.0
    tick_s: float = 1.0  # the unit's clock: between fixes it looks again this often
    onset_margin_s: float = 1.0  # on this much beyond the warning time (the clock wakes at the instant due)
    # The estimate (crossing_estimate): speed σ of a reported (Doppler) speed; how fast the
    # acceleration may change (white jerk, m²/s⁵); bounds at estimate + k·σ.
    speed_sigma_mps: float = 0.2
    jerk_psd: float = 0.003
    k_sigma: float = 3.3
    settle_fixes: int = 2  # fixes in a row inside the filter's prediction before its estimate alone counts
    # The filter's update uses the noise each device's own fixes prove (σ at most noise_m / 3).
    adaptive_noise: bool = True
    # A warning is released only if, by the bound, the road stays open this long at least and
    # it would not come on again before the next fix is in (one report period and the latency):
    # no flicker.  (Waiting for the next fix *and* this long after it held a slow train's road
    # closed one report period longer, for no gain: the bound alone guarantees the open time.)
    release_hold_s: float = 10.0
    length_sigma_m: float = 5.0  # how well the train's length is known (the EOT as a witness of the head)


def earliest_arrival_s(distance_m: float, speed_mps: float, accel_mps2: float, max_speed_mps: float) -> float:
    """Shortest time to run ``distance_m`` from ``speed_mps``, accelerating up to ``max_speed_mps``."""
    return earliest_s(distance_m, speed_mps, accel_mps2, max(max_speed_mps, speed_mps))


@dataclass(frozen=True)
class CrossingEvent:
    t_ns: int
    crossing: str
    train: str
    kind: str  # on | off | alarm
    reason: str


# Why a warning came on earlier than the evidence alone required: the causes a timeline names.
NO_SPEED, SPARSE, STALE, JUMPS = "no speed", "sparse fixes", "stale units", "jumps"


@dataclass(frozen=True)
class Onset:
    """What the unit knew when it turned a warning on: the bound and its parts (s of ETA)."""

    t_ns: int
    eta_s: float  # the earliest arrival then, as the unit bounded it
    nominal_eta_s: float | None  # the same from the best estimate, without margins (None: no estimate)
    doubt_s: dict[str, float]  # how far each doubt brought the bound forward (ETA s)
