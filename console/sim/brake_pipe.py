"""The brake pipe of a simulated train: its pressure at the front (cab) and at the rear (EOT unit).

Charged at ``NOMINAL_BAR``; a service application lowers it in proportion
to the braking asked (a full service application, ``FULL_SERVICE_MPS2``,
by ``FULL_SERVICE_DROP_BAR``), slowly; an emergency application vents it
fast, and is held until the train stands and ``HOLD_S`` after it.  The cab
acts at the front; the rear follows after the pipe's length at
``WAVE_MPS`` and recharges more slowly than the front (the whole pipe is
fed from the cab).  A parting vents the rear part's pipe from the break:
the rear reading falls after the rear part's length at ``WAVE_MPS``; the
head part's pipe stays charged (the head part runs on under its ATO).

The EOT unit sends an emergency status at once when it sees its pipe venting
(falling faster than any service application lowers it)
(:func:`emergency_times`): ``ALARM_REPEATS`` transmissions ``ALARM_GAP_S``
apart, each on its own over the radio (a confirmed uplink retried).
"""

from __future__ import annotations

import numpy as np

NOMINAL_BAR = 5.0
FULL_SERVICE_DROP_BAR = 1.5  # a full service application leaves 3.5 bar
FULL_SERVICE_MPS2 = 1.0
EMERGENCY_MPS2 = 1.15  # braking harder than this is an emergency application
WAVE_MPS = 250.0  # a reduction's speed along the pipe
VENT_BAR_S = 5.0  # an emergency vents this fast
SERVICE_BAR_S = 0.5  # a service reduction
RECHARGE_FRONT_BAR_S = 1.0
RECHARGE_REAR_BAR_S = 0.2
HOLD_S = 30.0  # an emergency application is held this long after the train stands
SENSOR_NOISE_BAR = 0.02
RESOLUTION_BAR = 0.05  # the LoRa payload's (version 2)
ALARM_BAR = 2.5  # below this the pipe vents at the emergency rate (the cab's demand)
ALARM_FALL_BAR_S = 2.5  # the EOT unit's emergency: its pipe falling faster than this (service: 0.5 bar/s)
ALARM_REPEATS = 3
ALARM_GAP_S = 1.5


def cab_demand(t_s: np.ndarray, accel: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """The pressure the cab asks for at each time of a grid: service braking in proportion, an emergency
    (``accel`` ≤ -``EMERGENCY_MPS2``) 0 until the train stands and ``HOLD_S`` after it."""
    service = np.clip(-accel / FULL_SERVICE_MPS2, 0.0, 1.0)
    demand = NOMINAL_BAR - FULL_SERVICE_DROP_BAR * service
    emergency = accel <= -EMERGENCY_MPS2
    held = np.zeros(len(t_s), dtype=bool)
    k = 0
    n = len(t_s)
    while k < n:
        if not emergency[k]:
            k += 1
            continue
        j = k
        while j < n and (emergency[j] or speed[j] > 0.0):
            j += 1  # until the train stands
        stand = t_s[min(j, n - 1)]
        held[k:] |= t_s[k:] <= stand + HOLD_S
        k = max(j, k + 1)
    demand[held] = 0.0
    return demand


def follow(t_s: np.ndarray, target: np.ndarray, recharge_bar_s: float) -> np.ndarray:
    """The pressure at one end following its target: vents fast, reduces and recharges slowly."""
    out = np.empty(len(t_s))
    p = NOMINAL_BAR
    for k in range(len(t_s)):  # a rate limit per step: a few thousand steps a run
        dt = t_s[k] - t_s[k - 1] if k else 0.0
        want = target[k]
        if want < p:
            p = max(want, p - (VENT_BAR_S if want < ALARM_BAR else SERVICE_BAR_S) * dt)
        else:
            p = min(want, p + recharge_bar_s * dt)
        out[k] = p
    return out


def pipe(
    t_s: np.ndarray,
    accel: np.ndarray,
    speed: np.ndarray,
    length_m: float,
    parting_s: float | None = None,
    rear_part_m: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """(front, rear) pressure in bar on the grid ``t_s``."""
    demand = cab_demand(t_s, accel, speed)
    front = follow(t_s, demand, RECHARGE_FRONT_BAR_S)
    # Before the run the pipe was charged: a reduction made at its start reaches the rear after the
    # pipe's length like any other.
    rear_target = np.interp(t_s - length_m / WAVE_MPS, t_s, demand, left=NOMINAL_BAR)
    if parting_s is not None:
        rear_target[t_s >= parting_s + rear_part_m / WAVE_MPS] = 0.0
    return front, follow(t_s, rear_target, RECHARGE_REAR_BAR_S)


def reading(rng: np.random.Generator, bar: np.ndarray) -> np.ndarray:
    """What a unit's sensor reports: a little noise, the payload's resolution."""
    noisy = np.maximum(0.0, bar + rng.normal(0.0, SENSOR_NOISE_BAR, len(bar)))
    return np.round(noisy / RESOLUTION_BAR) * RESOLUTION_BAR


def emergency_times(t_s: np.ndarray, rear_bar: np.ndarray) -> np.ndarray:
    """When the EOT unit sees its pipe venting: falling faster than ``ALARM_FALL_BAR_S`` over one
    step of the grid (each vent once, not each step of it)."""
    rate = np.r_[0.0, -np.diff(rear_bar) / np.maximum(np.diff(t_s), 1e-9)]
    fast = rate > ALARM_FALL_BAR_S
    onsets = np.flatnonzero(fast & ~np.r_[False, fast[:-1]])
    return t_s[onsets]
