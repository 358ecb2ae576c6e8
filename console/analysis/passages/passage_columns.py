"""One row per passage, as numpy columns: extent, detections, direction and the three speed methods
(the paper's per-second method, whole-train, per-axle mean), every figure vectorized over passages.
"""

from __future__ import annotations

import numpy as np

from console.analysis.counting.speed import MPS_TO_KMH
from console.analysis.counting.wheels import SYS1, SYS2
from console.analysis.passages.buckets import INT64_MAX, INT64_MIN, Columns, group_extremes
from console.analysis.passages.speed_settings import SpeedSettings
from parsers.units import NS

Arrays = dict[str, np.ndarray]
# The time resolution assumed for stamps with a fraction (the speed bounds).
SUBSECOND_RESOLUTION_S = 0.001


def _group_min(n: int, group: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = np.full(n, INT64_MAX, np.int64)
    np.minimum.at(out, group, values)
    return out


def _or_nan(values: np.ndarray, sentinel: int) -> np.ndarray:
    return np.where(values == sentinel, np.nan, values.astype(np.float64))


def passage_columns(
    buckets: Columns,
    onsets: Arrays,
    axles: Arrays,
    axle_bucket: np.ndarray,
    s: SpeedSettings,
    head_spacing_m: np.ndarray | None = None,
) -> Columns | None:
    """One row per passage, every figure vectorized over passages (no groupby per record).

    The columns of :data:`passage_frame.PASSAGE_COLUMNS`, except that the text columns are
    codes: ``head`` (into the head list), ``direction`` (into
    ``wheels.DIRECTIONS``, 3: mixed), ``whole_train_basis`` (into ``PASSAGE_BASES``)
    and ``kind`` (into ``PASSAGE_KINDS``); ``axle_speeds_kmh`` holds the per-axle
    speeds that ``axle_speeds_start``/``stop`` index.
    """
    if len(buckets["head"]) == 0:
        return None
    # Buckets are sorted by head and second, so a passage is a run of rows.
    passage = buckets["passage"]
    at = np.flatnonzero(np.r_[True, passage[1:] != passage[:-1]])
    n = len(at)

    def col(name: str) -> np.ndarray:
        return buckets[name]

    head = col("head")[at]
    spacing_m = head_spacing_m[head] if head_spacing_m is not None else s.spacing_m
    start_ns = np.minimum.reduceat(col("t_first_ns"), at)
    end_ns = np.maximum.reduceat(col("t_last_ns"), at)
    records = np.add.reduceat(col("records"), at)
    rec_first = {c: _or_nan(np.minimum.reduceat(col(f"t_first_sys{c}_ns"), at), INT64_MAX) for c in (SYS1, SYS2)}
    rec_last = {c: _or_nan(np.maximum.reduceat(col(f"t_last_sys{c}_ns"), at), INT64_MIN) for c in (SYS1, SYS2)}

    # Wheel onsets per passage and system.
    op, och, ot = onsets["passage"], onsets["channel"], onsets["time_ns"]
    det_n, det_first, det_last = {}, {}, {}
    for c in (SYS1, SYS2):
        det_n[c], least, greatest = group_extremes(n, op, ot, och, c)
        det_first[c] = _or_nan(least, INT64_MAX)
        det_last[c] = _or_nan(greatest, INT64_MIN)
    n_onsets = np.bincount(op, minlength=n)
    subsecond = (n_onsets > 0) & (np.bincount(op[~onsets["subsecond"]], minlength=n) == 0)

    # Axles belong to the passage of the bucket holding their earlier onset (``axle_bucket``: that row).
    ax_ok = axle_bucket >= 0
    ax_p = passage[axle_bucket[ax_ok]]
    ax_dir = axles["direction"][ax_ok]
    n_axles = np.bincount(ax_p, minlength=n)
    n12 = np.bincount(ax_p[ax_dir == 1], minlength=n)
    n21 = np.bincount(ax_p[ax_dir == 2], minlength=n)
    direction = np.zeros(n, np.int8)  # codes: see passage_frame.PASSAGE_DIRECTIONS
    direction[n12 > n21] = 1
    direction[n21 > n12] = 2
    direction[(n12 > 0) & (n12 == n21)] = 3
    # Per-axle speeds stay one array sorted by passage and time; each passage
    # holds [start, stop) into it.
    speed = axles["speed_kmh"][ax_ok]
    timed = ~np.isnan(speed)
    timed_p, timed_t, timed_v = ax_p[timed], axles["time_ns"][ax_ok][timed], speed[timed]
    # Axles come by head, each head's in time: the sort is mostly not needed (stable: the same order either way).
    if not bool(np.all((timed_p[1:] > timed_p[:-1]) | ((timed_p[1:] == timed_p[:-1]) & (timed_t[1:] >= timed_t[:-1])))):
        order = np.lexsort((timed_t, timed_p))
        timed_p, timed_v = timed_p[order], timed_v[order]
    n_timed = np.bincount(timed_p, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        axle_mean = np.bincount(timed_p, weights=timed_v, minlength=n) / n_timed

    # Paper's per-second method: records at the head in the first detection second.
    first_bucket = _group_min(n, op, onsets["bucket"])
    has = first_bucket != INT64_MAX
    fb = np.where(has, first_bucket, 0)
    detection_second_ns = np.where(has, col("second")[fb] * NS, np.nan)
    records_in_second = np.where(has, col("records")[fb], np.nan)

    # Whole-train: entering system's first record → leaving system's last.
    reverse = direction == 2
    both = (det_n[SYS1] > 0) & (det_n[SYS2] > 0)
    enter = np.where(reverse, 2, 1)
    leave = 3 - enter
    enter_first = np.where(
        both,
        np.where(enter == 1, det_first[SYS1], det_first[SYS2]),
        np.where(enter == 1, rec_first[SYS1], rec_first[SYS2]),
    )
    leave_last = np.where(
        both,
        np.where(leave == 2, det_last[SYS2], det_last[SYS1]),
        np.where(leave == 2, rec_last[SYS2], rec_last[SYS1]),
    )
    duration = (leave_last - enter_first) / NS
    with np.errstate(invalid="ignore", divide="ignore"):
        whole = np.where(duration > 0, (s.train_length_m + spacing_m) / duration * MPS_TO_KMH, np.nan)
    # A status dump with no wheel in it spans milliseconds: as a "train" it
    # would run at thousands of km/h.  No train is faster than max_speed_kmh.
    implausible = whole > s.max_speed_kmh
    whole = np.where(implausible, np.nan, whole)
    basis = np.where(both, 1, 2).astype(np.int8)
    basis[np.isnan(duration) | (duration <= 0) | implausible] = 0
    # Resolution: each stamp is the true time cut down to its resolution r, so
    # the true duration lies within (d - r, d + r) and the speed between
    # these bounds.  Sub-second stamps are taken as millisecond-exact (at
    # worst; microsecond logs are better).  No upper bound within one step.
    whole_second = (np.add.reduceat(col("records_whole_second"), at) > 0) | ((n_onsets > 0) & ~subsecond)
    resolution_s = np.where(whole_second, 1.0, SUBSECOND_RESOLUTION_S)
    measured = basis > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        length_m = s.train_length_m + spacing_m
        whole_min = np.where(measured, length_m / (duration + resolution_s) * MPS_TO_KMH, np.nan)
        whole_max = np.where(
            measured & (duration > resolution_s), length_m / (duration - resolution_s) * MPS_TO_KMH, np.nan
        )
    stop = np.cumsum(n_timed)
    return {
        "head": head,
        "start_ns": start_ns,
        "end_ns": end_ns,
        "duration_s": (end_ns - start_ns) / NS,
        "records": records,
        "detections_sys1": det_n[SYS1],
        "detections_sys2": det_n[SYS2],
        "axles": n_axles,
        "direction": direction,
        "detection_second_ns": detection_second_ns,
        "records_in_detection_second": records_in_second,
        "speed_kmh_per_second_method": spacing_m * records_in_second * MPS_TO_KMH,
        "speed_kmh_whole_train": whole,
        "speed_kmh_whole_train_min": whole_min,
        "speed_kmh_whole_train_max": whole_max,
        "whole_train_basis": basis,
        "whole_train_duration_s": duration,
        "axle_speeds_start": stop - n_timed,
        "axle_speeds_stop": stop,
        "speed_kmh_per_axle_mean": axle_mean,
        "subsecond": subsecond,
        "time_resolution_s": resolution_s,
        # A train: axles counted, or (the paper's whole-second excerpts) a
        # plausible Sys1→Sys2 span.  A damping: wheel-sensor onsets but no
        # axle (one system only: a trolley, metal).  Else a status dump.
        "kind": np.select([(n_axles > 0) | ~np.isnan(whole), n_onsets > 0], [0, 1], default=2).astype(np.int8),
        "axle_speeds_kmh": timed_v,
    }
