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

from dataclasses import dataclass

import numpy as np
import pandas as pd

from console.analysis.speed import MPS_TO_KMH

WHEEL_SENSOR_ADDRESS = 26
SYS1, SYS2 = 1, 2
DIRECTION_12 = "sys1_to_sys2"
DIRECTION_21 = "sys2_to_sys1"


@dataclass(frozen=True)
class PairingSettings:
    spacing_m: float = 0.13
    # spacing / (1 km/h): a slower wheel is not a train wheel (seed 002).
    pair_window_s: float = 0.13 / (1 / 3.6)


def pair_axles(onsets: pd.DataFrame, settings: PairingSettings) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Pair Sys1 and Sys2 onsets into axles.

    ``onsets`` has columns ``head`` (int key), ``channel``, ``time_ns``,
    ``subsecond``.  Returns (axles, unpaired): axles with ``head``,
    ``t_sys1_ns``, ``t_sys2_ns``, ``time_ns`` (the earlier onset),
    ``direction``, ``delay_s``, ``speed_kmh`` (NaN unless both onsets carry
    sub-second times); unpaired onsets as given.
    """
    s1 = onsets[onsets["channel"] == SYS1].sort_values("time_ns", kind="stable")
    s2 = onsets[onsets["channel"] == SYS2].sort_values("time_ns", kind="stable")
    empty_axles = pd.DataFrame(
        {
            "head": pd.Series(dtype=np.int64),
            "t_sys1_ns": pd.Series(dtype=np.int64),
            "t_sys2_ns": pd.Series(dtype=np.int64),
            "time_ns": pd.Series(dtype=np.int64),
            "direction": pd.Series(dtype=object),
            "delay_s": pd.Series(dtype=float),
            "speed_kmh": pd.Series(dtype=float),
        }
    )
    if s1.empty or s2.empty:
        return empty_axles, onsets
    # Whole-second logs cannot resolve a sub-second delay: allow one second.
    coarse = ~(s1["subsecond"].all() and s2["subsecond"].all())
    window_ns = int(max(settings.pair_window_s, 1.0 if coarse else 0.0) * 1e9)
    left = pd.DataFrame(
        {"head": s1["head"].to_numpy(), "t1": s1["time_ns"].to_numpy(), "sub1": s1["subsecond"].to_numpy()}
    )
    right = pd.DataFrame(
        {"head": s2["head"].to_numpy(), "t2": s2["time_ns"].to_numpy(), "sub2": s2["subsecond"].to_numpy()}
    )
    left["i1"] = np.arange(len(left))
    right["i2"] = np.arange(len(right))
    left["key"] = left["t1"]
    right["key"] = right["t2"]
    m = pd.merge_asof(left, right, on="key", by="head", direction="nearest", tolerance=window_ns)
    m = m.dropna(subset=["t2"])
    m["gap"] = (m["t2"] - m["t1"]).abs()
    # One to one: a Sys2 onset claimed twice goes to the nearer Sys1 onset.
    m = m.sort_values(["gap", "t1"], kind="stable").drop_duplicates("i2", keep="first").sort_values("t1")
    t1 = m["t1"].to_numpy(np.int64)
    t2 = m["t2"].to_numpy(np.int64)
    delay_s = (t2 - t1) / 1e9
    exact = m["sub1"].to_numpy(bool) & m["sub2"].to_numpy(bool)
    with np.errstate(divide="ignore"):
        speed = np.where(exact & (delay_s != 0), settings.spacing_m / np.abs(delay_s) * MPS_TO_KMH, np.nan)
    # Whole-second onsets in the same second say nothing about their order.
    known = exact | (t1 // 10**9 != t2 // 10**9)
    direction = np.full(len(t1), None, dtype=object)
    direction[known & (t2 > t1)] = DIRECTION_12
    direction[known & (t2 < t1)] = DIRECTION_21
    axles = pd.DataFrame(
        {
            "head": m["head"].to_numpy(np.int64),
            "t_sys1_ns": t1,
            "t_sys2_ns": t2,
            "time_ns": np.minimum(t1, t2),
            "direction": direction,
            "delay_s": np.where(exact, delay_s, np.nan),
            "speed_kmh": speed,
        }
    )
    free1 = np.ones(len(s1), bool)
    free1[m["i1"].to_numpy(np.int64)] = False
    free2 = np.ones(len(s2), bool)
    free2[m["i2"].to_numpy(np.int64)] = False
    unpaired = pd.concat([s1[free1], s2[free2]]).sort_values("time_ns", kind="stable")
    return axles, unpaired
