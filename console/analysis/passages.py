"""Passages: a train's run over one counting head.

Records are first reduced, chunk by chunk, to *activity buckets*: one row
per (head, channel, second, file) with the record count and the first and
last record time.  A day of logging is at most 86,400 buckets per head and
channel whatever the record rate, so memory stays bounded on long logs.

Overlapping exports: when several files hold records for the same head,
channel and second, that bucket is taken from the file with the most records
there and the others' records are counted as overlap, not twice (the
paper's excerpts repeat the line 09:32:24 Adr 018 in two excerpts).

A passage is a maximal run of a head's buckets in which no gap between
consecutive records exceeds ``idle_gap_s``.  Because bucket boundaries are
whole seconds, splitting buckets is exact for any idle gap of 1 s or more.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

NS = 1_000_000_000
BUCKET_COLUMNS = ("head", "channel", "second", "file", "records", "t_first_ns", "t_last_ns")


def chunk_buckets(head: np.ndarray, channel: np.ndarray, time_ns: np.ndarray, file_id: int) -> pd.DataFrame:
    """Run-length reduce one chunk's records to activity buckets.

    Records arrive mostly in time order, so consecutive records share a
    bucket; runs of equal keys collapse in O(n) without sorting.  The same
    bucket may still appear in several runs; :func:`merge_buckets` sums them.
    """
    n = len(time_ns)
    if n == 0:
        return pd.DataFrame({c: pd.Series(dtype=np.int64) for c in BUCKET_COLUMNS})
    second = time_ns // NS
    change = np.empty(n, bool)
    change[0] = True
    change[1:] = (head[1:] != head[:-1]) | (channel[1:] != channel[:-1]) | (second[1:] != second[:-1])
    starts = np.flatnonzero(change)
    counts = np.diff(np.append(starts, n))
    return pd.DataFrame(
        {
            "head": head[starts].astype(np.int64),
            "channel": channel[starts].astype(np.int64),
            "second": second[starts],
            "file": np.full(len(starts), file_id, np.int64),
            "records": counts.astype(np.int64),
            "t_first_ns": np.minimum.reduceat(time_ns, starts),
            "t_last_ns": np.maximum.reduceat(time_ns, starts),
        }
    )


def merge_buckets(parts: list[pd.DataFrame]) -> tuple[pd.DataFrame, int]:
    """Sum runs into buckets and resolve overlapping files.

    Returns (buckets with one file per head/channel/second, overlap records
    ignored).
    """
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=np.int64) for c in BUCKET_COLUMNS}), 0
    runs = pd.concat(parts, ignore_index=True)
    per_file = (
        runs.groupby(["head", "channel", "second", "file"], sort=False)
        .agg(records=("records", "sum"), t_first_ns=("t_first_ns", "min"), t_last_ns=("t_last_ns", "max"))
        .reset_index()
    )
    total = int(per_file["records"].sum())
    best = per_file.sort_values(["records", "file"], ascending=[False, True], kind="stable").drop_duplicates(
        ["head", "channel", "second"], keep="first"
    )
    best = best.sort_values(["head", "second", "channel"], kind="stable").reset_index(drop=True)
    return best, total - int(best["records"].sum())


def split_passages(buckets: pd.DataFrame, idle_gap_s: float) -> pd.DataFrame:
    """Assign a passage number to every bucket (column ``passage``).

    Also returns per passage: head, start/end (ns), records.
    """
    if idle_gap_s < 1:
        raise ValueError("idle gap must be at least 1 s (buckets are whole seconds)")
    if buckets.empty:
        out = buckets.copy()
        out["passage"] = pd.Series(dtype=np.int64)
        return out
    per_second = (
        buckets.groupby(["head", "second"], sort=True)
        .agg(t_first_ns=("t_first_ns", "min"), t_last_ns=("t_last_ns", "max"))
        .reset_index()
    )
    head = per_second["head"].to_numpy()
    first = per_second["t_first_ns"].to_numpy()
    last = per_second["t_last_ns"].to_numpy()
    new = np.ones(len(per_second), bool)
    new[1:] = (head[1:] != head[:-1]) | (first[1:] - last[:-1] > int(idle_gap_s * NS))
    per_second["passage"] = np.cumsum(new) - 1
    return buckets.merge(per_second[["head", "second", "passage"]], on=["head", "second"], how="left")
