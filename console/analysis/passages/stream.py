"""Passages as soon as they are whole: one engine for batch reads and live following.

A passage of a counting head ends where the head's records pause for more
than the idle gap.  Reading a log in chunks, a head's records up to such a
pause are *closed*: nothing read later can join them, so they are analysed
at once (by the batch analysis itself, :func:`part_analysis.analyse_parts`)
and dropped.  What stays in memory is, per head, the reductions of its
open run (activity buckets, wheel onsets) and a few numbers: memory grows
with the heads and the open passages, not with the log.

A head's run also closes once the clock of the file its records come from
(the latest record time read from that file) is more than the idle gap
plus :data:`ORDER_SLACK_S` past its last record (files followed live are
read at their own pace: one that runs ahead does not cut another's runs):
logs interleave boards whose clocks step differently, so a record
may come up to that slack after a later-stamped one of another board, but
never more.  Within one head records come in time order, so a pause inside
a head's own records closes the run before it at once.

A record that comes later than that (a log out of time order, e.g. two
exports concatenated the wrong way round) would have joined a passage
already closed: it is counted in :attr:`PassageStream.late_records`, and the
commands read such a file again, whole, or warn where they cannot.

A wheel, a whole-second group or a passage that straddles a chunk boundary
is simply still open when the next chunk comes: the reductions of both
chunks merge before the run is analysed, so the passages, axles and speeds
are those of a whole-file read (``tests/test_streaming_property.py``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from console.analysis.head_table import HeadTable, by_head_then_time
from console.analysis.passages.accumulator import DiagAccumulator
from console.analysis.passages.buckets import Columns, compiled_record_runs, compiled_runs, merge_buckets
from console.analysis.passages.part_analysis import PartAnalysis, analyse_parts
from console.analysis.passages.speed_settings import SpeedSettings
from parsers.diag.records import DiagChunk
from parsers.diag.registry import DiagRegistry
from parsers.units import ALL_TIME, NO_TIME, NS

ORDER_SLACK_S = 2.0
# Held reductions are merged into one part once there are this many (bounds list overhead).
_MERGE_PARTS = 16


def _grown(values: np.ndarray, n: int, fill: int) -> np.ndarray:
    """At least ``n`` entries; room for half as many again, so a log adding heads in every chunk
    does not copy every head's state per chunk (the spare entries hold ``fill``: nothing open)."""
    if len(values) >= n:
        return values
    grown = np.full(max(n, len(values) * 3 // 2), fill, np.int64)
    grown[: len(values)] = values
    return grown


@dataclass
class PassageStream:
    """Feed parsed chunks in read order; get each batch of closed passages back as :class:`PartAnalysis`."""

    registry: DiagRegistry
    settings: SpeedSettings
    keep_releases: bool = False
    order_slack_s: float = ORDER_SLACK_S
    # Per head key, its stamps' resolution over the whole log when known up front (see pair_axle_arrays).
    head_step_s: np.ndarray | None = None
    # Passages close after every this many chunks (1: every chunk, as a live source wants them).  A read of
    # files closes every few: the analysis of closed passages costs per call as much as per passage, and the
    # passages are the same whenever they close.
    close_every_chunks: int = 1
    # Closed passages analysed on a worker thread while the next chunks are read (numpy lets go of the GIL in
    # its larger loops): :meth:`add` and :meth:`finish` then return None, and the parts come back, in the
    # order they closed, from :meth:`closed_parts`.  For a read of files, which closes every few chunks.
    analyse_aside: bool = False
    unpaired_detections: int = 0
    passages_closed: int = 0
    # Records that came after their head's passage was closed, near enough to have joined it
    # (or earlier than it): the log is out of time order beyond the slack, and the passages
    # around them are not those of a whole read.  Counted, so a face can say so.
    late_records: int = 0
    clock_ns: int = NO_TIME
    acc: DiagAccumulator = field(init=False)
    # Per file id, its latest record; per head key, the file its latest records came from.
    _file_clock: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _head_file: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _open_first: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _open_last: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _cut: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _closed_upto: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _slot: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))  # head_spans' scratch
    _chunks_since_close: int = 0
    _runs_since_close: int = 0
    _analysing: deque[Future[PartAnalysis]] = field(default_factory=deque)
    _analyst: ThreadPoolExecutor | None = None
    _head_spacing_m: np.ndarray | None = None  # per head key, when the heads' spacings differ

    def __post_init__(self) -> None:
        # One read of one log: no other file to overlap (see jobs.analyze_files).
        self.acc = DiagAccumulator(self.registry, keep_releases=self.keep_releases, track_overlap=False)
        self._gap_ns = int(self.settings.idle_gap_s * NS)
        self._slack_ns = int(self.order_slack_s * NS)

    @property
    def heads(self) -> HeadTable:
        return self.acc._lookup().heads

    def open_first_ns(self) -> int:
        """The earliest record time of any open run (int64 max: none open)."""
        open_ = self._open_last != NO_TIME
        return int(self._open_first[open_].min()) if open_.any() else ALL_TIME

    def open_firsts(self) -> np.ndarray:
        """Per head key, the first record of its open run (NO_TIME: none open)."""
        n = len(self._open_last)
        return np.where(self._open_last != NO_TIME, self._open_first[:n], NO_TIME)

    def lagging_clock_ns(self) -> int:
        """The clock to release events by: the log's latest record, but no later than the clock of any file
        a head is open in (followed files are read at their own pace: one that runs ahead must not release
        events the other's records still to come would precede)."""
        open_ = np.flatnonzero(self._open_last[: len(self._head_file)] != NO_TIME)
        if not len(open_):
            return self.clock_ns
        return min(self.clock_ns, int(self._file_clock[self._head_file[open_]].min()))

    def add(self, chunk: DiagChunk) -> PartAnalysis | None:
        """Take in a chunk; the passages it completed, if any."""
        if len(chunk) == 0:
            return None
        heads = self.acc.add(chunk)
        tables = self.acc._lookup()
        n = len(tables.head_device)
        self._open_first = _grown(self._open_first, n, NO_TIME)
        self._open_last = _grown(self._open_last, n, NO_TIME)
        self._cut = _grown(self._cut, n, NO_TIME)
        self._closed_upto = _grown(self._closed_upto, n, NO_TIME)
        self._head_file = _grown(self._head_file, len(self._open_last), 0)
        self._file_clock = _grown(self._file_clock, chunk.file_id + 1, NO_TIME)
        self._file_clock[chunk.file_id] = max(int(self._file_clock[chunk.file_id]), int(chunk.time_ns.max()))
        self._head_file[heads] = chunk.file_id
        self.late_records += int(np.count_nonzero(chunk.time_ns <= self._closed_upto[heads] + self._gap_ns))
        self._advance(heads, chunk.time_ns)
        self._chunks_since_close += 1
        self._runs_since_close += len(self.acc._buckets[-1]["head"])
        if self._chunks_since_close < self.close_every_chunks and self._runs_since_close < _DEFERRED_RUNS_MAX:
            return None
        return self._close(final=False)

    def complete_until(self, t_ns: int) -> PartAnalysis | None:
        """No record still to come is earlier than ``t_ns`` (a source that says so: the simulated heads):
        every file's clock runs to there, and the runs idle by then close; the passages that completed."""
        if not len(self._file_clock) or t_ns <= self.clock_ns:
            return None
        self.clock_ns = t_ns
        np.maximum(self._file_clock, t_ns, out=self._file_clock)
        return self._close(final=False)

    def finish(self) -> PartAnalysis | None:
        """End of input: every open run is whole."""
        return self._close(final=True)

    def _advance(self, heads: np.ndarray, t: np.ndarray) -> None:
        """Move each head's open run over the chunk's records, all heads at once."""
        self.clock_ns = max(self.clock_ns, int(t.max()))
        if len(self._slot) < len(self._open_last):
            self._slot = np.full(len(self._open_last), -1, np.int32)
        h, first, last, before, after = head_spans(heads, t, self._gap_ns, self._slot)
        prev = self._open_last[h]
        # The chunk's first record is more than the gap after the open run: that run is whole.
        broke = (prev != NO_TIME) & (first - prev > self._gap_ns)
        self._cut[h[broke]] = np.maximum(self._cut[h[broke]], prev[broke])
        new_run = (prev == NO_TIME) | broke
        self._open_first[h[new_run]] = first[new_run]
        # A pause inside the chunk's records of a head: everything up to the last pause is whole.
        inner = before != NO_PAUSE
        self._cut[h[inner]] = np.maximum(self._cut[h[inner]], before[inner])
        self._open_first[h[inner]] = after[inner]
        self._open_last[h] = np.where(prev == NO_TIME, last, np.maximum(prev, last))

    def _close(self, final: bool) -> PartAnalysis | None:
        self._chunks_since_close = self._runs_since_close = 0
        # Per head state is updated in place, and temporaries are only the heads closing (a log
        # may have a million heads and close a few hundred per chunk).
        idle = self._open_last != NO_TIME
        if not final:
            clock = self._file_clock[self._head_file[: len(idle)]]
            idle &= self._open_last < clock - self._gap_ns - self._slack_ns
        closing = np.flatnonzero(idle | (self._cut != NO_TIME))
        if not len(closing):
            return None
        upto = np.where(idle[closing], self._open_last[closing], self._cut[closing])
        self._closed_upto[closing] = np.maximum(self._closed_upto[closing], upto)
        self._cut[idle] = ALL_TIME
        self._open_last[idle] = NO_TIME
        buckets, self.acc._buckets = _split(self.acc._buckets, self._cut, "t_first_ns")
        detections, self.acc._detections = _split(self.acc._detections, self._cut, "time_ns")
        self._cut[closing] = NO_TIME
        if len(self.acc._buckets) > _MERGE_PARTS:
            self.acc._buckets = [merge_buckets(self.acc._buckets)]
        if len(self.acc._detections) > _MERGE_PARTS:
            held = self.acc._detections
            self.acc._detections = [{c: np.concatenate([d[c] for d in held]) for c in held[0]}]
        if not buckets:
            return None
        analysis = partial(
            _analyse_closed,
            buckets,
            detections,
            self.settings,
            self.keep_releases,
            head_step_s=self.head_step_s,
            head_spacing_m=self._spacing_by_head(),
        )
        if not self.analyse_aside:
            return self._counted(analysis())
        if self._analyst is None:
            self._analyst = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trackside-close")
        self._analysing.append(self._analyst.submit(analysis))
        return None

    def _spacing_by_head(self) -> np.ndarray | None:
        """Per head key, its spacing (None: one for all), made again only when heads have been added."""
        if not self.settings.head_spacing_m:
            return None
        heads = self.heads
        if self._head_spacing_m is None or len(self._head_spacing_m) != len(heads):
            self._head_spacing_m = self.settings.spacing_by_head(heads)
        return self._head_spacing_m

    def closed_parts(self, wait: bool = False) -> Iterator[PartAnalysis]:
        """The parts analysed aside, in the order they closed: those done (``wait``: all, and the worker
        stops; after :meth:`finish`)."""
        while self._analysing and (wait or self._analysing[0].done()):
            yield self._counted(self._analysing.popleft().result())
        if wait and self._analyst is not None:
            self._analyst.shutdown()
            self._analyst = None

    def _counted(self, part: PartAnalysis) -> PartAnalysis:
        self.unpaired_detections += part.unpaired
        self.passages_closed += len(part.passages["head"]) if part.passages is not None else 0
        return part


def _analyse_closed(
    buckets: list[Columns],
    detections: list[Columns],
    settings: SpeedSettings,
    keep_releases: bool,
    head_step_s: np.ndarray | None,
    head_spacing_m: np.ndarray | None = None,
) -> PartAnalysis:
    """The passages of closed runs: their chunks' buckets merged (on the worker, when analysed aside: the merge's
    sort lets go of the GIL), then analysed."""
    return analyse_parts(
        merge_buckets(buckets),
        detections,
        settings,
        keep_releases,
        head_step_s=head_step_s,
        head_spacing_m=head_spacing_m,
    )


# The activity runs a deferred close holds at most: a log whose every record opens a run (a million heads)
# closes after each chunk, as its memory wants (1 M heads: 463 MB closing each chunk, 610 MB every fourth).
_DEFERRED_RUNS_MAX = 20_000
NO_PAUSE = np.iinfo(np.int64).min  # head_spans: no pause longer than the gap among a head's records


def _head_spans_numpy(
    heads: np.ndarray, t: np.ndarray, gap_ns: int, slot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per head key of a chunk's records (each head's in time order or not): the key, its first and last
    record time, and around its last pause longer than ``gap_ns`` the times before and after it
    (:data:`NO_PAUSE`: none).  ``slot``: int32 scratch, one per head key, all -1 (left so).
    (:data:`head_spans`: this, or the compiled pass alike, which lists the heads as they first appear.)"""
    _, hs, ts = by_head_then_time(heads, t)
    starts = np.flatnonzero(np.r_[True, hs[1:] != hs[:-1]])
    ends = np.r_[starts[1:], len(hs)] - 1
    pause = np.r_[(np.diff(ts) > gap_ns) & (hs[1:] == hs[:-1]), False]
    at = np.maximum.reduceat(np.where(pause, np.arange(len(ts)), -1), starts)
    inner = at >= 0
    before = np.where(inner, ts[at], NO_PAUSE)
    after = np.where(inner, ts[np.minimum(at + 1, len(ts) - 1)], NO_PAUSE)
    return hs[starts], ts[starts], ts[ends], before, after


def _head_spans_compiled(
    heads: np.ndarray, t: np.ndarray, gap_ns: int, slot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_head_spans_numpy`'s figures in one compiled pass without the GIL (``compiled_runs.c``), heads in
    order of first appearance; the numpy sort where a head's times go back."""
    assert compiled_runs is not None
    out = compiled_runs.head_spans(heads, t, gap_ns, slot)
    if out is None:
        return _head_spans_numpy(heads, t, gap_ns, slot)
    m, *cols = out
    h, first, last, before, after = (np.frombuffer(c, np.int64)[:m] for c in cols)
    return h, first, last, before, after


# The compiled pass where it was built, unless TRACKSIDE_PURE=1 asks for numpy (tests/test_passages_compiled.py).
head_spans = _head_spans_compiled if compiled_record_runs() else _head_spans_numpy


def _split(parts: list[Columns], cut: np.ndarray, time_column: str) -> tuple[list[Columns], list[Columns]]:
    """Each part's rows at or before their head's cut time, and the rest (read order kept)."""
    closed, kept = [], []
    for p in parts:
        mask = p[time_column] <= cut[p["head"]]
        if mask.all():
            closed.append(p)
        elif not mask.any():
            kept.append(p)
        else:
            closed.append({c: v[mask] for c, v in p.items()})
            kept.append({c: v[~mask] for c, v in p.items()})
    return closed, kept


# -- passage columns: concatenating batches, taking rows ----------------------------------


def take_passages(cols: Columns, rows: np.ndarray) -> Columns:
    """The passages at ``rows`` (in that order), their per-axle speeds re-indexed."""
    start, stop = cols["axle_speeds_start"][rows], cols["axle_speeds_stop"][rows]
    count = stop - start
    new_stop = np.cumsum(count)
    new_start = new_stop - count
    speeds = cols["axle_speeds_kmh"][
        np.repeat(start - new_start, count) + np.arange(int(new_stop[-1]) if len(rows) else 0)
    ]
    out = {c: v[rows] for c, v in cols.items() if c != "axle_speeds_kmh"}
    out.update(axle_speeds_start=new_start, axle_speeds_stop=new_stop, axle_speeds_kmh=speeds)
    return out


def concat_passages(parts: list[Columns]) -> Columns | None:
    """Batches of passage columns as one table (per-axle speed indices shifted)."""
    if not parts:
        return None
    offsets = np.cumsum([0] + [len(p["axle_speeds_kmh"]) for p in parts[:-1]])
    out: Columns = {}
    for c in parts[0]:
        if c in ("axle_speeds_start", "axle_speeds_stop"):
            out[c] = np.concatenate([p[c] + off for p, off in zip(parts, offsets, strict=True)])
        else:
            out[c] = np.concatenate([p[c] for p in parts])
    return out


def by_head_and_start(cols: Columns) -> np.ndarray:
    """Row order of a whole-file read: by head key, then start time."""
    return np.lexsort((cols["start_ns"], cols["head"]))


def by_start(cols: Columns) -> np.ndarray:
    """Row order of a stream: by start time, then head key."""
    return np.lexsort((cols["head"], cols["start_ns"]))
