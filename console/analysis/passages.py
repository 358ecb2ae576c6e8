"""Passages: a train's run over one counting head.

Records are first reduced, chunk by chunk, to *activity buckets*: one row
per (head, second, file) with the record count and the first and last record
time, overall and for Sys1 and Sys2.  A day of logging is at most 86,400
buckets per head whatever the record rate, so memory stays bounded on long
logs.

Overlapping exports: when several files hold records for the same head and
second, that second is taken from the file with the most records there and
the others' records are counted as overlap, not twice (the paper's excerpts
repeat the line 09:32:24 Adr 018 in two excerpts).

A passage is a maximal run of a head's buckets in which no gap between
consecutive records exceeds ``idle_gap_s``.  Because bucket boundaries are
whole seconds, splitting buckets is exact for any idle gap of 1 s or more.
"""

from __future__ import annotations

import numpy as np

from console.analysis.timefmt import NS

_BIG = np.iinfo(np.int64).max
_SMALL = np.iinfo(np.int64).min
_FIRST = ("t_first_ns", "t_first_sys1_ns", "t_first_sys2_ns")
_LAST = ("t_last_ns", "t_last_sys1_ns", "t_last_sys2_ns")
BUCKET_COLUMNS = ("head", "second", "file", "records", "records_sys1", "records_sys2", *_FIRST, *_LAST)


Columns = dict[str, np.ndarray]


def _empty() -> Columns:
    return {c: np.zeros(0, np.int64) for c in BUCKET_COLUMNS}


def chunk_buckets(head: np.ndarray, channel: np.ndarray, time_ns: np.ndarray, file_id: int) -> Columns:
    """Run-length reduce one chunk's records to activity buckets.

    Records arrive mostly in time order, so consecutive records share a
    bucket; runs of equal keys collapse in O(n) without sorting.  The same
    bucket may still appear in several runs; :func:`merge_buckets` combines
    them.  Missing per-system times are int64 max/min sentinels.
    """
    n = len(time_ns)
    if n == 0:
        return {c: np.zeros(0, np.int64) for c in BUCKET_COLUMNS}
    second = time_ns // NS
    change = np.empty(n, bool)
    change[0] = True
    change[1:] = (head[1:] != head[:-1]) | (second[1:] != second[:-1])
    starts = np.flatnonzero(change)
    counts = np.diff(np.append(starts, n))
    out = {
        "head": head[starts].astype(np.int64),
        "second": second[starts],
        "file": np.full(len(starts), file_id, np.int64),
        "records": counts.astype(np.int64),
        "t_first_ns": np.minimum.reduceat(time_ns, starts),
        "t_last_ns": np.maximum.reduceat(time_ns, starts),
    }
    for ch in (1, 2):
        on = channel == ch
        out[f"records_sys{ch}"] = np.add.reduceat(on.astype(np.int64), starts)
        out[f"t_first_sys{ch}_ns"] = np.minimum.reduceat(np.where(on, time_ns, _BIG), starts)
        out[f"t_last_sys{ch}_ns"] = np.maximum.reduceat(np.where(on, time_ns, _SMALL), starts)
    return out


def merge_buckets(parts: list[Columns]) -> tuple[Columns, int]:
    """Combine runs into buckets and resolve overlapping files.

    Returns (one bucket per head and second, sorted; overlap records ignored).
    """
    if not parts:
        return _empty(), 0
    cols = {c: np.concatenate([part[c] for part in parts]) for c in BUCKET_COLUMNS}
    # Runs of one (head, second, file) can repeat (chunk edges, interleaved
    # heads): sort by key, then reduce each group with ufunc.reduceat.
    order = np.lexsort((cols["file"], cols["second"], cols["head"]))
    cols = {c: v[order] for c, v in cols.items()}
    h, sec, f = cols["head"], cols["second"], cols["file"]
    new = np.ones(len(h), bool)
    new[1:] = (h[1:] != h[:-1]) | (sec[1:] != sec[:-1]) | (f[1:] != f[:-1])
    if not new.all():
        at = np.flatnonzero(new)
        reduce: dict[str, np.ufunc] = {c: np.add for c in ("records", "records_sys1", "records_sys2")}
        reduce.update({c: np.minimum for c in _FIRST})
        reduce.update({c: np.maximum for c in _LAST})
        cols = {c: (reduce[c].reduceat(v, at) if c in reduce else v[at]) for c, v in cols.items()}
    total = int(cols["records"].sum())
    h, sec, f = cols["head"], cols["second"], cols["file"]
    if len(f) and (f != f[0]).any():
        # Per head and second, the file with the most records (ties: the first file).
        order = np.lexsort((f, -cols["records"], sec, h))
        h, sec = h[order], sec[order]
        first = np.ones(len(h), bool)
        first[1:] = (h[1:] != h[:-1]) | (sec[1:] != sec[:-1])
        cols = {c: v[order][first] for c, v in cols.items()}
    return cols, total - int(cols["records"].sum())


def split_passages(buckets: Columns, idle_gap_s: float) -> Columns:
    """Add a ``passage`` number to buckets sorted by head and second."""
    if idle_gap_s < 1:
        raise ValueError("idle gap must be at least 1 s (buckets are whole seconds)")
    head = buckets["head"]
    first = buckets["t_first_ns"]
    last = buckets["t_last_ns"]
    new = np.ones(len(head), bool)
    new[1:] = (head[1:] != head[:-1]) | (first[1:] - last[:-1] > int(idle_gap_s * NS))
    return {**buckets, "passage": np.cumsum(new) - 1}


def bucket_index(buckets: Columns, head: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
    """Row of ``buckets`` holding each (head, time), or -1 (vectorized lookup)."""
    key = buckets["head"] * (1 << 40) + buckets["second"]
    probe = head.astype(np.int64) * (1 << 40) + time_ns // NS
    pos = np.searchsorted(key, probe)
    pos_ok = np.minimum(pos, max(len(key) - 1, 0))
    found = (pos < len(key)) & (key[pos_ok] == probe) if len(key) else np.zeros(len(probe), bool)
    return np.where(found, pos_ok, -1)
