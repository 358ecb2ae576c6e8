"""Wheel detections → axles, for one counting head's two systems.

A counting head has two receiver systems (Sys1 = channel 1, Sys2 = channel
2) a coil spacing apart.  In the diagnostic log a wheel shows as the
``Radsensor`` register (Adr 026) turning 1 on one channel and then on the
other; the ``Diagnose`` register (Adr 024) mirrors it as a status bit, so we
count onsets from Radsensor only and never count one wheel twice.

An axle is a Sys1 onset paired with the nearest Sys2 onset of the same head
within ``pair_window_s``.  The default window is the time a wheel needs to
cross the coil spacing at 1 km/h (0.13 m → 0.47 s; seed 002's "about half a
second"): a partner further away is not the same wheel.  The pairing is one
to one.  The order of the two onsets gives the direction.  An onset with no
partner (a single system damped, e.g. by a maintenance trolley's metal) is
not an axle; it is counted as an unpaired detection.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from console.analysis.speed import MPS_TO_KMH

WHEEL_SENSOR_ADDRESS = 26
SYS1, SYS2 = 1, 2
DIRECTION_12 = "sys1_to_sys2"
DIRECTION_21 = "sys2_to_sys1"
NS = 1_000_000_000


@dataclass(frozen=True)
class PairingSettings:
    spacing_m: float = 0.13
    # spacing / (1 km/h): a slower wheel is not a train wheel (seed 002).
    pair_window_s: float = 0.13 / (1 / 3.6)


def _nearest(t1: np.ndarray, t2: np.ndarray, window_ns: int) -> np.ndarray:
    """For each t1 (sorted), the index of the nearest t2 (sorted) within the window, else -1."""
    if len(t2) == 0:
        return np.full(len(t1), -1, np.int64)
    pos = np.searchsorted(t2, t1)
    right = np.minimum(pos, len(t2) - 1)
    left = np.maximum(pos - 1, 0)
    d_right = np.abs(t2[right] - t1)
    d_left = np.abs(t1 - t2[left])
    pick = np.where(d_left <= d_right, left, right)
    gap = np.minimum(d_left, d_right)
    return np.where(gap <= window_ns, pick, -1)


def pair_axles(onsets: Mapping[str, Any], settings: PairingSettings) -> tuple[pd.DataFrame, int]:
    """Pair Sys1 and Sys2 onsets into axles.

    ``onsets`` (a DataFrame or a dict of arrays) has columns ``head`` (int key), ``channel``, ``time_ns``,
    ``subsecond``.  Returns (axles, number of unpaired onsets); axles have
    ``head``, ``t_sys1_ns``, ``t_sys2_ns``, ``time_ns`` (the earlier onset),
    ``direction``, ``delay_s`` and ``speed_kmh`` (NaN unless both onsets
    carry sub-second times).
    """
    head = np.asarray(onsets["head"], np.int64)
    channel = np.asarray(onsets["channel"], np.int64)
    time_ns = np.asarray(onsets["time_ns"], np.int64)
    subsecond = np.asarray(onsets["subsecond"], bool)
    is1, is2 = channel == SYS1, channel == SYS2
    # Whole-second logs cannot resolve a sub-second delay: allow one second.
    coarse = not bool(subsecond[is1 | is2].all())
    window_ns = int(max(settings.pair_window_s, 1.0 if coarse else 0.0) * NS)

    idx1_all, idx2_all = [], []
    for h in np.unique(head):  # a handful of counting heads, not records
        i1 = np.flatnonzero(is1 & (head == h))
        i2 = np.flatnonzero(is2 & (head == h))
        i1 = i1[np.argsort(time_ns[i1], kind="stable")]
        i2 = i2[np.argsort(time_ns[i2], kind="stable")]
        j = _nearest(time_ns[i1], time_ns[i2], window_ns)
        ok = j >= 0
        a, b = i1[ok], i2[j[ok]]
        # One to one: a Sys2 onset claimed twice goes to the nearer Sys1 onset.
        # Nearest indices grow with t1, so a repeated claim is adjacent.
        if len(b) > 1 and bool((b[1:] == b[:-1]).any()):
            by_gap = np.argsort(np.abs(time_ns[b] - time_ns[a]), kind="stable")
            _, first = np.unique(b[by_gap], return_index=True)
            keep = np.sort(by_gap[first])
            a, b = a[keep], b[keep]
        idx1_all.append(a)
        idx2_all.append(b)
    a = np.concatenate(idx1_all) if idx1_all else np.zeros(0, np.int64)
    b = np.concatenate(idx2_all) if idx2_all else np.zeros(0, np.int64)
    t1, t2 = time_ns[a], time_ns[b]
    delay_s = (t2 - t1) / NS
    exact = subsecond[a] & subsecond[b]
    with np.errstate(divide="ignore"):
        speed = np.where(exact & (delay_s != 0), settings.spacing_m / np.abs(delay_s) * MPS_TO_KMH, np.nan)
    # Whole-second onsets in the same second say nothing about their order.
    known = exact | (t1 // NS != t2 // NS)
    direction = np.full(len(t1), None, dtype=object)
    direction[known & (t2 > t1)] = DIRECTION_12
    direction[known & (t2 < t1)] = DIRECTION_21
    axles = pd.DataFrame(
        {
            "head": head[a],
            "t_sys1_ns": t1,
            "t_sys2_ns": t2,
            "time_ns": np.minimum(t1, t2),
            "direction": direction,
            "delay_s": np.where(exact, delay_s, np.nan),
            "speed_kmh": speed,
        }
    )
    unpaired = int((is1 | is2).sum()) - 2 * len(a)
    return axles, unpaired
