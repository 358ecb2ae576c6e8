"""Whole passages' reductions (merged buckets, wheel detections) → their passages, axles and unpaired onsets."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from console.analysis.counting.wheels import PairingSettings, pair_onsets
from console.analysis.passages.buckets import INT64_MAX, Columns, bucket_index, split_passages
from console.analysis.passages.passage_columns import Arrays, passage_columns
from console.analysis.passages.speed_settings import SpeedSettings


@dataclass
class PartAnalysis:
    """Passages, axles and unpaired onsets of a set of whole passages' reductions."""

    passages: Columns | None
    axles: Columns
    unpaired: int
    wheel: Columns | None = None
    activity: Columns | None = None


def analyse_parts(
    buckets: Columns,
    detections: list[dict[str, np.ndarray]],
    settings: SpeedSettings,
    keep_releases: bool = False,
    repeated: np.ndarray | None = None,
    head_step_s: np.ndarray | None = None,
    head_spacing_m: np.ndarray | None = None,
) -> PartAnalysis:
    """Merged buckets and wheel detections of whole passages → their passages and axles.

    The batch analysis calls it once for the whole log; the streaming one
    (:mod:`console.analysis.passages.stream`) once per batch of closed passages.
    """
    buckets = split_passages(buckets, settings.idle_gap_s)
    wheel = _wheel_records(detections, buckets, repeated)
    # Without releases every wheel record is an onset: no copy needed.
    onsets = {c: v[wheel["value"] == 1] for c, v in wheel.items()} if keep_releases else wheel
    pairing = PairingSettings(settings.spacing_m, settings.pair_window_s)
    axles, n_unpaired, first_onset = pair_onsets(onsets, pairing, head_step_s, head_spacing_m)
    return PartAnalysis(
        passages=passage_columns(buckets, onsets, axles, onsets["bucket"][first_onset], settings, head_spacing_m),
        axles=axles,
        unpaired=n_unpaired,
        wheel={c: wheel[c] for c in ("head", "channel", "time_ns", "value", "subsecond")} if keep_releases else None,
        activity={c: buckets[c] for c in ("head", "t_first_ns", "t_last_ns")} if keep_releases else None,
    )


def _wheel_records(parts: list[Arrays], buckets: Columns, repeated: np.ndarray | None) -> Arrays:
    """Wheel-sensor records in read order, less those repeated from another file,
    with their bucket row and passage."""
    names = ("head", "channel", "time_ns", "value", "subsecond", "file")
    if not parts:
        empty = {c: np.zeros(0, bool if c == "subsecond" else np.int64) for c in names}
        empty["value"] = np.zeros(0, np.int8)
        return {**empty, "bucket": np.zeros(0, np.int64), "passage": np.zeros(0, np.int64)}
    cols = {c: np.concatenate([part[c] for part in parts]) for c in names}
    row = bucket_index(buckets, cols["head"], cols["time_ns"])
    keep = row >= 0
    if repeated is not None:
        keep &= ~repeated[np.concatenate([part["record"] for part in parts])]
    if keep.all():  # nothing to drop: no copy
        cols["bucket"] = row
    else:
        cols = {c: v[keep] for c, v in cols.items()}
        cols["bucket"] = row[keep]
    if len(parts) > 1 and (cols["file"] != cols["file"][0]).any():
        order = _merged_order(cols["head"], cols["file"], cols["time_ns"])
        cols = {c: v[order] for c, v in cols.items()}
    cols["passage"] = buckets["passage"][cols["bucket"]]
    return cols


def _merged_order(head: np.ndarray, file: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
    """Read order → one log's order: by time; equal times by file, each file in its own order.

    Equal whole-second stamps from two files meet at a seam (a pull that
    ends mid-second, the next that begins there): per head, the file whose
    records begin earlier holds the earlier part of that second, whatever
    order the files were given in; where both begin in the same second (the
    head's first passage at the seam), the one that ends earlier (the earlier
    pull, its copy of the seam set aside as overlap).
    """
    key = head * (int(file.max()) + 1) + file
    groups, inverse = np.unique(key, return_inverse=True)
    first = np.full(len(groups), INT64_MAX, np.int64)
    np.minimum.at(first, inverse, time_ns)
    last = np.full(len(groups), -INT64_MAX, np.int64)
    np.maximum.at(last, inverse, time_ns)
    g_head = groups // (int(file.max()) + 1)
    g_order = np.lexsort((groups, last, first, g_head))  # per head: by first time, last time, then file
    rank = np.empty(len(groups), np.int64)
    rank[g_order] = np.arange(len(groups))
    return np.lexsort((np.arange(len(time_ns)), rank[inverse], time_ns))
