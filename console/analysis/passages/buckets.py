"""Passages: a train's run over one counting head.

Records are first reduced, chunk by chunk, to *activity buckets*: one row
per (head, second) with the record count and the first and last record
time, overall and for Sys1 and Sys2.  A day of logging is at most 86,400
buckets per head whatever the record rate, so memory stays bounded on long
logs.

Several files are one log: buckets of the same head and second from several
files add up.  Records one file repeats from another (overlapping exports,
found record by record in :mod:`console.analysis.passages.overlap`) are taken out
again with :func:`remove_records`, so they count once.

A passage is a maximal run of a head's buckets in which no gap between
consecutive records exceeds ``idle_gap_s``.  Because bucket boundaries are
whole seconds, splitting buckets is exact for any idle gap of 1 s or more.
"""

from __future__ import annotations

import os
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from parsers.diag.records import DiagChunk
from parsers.units import NS

try:
    from console.analysis.passages import compiled_runs
except ImportError:  # built without a C compiler: the numpy path, which gives the same columns
    compiled_runs = None  # type: ignore[assignment]

# The sentinels of min/max reductions over no record ("no time yet").
INT64_MAX = np.iinfo(np.int64).max
INT64_MIN = np.iinfo(np.int64).min
_FIRST = ("t_first_ns", "t_first_sys1_ns", "t_first_sys2_ns")
_LAST = ("t_last_ns", "t_last_sys1_ns", "t_last_sys2_ns")
BUCKET_COLUMNS = ("head", "second", "records", "records_sys1", "records_sys2", "records_whole_second", *_FIRST, *_LAST)


Columns = dict[str, np.ndarray]


def _empty() -> Columns:
    return {c: np.zeros(0, np.int64) for c in BUCKET_COLUMNS}


def chunk_buckets(head: np.ndarray, channel: np.ndarray, time_ns: np.ndarray, subsecond: np.ndarray) -> Columns:
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
        "records": counts.astype(np.int64),
        # Records stamped to the whole second: their passage's times are only that exact.
        "records_whole_second": np.add.reduceat((~subsecond).astype(np.int64), starts),
        "t_first_ns": np.minimum.reduceat(time_ns, starts),
        "t_last_ns": np.maximum.reduceat(time_ns, starts),
    }
    for ch in (1, 2):
        on = channel == ch
        out[f"records_sys{ch}"] = np.add.reduceat(on.astype(np.int64), starts)
        out[f"t_first_sys{ch}_ns"] = np.minimum.reduceat(np.where(on, time_ns, INT64_MAX), starts)
        out[f"t_last_sys{ch}_ns"] = np.maximum.reduceat(np.where(on, time_ns, INT64_MIN), starts)
    return out


def _record_runs_numpy(
    chunk: DiagChunk, luts: RunTables, keep_releases: bool
) -> tuple[np.ndarray, Columns, np.ndarray]:
    """A chunk's head key per record (int64), its activity runs (:func:`chunk_buckets`), and the positions of
    its wheel-sensor records wanted: onsets (value 1), and releases (0) too with ``keep_releases``
    (:data:`record_runs`: this, or the compiled pass alike)."""
    rid, value = chunk.register_id, chunk.value
    head = luts.head[rid].astype(np.int64)
    channel = luts.channel[rid].astype(np.int64)
    runs = chunk_buckets(head, channel, chunk.time_ns, chunk.subsecond)
    wanted = (value == 1) | (value == 0) if keep_releases else value == 1
    return head, runs, np.flatnonzero(luts.is_wheel[rid] & wanted)


def _record_runs_compiled(
    chunk: DiagChunk, luts: RunTables, keep_releases: bool
) -> tuple[np.ndarray, Columns, np.ndarray]:
    """:func:`_record_runs_numpy`'s columns in two compiled passes without the GIL (``compiled_runs.c``)."""
    assert compiled_runs is not None
    c = chunk
    head, runs, n_runs, wheel = compiled_runs.chunk_runs(
        c.register_id, c.time_ns, c.subsecond, c.value, luts.head, luts.channel, luts.is_wheel, keep_releases
    )
    cols = np.frombuffer(runs, np.int64).reshape(len(BUCKET_COLUMNS), n_runs)
    return np.frombuffer(head, np.int64), dict(zip(BUCKET_COLUMNS, cols, strict=True)), np.frombuffer(wheel, np.int64)


class RunTables(Protocol):
    """Per register: its head key (int32), channel (int8), and whether it is a wheel sensor (bool)."""

    @property
    def head(self) -> np.ndarray: ...
    @property
    def channel(self) -> np.ndarray: ...
    @property
    def is_wheel(self) -> np.ndarray: ...


# The compiled pass where it was built (``pip install`` with a C compiler), unless TRACKSIDE_PURE=1 asks
# for the numpy path (the reference: tests/test_passages_compiled.py checks both alike).
_COMPILED = compiled_runs is not None and not os.environ.get("TRACKSIDE_PURE")
record_runs = _record_runs_compiled if _COMPILED else _record_runs_numpy


def compiled_record_runs() -> bool:
    """Whether records are reduced to runs by the compiled pass."""
    return record_runs is _record_runs_compiled


def merge_buckets(parts: list[Columns]) -> Columns:
    """Combine runs (of any chunk or file) into one bucket per head and second, sorted."""
    if not parts:
        return _empty()
    # Runs of one (head, second) can repeat (chunk edges, interleaved heads,
    # several files): sort by key, then combine each group.
    return _merge_runs(np.stack([np.concatenate([part[c] for part in parts]) for c in BUCKET_COLUMNS], dtype=np.int64))


def _by_head_and_second(head: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The order of ``np.lexsort((second, head))``: one stable sort of a key of both where they fit 63 bits."""
    if len(head) and int(head.min()) >= 0 and int(head.max()) < 1 << 30:
        s_min = int(second.min())
        if int(second.max()) - s_min < 1 << 33:
            return np.argsort((head << 33) | (second - s_min), kind="stable")
    return np.lexsort((second, head))


def _merge_runs_numpy(runs: np.ndarray) -> Columns:
    cols = dict(zip(BUCKET_COLUMNS, runs[:, _by_head_and_second(runs[0], runs[1])], strict=True))
    h, sec = cols["head"], cols["second"]
    new = np.ones(len(h), bool)
    new[1:] = (h[1:] != h[:-1]) | (sec[1:] != sec[:-1])
    if not new.all():
        at = np.flatnonzero(new)
        counts = ("records", "records_sys1", "records_sys2", "records_whole_second")
        reduce: dict[str, np.ufunc] = {c: np.add for c in counts}
        reduce.update({c: np.minimum for c in _FIRST})
        reduce.update({c: np.maximum for c in _LAST})
        cols = {c: (reduce[c].reduceat(v, at) if c in reduce else v[at]) for c, v in cols.items()}
    return cols


def _merge_runs_compiled(runs: np.ndarray) -> Columns:
    """:func:`_merge_runs_numpy`'s buckets, combined in one compiled pass without the GIL (``compiled_runs.c``)."""
    assert compiled_runs is not None
    n = runs.shape[1]
    m, merged = compiled_runs.merge_runs(_by_head_and_second(runs[0], runs[1]), runs)
    # Copied out when groups combined: the buckets are held between chunks, the runs' room is not.
    cols = np.frombuffer(merged, np.int64).reshape(len(BUCKET_COLUMNS), n)[:, :m]
    return dict(zip(BUCKET_COLUMNS, cols if m == n else cols.copy(), strict=True))


_merge_runs = _merge_runs_compiled if _COMPILED else _merge_runs_numpy


def _group_extremes_numpy(
    n: int, group: np.ndarray, values: np.ndarray, channel: np.ndarray, wanted: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per group 0…n-1, over the items on channel ``wanted``: how many, the least and the greatest value
    (int64 max and min where none).  (:data:`group_extremes`: this, or the compiled pass alike.)"""
    m = channel == wanted
    g, v = group[m], values[m]
    least = np.full(n, INT64_MAX, np.int64)
    np.minimum.at(least, g, v)
    greatest = np.full(n, INT64_MIN, np.int64)
    np.maximum.at(greatest, g, v)
    return np.bincount(g, minlength=n).astype(np.int64), least, greatest


def _group_extremes_compiled(
    n: int, group: np.ndarray, values: np.ndarray, channel: np.ndarray, wanted: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_group_extremes_numpy`'s figures in one compiled pass without the GIL (``compiled_runs.c``)."""
    assert compiled_runs is not None
    g, v, c = (np.ascontiguousarray(a, np.int64) for a in (group, values, channel))
    count, least, greatest = compiled_runs.group_extremes(n, g, v, c, wanted)
    return np.frombuffer(count, np.int64), np.frombuffer(least, np.int64), np.frombuffer(greatest, np.int64)


group_extremes = _group_extremes_compiled if _COMPILED else _group_extremes_numpy


def _squeeze_rows_numpy(rows: np.ndarray) -> tuple[bytes, np.ndarray]:
    """Rows of bytes (uint8, 2-D), each a text padded with 0 bytes: the texts without them, back to back, and
    each one's length.  (:data:`squeeze_rows`: this, or the compiled pass alike.)"""
    kept = rows != 0
    return rows[kept].tobytes(), np.count_nonzero(kept, axis=1).astype(np.int64)


def _squeeze_rows_compiled(rows: np.ndarray) -> tuple[bytes, np.ndarray]:
    """:func:`_squeeze_rows_numpy`'s text and lengths in one compiled pass without the GIL (``compiled_runs.c``)."""
    assert compiled_runs is not None
    if rows.size == 0:
        return b"", np.zeros(len(rows), np.int64)
    text, lengths = compiled_runs.squeeze_rows(np.ascontiguousarray(rows, np.uint8), rows.shape[1])
    return text, np.frombuffer(lengths, np.int64)


squeeze_rows = _squeeze_rows_compiled if _COMPILED else _squeeze_rows_numpy


def remove_records(buckets: Columns, head: np.ndarray, channel: np.ndarray, time_ns: np.ndarray) -> None:
    """Take records out of the bucket counts (in place).

    Only for records with an identical twin that stays (overlap): the
    bucket's first and last times are the twin's too, so they stand.
    """
    if len(head) == 0:
        return
    row = bucket_index(buckets, head, time_ns)
    found = row >= 0
    np.subtract.at(buckets["records"], row[found], 1)
    for ch in (1, 2):
        on = found & (channel == ch)
        np.subtract.at(buckets[f"records_sys{ch}"], row[on], 1)


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


def _bucket_index_numpy(buckets: Columns, head: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
    """Row of ``buckets`` (sorted by head and second) holding each (head, time), or -1 (vectorized lookup).
    (:data:`bucket_index`: this, or the compiled lookup alike.)"""
    key = buckets["head"] * (1 << 40) + buckets["second"]
    probe = head.astype(np.int64) * (1 << 40) + time_ns // NS
    pos = np.searchsorted(key, probe)
    pos_ok = np.minimum(pos, max(len(key) - 1, 0))
    found = (pos < len(key)) & (key[pos_ok] == probe) if len(key) else np.zeros(len(probe), bool)
    return np.where(found, pos_ok, -1)


def _bucket_index_compiled(buckets: Columns, head: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
    """:func:`_bucket_index_numpy`'s rows through a hash of the buckets' keys, without the GIL
    (``compiled_runs.c``): no search per item."""
    assert compiled_runs is not None
    rows = compiled_runs.bucket_rows(
        np.ascontiguousarray(buckets["head"], np.int64),
        np.ascontiguousarray(buckets["second"], np.int64),
        np.ascontiguousarray(head, np.int64),
        np.ascontiguousarray(time_ns, np.int64),
    )
    return np.frombuffer(rows, np.int64)[: len(head)]


bucket_index = _bucket_index_compiled if _COMPILED else _bucket_index_numpy


# Why a passage's axles cannot be counted ("–" in tables, ``axles_unknown_reason`` in JSON), by code: an axle
# is a Sys1 and a Sys2 onset of one wheel, so none can be paired where a system has no onset.  JSON keeps
# ``axles`` the number of pairs found (0), as version 1 documents always have.  Code: 2·(no Sys1) + (no Sys2).
AXLES_UNKNOWN_REASONS = (None, "wheel onsets on Sys1 only", "wheel onsets on Sys2 only", "no wheel onset")


def axles_unknown_codes(detections_sys1: ArrayLike, detections_sys2: ArrayLike) -> np.ndarray:
    """Per passage, 0 where its axles were counted, else the index of its reason in AXLES_UNKNOWN_REASONS."""
    no1 = np.asarray(detections_sys1, np.int64) == 0
    no2 = np.asarray(detections_sys2, np.int64) == 0
    return (2 * no1 + no2).astype(np.int8)
