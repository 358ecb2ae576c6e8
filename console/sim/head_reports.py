"""The counting heads: the coil edges the wheels cross (and the truth's wheel passages at each head's
centre), the records faults add or take away, and the heads' status records (heartbeats)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from console.analysis.counting.wheels import SYS1, SYS2
from console.layout import Layout
from console.sim.faults import Fault
from console.sim.line_values import SimTrain, WheelRecord
from parsers.units import NS

DETECTION_ZONE_M = 0.25  # a wheel damps a coil over this length of travel


def coil_edges(
    head_m: float,
    spacing_m: float,
    sys1_first_up: bool,
    axles_m: np.ndarray,
    direction: int,
    x0: float,
    x1: float,
    t0: float,
    t1: float,
    zone_m: float = DETECTION_ZONE_M,
) -> list[tuple[float, int, int]]:
    """(time s, channel, 1 onset / 0 release) of every coil edge the wheels cross while the
    head of the train moves from x0 to x1 between t0 and t1 (linear inside the step).

    Sys1 sits on the side an up train reaches first when the head is "Sys1 first up"; a
    wheel damps a coil while within ``zone_m / 2`` of it.
    """
    half = spacing_m / 2
    c1 = head_m - half if sys1_first_up else head_m + half
    coils = ((SYS1, c1), (SYS2, 2 * head_m - c1))
    d = direction
    p0, p1 = x0 - d * axles_m, x1 - d * axles_m
    out = []
    for ch, c in coils:
        for edge, value in ((c - d * zone_m / 2, 1), (c + d * zone_m / 2, 0)):
            crossed = (d * (p0 - edge) < 0) & (d * (p1 - edge) >= 0)
            for k in np.flatnonzero(crossed):
                frac = (edge - p0[k]) / (p1[k] - p0[k])
                out.append((t0 + frac * (t1 - t0), ch, value))
    return out


def wheel_edges(
    layout: Layout, start_ns: int, tr: SimTrain, x0: float, x1: float, t0: float, t1: float, v0: float
) -> tuple[list[WheelRecord], list[tuple[str, int, float, float]]]:
    """Onsets and releases of every coil the train's wheels passed in this step, and the truth's
    passages of a wheel over a head's centre: (head, axle, time s, speed m/s), in the order they are found."""
    out: list[WheelRecord] = []
    passages: list[tuple[str, int, float, float]] = []
    if x1 == x0:
        return out, passages
    axles = np.asarray(tr.consist.axles_m)
    d = tr.direction
    # The wheels run from the head back to the tail, behind the direction of travel.
    ends = (x0, x1, x0 - d * tr.consist.length_m, x1 - d * tr.consist.length_m)
    lo, hi = min(ends) - 1, max(ends) + 1
    for head in layout.heads:
        if not lo <= head.chainage_m <= hi:
            continue
        for t, ch, value in coil_edges(
            head.chainage_m, head.spacing_m, head.up_is_first_channel_first, axles, d, x0, x1, t0, t1
        ):
            out.append(WheelRecord(start_ns + int(t * NS), head.id, ch, value))
        # The truth: each wheel passing the head's centre.
        p0, p1 = x0 - d * axles, x1 - d * axles
        passed = (d * (p0 - head.chainage_m) < 0) & (d * (p1 - head.chainage_m) >= 0)
        for k in np.flatnonzero(passed):
            frac = (head.chainage_m - p0[k]) / (p1[k] - p0[k])
            axle = tr.axle_offset + int(k)
            passages.append((head.id, axle, t0 + frac * (t1 - t0), v0 + (tr.v_mps - v0) * frac))
    return out, passages


def fault_records(faults: Sequence[Fault], start_ns: int, t0: float, t1: float) -> list[WheelRecord]:
    """Records that faults add in the step from t0 to t1: isolated pulses and damped heads."""
    out = []
    for f in faults:
        if f.kind == "isolated_pulse" and t0 <= f.start_s < t1:
            t = start_ns + int(f.start_s * NS)
            out += [WheelRecord(t, f.target, f.channel, 1), WheelRecord(t + NS // 5, f.target, f.channel, 0)]
        elif f.kind == "damped_head":
            if t0 <= f.start_s < t1:
                out.append(WheelRecord(start_ns + int(f.start_s * NS), f.target, f.channel, 1))
            if t0 <= f.end_s < t1:
                out.append(WheelRecord(start_ns + int(f.end_s * NS), f.target, f.channel, 0))
    return out


def reported_records(
    records: list[WheelRecord],
    faults: Sequence[Fault],
    start_ns: int,
    swallowed: set[tuple[str, int]],
    rng: np.random.Generator,
) -> list[WheelRecord]:
    """What the heads report, after dead channels, power loss and missed detections.

    A damping whose onset a fault swallowed loses its release too (even in
    a later step): a head never reports freeing a coil it never reported
    damped.  ``swallowed``: the (head, channel) pairs whose onset a fault removed, carried from step
    to step (updated here); ``rng``: the missed detections' draws.
    """
    keep = []
    for r in sorted(records, key=lambda r: r.t_ns):
        key = (r.head, r.channel)
        if r.value == 0 and key in swallowed:
            swallowed.discard(key)
            continue
        t_s = (r.t_ns - start_ns) / NS
        drop = False
        for f in faults:
            if f.target != r.head or not f.active(t_s):
                continue
            if f.kind == "power_loss" or (f.kind == "dead_channel" and f.channel == r.channel):
                drop = True
            elif f.kind == "missed_detections" and f.channel == r.channel and r.value == 1:
                drop = bool(rng.random() < f.probability)
        if drop and r.value == 1:
            swallowed.add(key)
        elif not drop:
            keep.append(r)
    return keep


def heartbeats_until(
    layout: Layout, faults: Sequence[Fault], start_ns: int, next_s: float, period_s: float, t1: float
) -> tuple[list[tuple[int, str]], float]:
    """Each powered head's status records from ``next_s`` up to ``t1`` (a head without power writes none),
    every ``period_s``; and the time of the next round."""
    beats = []
    while next_s <= t1:
        t = next_s
        for h in layout.heads:
            dark = any(f.kind == "power_loss" and f.target == h.id and f.active(t) for f in faults)
            if not dark:
                beats.append((start_ns + int(t * NS), h.id))
        next_s += period_s
    return beats, next_s
