"""Writing Parquet parts: LZ4, partitioned hive-style by day and device, bounded memory.

A :class:`PartWriter` takes Arrow tables for one archive table, splits them
by partition (one stable sort and one take per write-out, on the writer
thread; no loop per row), and appends each partition's rows to one open Parquet file: at most
one part per partition per ingest, rows appended across the parser's
chunks.  Memory is bounded by :data:`BUFFER_BYTES` (or the writer's ``buffer_bytes``) of buffered rows in all:
past it, every partition's rows are written out as a row group (so a
partition that gets a few rows per chunk cannot pin the chunks it came
from).  The buffered pieces share one dictionary per column
(:class:`_Dictionaries`), so a partition's pieces concatenate without
hashing.  Rows keep their order inside a partition unless ``sort_by`` asks
for another (records keep the input's: file and line, time order in an
exported log, so a row group spans a stretch of time and a query for one
hour skips the others by their statistics).  At most :data:`MAX_OPEN_WRITERS`
files are open; past it the least recently written one is closed and a
later row of its partition starts a second part (compaction merges them).
Every file written is listed in :attr:`PartWriter.written` (relative to the
archive) for the manifest; :func:`compact` merges a partition's small parts.

The write-outs (concatenate, sort, encode, compress, write) run on one
background thread (:func:`_writer_thread`), in the order they were asked for, while
the caller goes on parsing: Arrow and Parquet release the GIL, and on two
cores the ingest's reading and writing overlap.  A writer keeps at most
:data:`MAX_PENDING_WRITE_OUTS` write-outs queued, so memory stays bounded;
a part is fsynced on the thread when it is closed, so the publish finds it
already on disk.  A write-out's failure is raised by the writer's next call.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import re
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from console.archive import arrow_np
from console.archive.store import DATA, fsync_file, sync_paths
from parsers.units import NS_PER_DAY

ROW_GROUP_ROWS = 256_000
# Rows waiting to be written, all partitions together (Arrow bytes of the tables added since the last
# write-out): about a third of a second of parsing.  A write-out holds these rows and their copy in partition
# order while the next buffer fills, so the buffer sets much of an ingest's peak: a 12 M-record log of 40
# boards peaked at 276-287 MB at 16 MB and 249-255 MB at 10 MB (242-247 at 8), for about 6 % more CPU (more,
# smaller row groups; at 3 M records the same CPU within noise).
# Bigger buffers make bigger row groups, which compress better (3 M records, LZ4: records 8.9 MB at 16 MB,
# 10.1 MB at 10 MB, 10.6 MB at 8 MB).
BUFFER_BYTES = 10 << 20
MAX_OPEN_WRITERS = 128
IDLE_WRITE_OUTS = 3
# :meth:`PartWriter.advance` closes a day's files once the caller's time watermark is this far past the
# day's end: a log in time order has left the day (a passage still open at midnight is closed within
# minutes).  Until then a writer of derived rows (small buffers, a write-out every few hours of log) kept
# the last day's files open for hours into the next: 80 more open files, ~40 MB of peak RSS at 12 M records.
DAY_CLOSE_MARGIN_NS = 3600 * 10**9
_NO_DAY = 1 << 62
# LZ4 (LZ4_RAW): on a 3 M-record log it writes the parts with about 45 % less CPU than zstd level 6 (nearly what
# no compression costs), for parts 1.55x the size (10.2 MB against 6.5 MB: ~3.4 bytes a record, the dictionary
# and delta encodings do most of the work).  DuckDB's counts, group-bys and time filters on them took the same CPU;
# reading every column, 7-11 % more.  Parts written with zstd by an older trackside read the same (each file names
# its codec).
COMPRESSION = "lz4"
# Record columns no query filters on by range: no min/max statistics written for them.  A board reports every
# register in every stretch of its log, so each row group of a part holds every label: min and max of label and
# label_canonical were the same in all 480 row groups of a 3 M-record log (they never skip one), and for a
# dictionary column the writer finds them by a hash of each batch's codes (a tenth of writing the records).
# counting_head and device keep theirs: a part holds one board's heads, so a query for a head skips the others.
NO_STATISTICS = frozenset(
    {"type", "gs", "label", "label_canonical", "label_encoding", "data", "data_kind", "subsecond", "file"}
)
# Integer columns that grow steadily along a part (delta-coded); *_ns columns are times too.
DELTA_COLUMNS = frozenset({"line", "time_ns", "start_ns", "end_ns", "t_sys1_ns", "t_sys2_ns"})
# Rows the Parquet writer takes per step (Arrow's default is 1,024): each step of a dictionary column with
# statistics runs a hash and a take through Arrow's compute dispatch, so a record row group (~6,000 rows) took
# six.  Pages are cut by the writer's own limits (1 MB, 20,000 rows) either way: the files are byte-identical.
WRITE_BATCH_ROWS = 1 << 16
# Compaction merges a partition's parts while the merged part stays under this many rows
# (its rows are held in memory to be sorted: ~60 bytes a record row).
COMPACT_MAX_ROWS = 1_500_000
# Write-outs of one writer queued for the background thread, the one being written included: the caller
# waits past it (each holds up to BUFFER_BYTES of rows).
MAX_PENDING_WRITE_OUTS = 1
# One thread for every writer of the process (made again in a forked child, which has not got its parent's
# threads): write-outs run in the order they are asked for.
_WRITER: dict[int, ThreadPoolExecutor] = {}


def _writer_thread() -> ThreadPoolExecutor:
    pid = os.getpid()
    if pid not in _WRITER:
        _WRITER.clear()
        _WRITER[pid] = ThreadPoolExecutor(max_workers=1, thread_name_prefix="parquet-writer")
    return _WRITER[pid]


def day_text(day_index: int) -> str:
    return str(np.datetime64(int(day_index), "D"))


def encodings(schema: pa.Schema) -> dict[str, object]:
    """Parquet encodings by column: times and line numbers delta-coded, everything else dictionary-coded.

    Times and lines grow steadily (a delta is a few bits); register fields, values and small integers
    repeat (a dictionary code is a few bits; the writer falls back to plain when a dictionary grows
    too big).  On a realistic log this is a fifth smaller than delta-coding every integer, for the
    same writing time (docs/archive.md, Measured).
    """
    delta = [
        f.name
        for f in schema
        if pa.types.is_timestamp(f.type) or (pa.types.is_integer(f.type) and f.name in DELTA_COLUMNS)
    ]
    return {
        "use_dictionary": [f.name for f in schema if f.name not in delta],
        "column_encoding": dict.fromkeys(delta, "DELTA_BINARY_PACKED"),
        # Min/max per row group where a query filters (a fifth of the writing time for the others).
        "write_statistics": [f.name for f in schema if f.name not in NO_STATISTICS],
    }


def _writer(path: Path, schema: pa.Schema) -> pq.ParquetWriter:
    return pq.ParquetWriter(
        path,
        schema,
        compression=COMPRESSION,
        write_batch_size=WRITE_BATCH_ROWS,
        **encodings(schema),
    )


def _sort_keys(table: pa.Table, sort_by: Sequence[str]) -> list[np.ndarray]:
    """``sort_by``'s columns as integer arrays, primary key first (dictionary columns by their codes)."""
    keys = []
    for name in sort_by:
        col = table.column(name)
        if pa.types.is_dictionary(col.type):
            col = pa.chunked_array([c.indices for c in col.chunks], col.type.index_type)
        if pa.types.is_timestamp(col.type):
            col = col.cast(pa.int64())
        keys.append(arrow_np.to_numpy(col.fill_null(-1) if col.null_count else col))
    return keys


def _in_order(keys: list[np.ndarray]) -> bool:
    """Rows already in lexicographic order of ``keys`` (one pass, no sort): the usual case of input order."""
    undecided = np.ones(len(keys[0]) - 1, bool)  # pairs equal on every key so far
    for k in keys:
        a, b = k[:-1], k[1:]
        if (undecided & (a > b)).any():
            return False
        undecided &= a == b
    return True


def sorted_rows(table: pa.Table, sort_by: Sequence[str]) -> pa.Table:
    """``table`` in ``sort_by`` order (dictionary columns by their codes: grouped, not alphabetical)."""
    if not sort_by or table.num_rows < 2:
        return table
    keys = _sort_keys(table, sort_by)
    if _in_order(keys):
        return table
    order = np.lexsort(keys[::-1])  # np.lexsort: the last key is the primary one
    return table.take(arrow_np.array(order))


class _Dictionaries:
    """One dictionary per dictionary column, shared by every table buffered, so tables concatenate without a hash.

    The record encoder's dictionaries only grow (each chunk's is the registry's values so far): the
    longest one holds every earlier one as a prefix, and the earlier codes are valid in it.  A table
    whose dictionary is not such a prefix (another file's name) marks the buffer for unification.
    """

    def __init__(self) -> None:
        self.values: dict[str, pa.Array] = {}
        self.mixed = False

    def adopt(self, table: pa.Table) -> None:
        for i, f in enumerate(table.schema):
            if not pa.types.is_dictionary(f.type):
                continue
            col = table.column(i)
            for c in col.chunks:
                known = self.values.get(f.name)
                d = c.dictionary
                if known is None or (len(d) > len(known) and d.slice(0, len(known)).equals(known)):
                    self.values[f.name] = d
                elif not (len(d) <= len(known) and known.slice(0, len(d)).equals(d)):
                    self.mixed = True

    def concat(self, pieces: list[pa.Table]) -> pa.Table:
        """The pieces as one contiguous table, every dictionary column on the shared dictionary."""
        if self.mixed or len(pieces) < 2:
            table = pa.concat_tables(pieces)
            return table.unify_dictionaries().combine_chunks() if self.mixed else table.combine_chunks()
        schema = pieces[0].schema
        together = pa.concat_tables(pieces)  # zero-copy: one chunk per piece
        cols = []
        for i, f in enumerate(schema):
            col = together.column(i)
            if pa.types.is_dictionary(f.type) and f.name in self.values:
                indices = pa.concat_arrays([c.indices for c in col.chunks])
                # Every piece's codes index a prefix of the shared dictionary: no bounds check (a pass over the codes).
                cols.append(pa.DictionaryArray.from_arrays(indices, self.values[f.name], safe=False))
            else:
                cols.append(col.combine_chunks())
        return pa.Table.from_arrays(cols, schema=schema)

    def gather(self, pieces: list[pa.Table], order: np.ndarray | None) -> pa.Table:
        """The pieces' rows as one contiguous table, in ``order`` (row numbers; None: as they are), every
        dictionary column on the shared dictionary.  ``pieces`` is emptied: a column's buffers are let go
        as soon as it is gathered, so a write-out holds little more than one copy of its rows."""
        import pyarrow.compute as pc  # deferred: a query's start-up imports this module, not the writing

        if self.mixed or len(pieces) < 2:
            table = self.concat(pieces)
            pieces.clear()
            # ``order`` is a permutation of the rows: no bounds check (a pass over it per column).
            return table if order is None else pc.take(table, arrow_np.array(order), boundscheck=False)
        schema = pieces[0].schema
        columns: list[list[pa.Array] | None] = [
            [c for t in pieces for c in t.column(i).chunks] for i in range(len(schema))
        ]
        pieces.clear()
        taken = None if order is None else arrow_np.array(order)
        out = []
        for i, f in enumerate(schema):
            chunks, columns[i] = columns[i], None
            assert chunks is not None
            if pa.types.is_dictionary(f.type) and f.name in self.values:
                codes = pa.concat_arrays([c.indices for c in chunks])
                col = pa.DictionaryArray.from_arrays(codes, self.values[f.name], safe=False)  # valid, as in concat
            else:
                col = pa.concat_arrays(chunks)
            del chunks
            out.append(col if taken is None else pc.take(col, taken, boundscheck=False))
        return pa.Table.from_arrays(out, schema=schema)


def _in_sort_order(pieces: list[tuple[pa.Table, np.ndarray]], sort_by: Sequence[str]) -> bool:
    """The buffered rows, all together, in ``sort_by`` order already (the records in input order): then so is
    each partition's share, the split being stable, and no partition needs sorting.  One check of the whole
    buffer, where a check of each partition costs a few calls each."""
    if not sort_by or not pieces:
        return True
    together = pa.concat_tables([t for t, _ in pieces])  # zero-copy
    if any(pa.types.is_dictionary(together.schema.field(name).type) for name in sort_by):
        return False  # codes of different pieces' dictionaries do not compare: each partition is sorted
    keys = _sort_keys(together, sort_by)
    return len(keys[0]) < 2 or _in_order(keys)


def _stable_order(key: np.ndarray) -> np.ndarray:
    """``np.argsort(key, kind="stable")`` of partition keys (day << 32 | device): the same permutation, by the
    keys' ranks among the few (day, device) pairs when they fit 16 bits (numpy sorts those by radix, where it
    merges int64s: ~4 ms less per write-out of 230,000 records)."""
    day = key >> 32
    dev = key - (day << 32)  # 0 <= dev < 2**32: (day, dev) in lexicographic order is key order
    day -= day.min()
    dev -= dev.min()
    devices = int(dev.max()) + 1
    if (int(day.max()) + 1) * devices > 1 << 16:
        return np.argsort(key, kind="stable")
    return np.argsort((day * devices + dev).astype(np.uint16), kind="stable")


def _by_partition(pieces: list[tuple[pa.Table, np.ndarray]], dicts: _Dictionaries) -> list[tuple[int, pa.Table]]:
    """The buffered tables' rows by partition key, each partition's rows in the order they were added.

    Partitions come in the order of their first row's table, then by key (as a split of each table as it was
    added would order them); one stable sort and one take of the whole buffer, then zero-copy slices.
    """
    if not pieces:
        return []
    key = np.concatenate([k for _, k in pieces])
    sizes = [len(k) for _, k in pieces]
    tables = [t for t, _ in pieces]
    pieces.clear()  # the rows are let go column by column as they are gathered
    if (key == key[0]).all():  # one day, one board
        return [(int(key[0]), dicts.gather(tables, None))]
    order = _stable_order(key)
    table = dicts.gather(tables, order)
    sorted_key = key[order]
    piece = np.repeat(np.arange(len(sizes)), sizes)[order]
    cuts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1], True])
    starts, stops = cuts[:-1], cuts[1:]
    # A partition's first row is its earliest (the sort is stable): its table's place orders the partitions.
    firsts = np.lexsort((sorted_key[starts], piece[starts]))
    return [
        (int(sorted_key[a]), table.slice(a, b - a))
        for a, b in zip(starts[firsts].tolist(), stops[firsts].tolist(), strict=True)
    ]


def _days_over(watermark_ns: int) -> int:
    """The index of the first day whose files stay open at ``watermark_ns``."""
    return (int(watermark_ns) - DAY_CLOSE_MARGIN_NS) // NS_PER_DAY


class PartWriter:
    """Parquet parts of one table, one open file per partition, written as buffers fill."""

    def __init__(
        self,
        root: Path,
        table: str,
        generation: int,
        tag: str,
        *,
        by_device: bool = True,
        by_day: bool = True,
        sort_by: Sequence[str] = (),
        buffer_bytes: int | None = None,
        expand: Callable[[pa.Table, Any], pa.Table] | None = None,
    ) -> None:
        self.root = root
        self.buffer_bytes = buffer_bytes  # None: BUFFER_BYTES
        # Rows may be added in a compact form: ``expand(rows, payload)`` makes a partition's rows the stored
        # columns as they are written, with the payload of the last :meth:`add`'s ``context`` (records: their
        # registers' columns, a number per row in the buffer; more rows per buffer, so bigger row groups).
        self.expand = expand
        self._expanded_row_bytes = 80.0  # an expanded row's bytes, as last seen (the writer thread's)
        self._context: tuple[object, Any] | None = None
        self.table = table
        self.generation = generation
        self.tag = tag
        self.by_device = by_device
        self.by_day = by_day
        self.sort_by = tuple(sort_by)
        self.written: list[str] = []
        self.rows = 0
        self._writers: dict[tuple[int, int], pq.ParquetWriter] = {}  # insertion order = least recently written
        self._file_of: dict[tuple[int, int], str] = {}  # the part each open writer writes
        self._parts_of: dict[tuple[int, int], int] = {}
        # Tables added since the last write-out, each with its rows' partitions (day << 32 | device).
        self._pieces: list[tuple[pa.Table, np.ndarray]] = []
        self._dicts = _Dictionaries()
        self._pending_bytes = 0
        self._write_outs = 0
        self._last_write_out: dict[tuple[int, int], int] = {}
        self._pending_min_day = _NO_DAY  # the earliest day of the rows buffered (by_day writers)
        self._days_over = -_NO_DAY  # days before this one were closed by :meth:`advance`
        # Write-outs handed to the background thread, oldest first.  Only that thread touches the open
        # files, ``written`` and the counters above them until :meth:`_wait` says it is done.
        self._queued: deque[Future[None]] = deque()

    def _path(self, key: tuple[int, int]) -> str:
        parts = [DATA, self.table]
        if self.by_day:
            parts.append(f"day={day_text(key[0])}")
        if self.by_device:
            parts.append(f"device_id={key[1]}")
        n = self._parts_of.get(key, 0)
        self._parts_of[key] = n + 1
        parts.append(f"g{self.generation:06d}-{self.tag}{n or ''}.parquet")
        return os.path.join(*parts)

    def add(
        self,
        table: pa.Table,
        day_index: np.ndarray | None = None,
        device_id: np.ndarray | None = None,
        *,
        context: tuple[object, Any] | None = None,
    ) -> None:
        """Add rows; ``day_index`` (days since 1970) and ``device_id`` choose each row's partition.

        ``context`` (a writer with ``expand``): (group, payload); rows of one group are expanded with the
        payload of its latest rows (a registry's snapshot holds every register of the earlier ones), so rows
        of another group are written out first.

        The rows are only kept here: the split by partition is made for the whole buffer at its write-out, on
        the background thread (one concatenation, one stable sort and one take per write-out, not per table).
        """
        if table.num_rows == 0:
            return
        n = table.num_rows
        self.rows += n
        if self._pieces and not table.schema.equals(self._pieces[0][0].schema):
            self._write_out()  # another schema (a file with other columns): its rows in parts of their own
        if context is not None:
            if self._pieces and self._context is not None and self._context[0] is not context[0]:
                self._write_out()
            self._context = context
        self._dicts.adopt(table)
        days = day_index if self.by_day and day_index is not None else np.zeros(n, np.int64)
        devs = device_id if self.by_device and device_id is not None else np.zeros(n, np.int64)
        key = days.astype(np.int64) * (1 << 32) + devs.astype(np.int64)
        self._pending_bytes += table.nbytes
        if self.by_day and day_index is not None:
            self._pending_min_day = min(self._pending_min_day, int(days.min()))
        self._pieces.append((table, key))
        if self._pending_bytes > self._buffer():
            self._write_out()

    def _write_out(self) -> None:
        """Every partition's buffered rows as one row group of its file (in ``sort_by`` order).

        A file that got no rows in the last :data:`IDLE_WRITE_OUTS` write-outs is closed (a day that is
        over, in a log in time order): an open writer holds its buffers (~0.3 MB), and a long log would
        otherwise keep :data:`MAX_OPEN_WRITERS` of them.  A later row starts a second part (compacted).
        """
        pieces, self._pieces, self._pending_bytes = self._pieces, [], 0
        self._pending_min_day = _NO_DAY
        dicts, self._dicts = self._dicts, _Dictionaries()
        payload = None if self._context is None else self._context[1]
        self._submit(lambda: self._write_pieces(pieces, dicts, payload))

    def _write_pieces(
        self, pieces: list[tuple[pa.Table, np.ndarray]], dicts: _Dictionaries, payload: Any = None
    ) -> None:
        """One write-out (on the background thread)."""
        self._write_outs += 1
        in_order = _in_sort_order(pieces, self.sort_by)
        for k, rows in _by_partition(pieces, dicts):
            key = (k >> 32, k & 0xFFFFFFFF)
            rows = rows if in_order else sorted_rows(rows, self.sort_by)
            if self.expand is None:
                self._write(key, rows)
            else:
                self._write_expanded(key, rows, payload)
            self._last_write_out[key] = self._write_outs
        for key in [k for k in self._writers if self._last_write_out[k] <= self._write_outs - IDLE_WRITE_OUTS]:
            self._close_file(key)

    def _write_expanded(self, key: tuple[int, int], rows: pa.Table, payload: Any) -> None:
        """(On the background thread.)  Compact rows written as their stored columns, at most a quarter of the
        buffer's bytes of them expanded at a time (then a row group each).  A write-out of many boards' rows
        expands a few MB per partition; one of a single partition (a file per board and day) holds its compact
        rows, 1.7x as many as the buffer held expanded, while they are expanded: a quarter keeps that within
        4 MB of the buffer's full-width rows it held before, in row groups of ~50,000 rows."""
        assert self.expand is not None
        step = max(1024, int(self._buffer() / 4 / self._expanded_row_bytes))
        if rows.num_rows <= step:  # the usual case: no nbytes (a tenth of a ms a call, more than the expansion)
            self._write(key, self.expand(rows, payload))
            return
        for start in range(0, rows.num_rows, step):
            full = self.expand(rows.slice(start, step), payload)
            self._expanded_row_bytes = max(1.0, full.nbytes / max(1, full.num_rows))
            self._write(key, full)
            del full

    def _buffer(self) -> int:
        return BUFFER_BYTES if self.buffer_bytes is None else self.buffer_bytes

    def advance(self, watermark_ns: int) -> None:
        """The caller's rows have reached ``watermark_ns``: the files of days that ended more than
        :data:`DAY_CLOSE_MARGIN_NS` before it are closed (their buffered rows written first, so a log in time
        order keeps one part per partition).  A later row of a closed day starts a further part of it, as a
        file closed for :data:`MAX_OPEN_WRITERS` does; readers take every part the manifest lists."""
        if not self.closes_day(watermark_ns):
            return
        over = self._days_over = _days_over(watermark_ns)
        if self._pending_min_day < over:
            self._write_out()
        self._submit(lambda: self._close_days_before(over))

    def closes_day(self, watermark_ns: int) -> bool:
        """Whether :meth:`advance` to ``watermark_ns`` would close the files of a day not closed yet (a caller
        holding rows of its own writes them first, so that a log in time order keeps one part per partition)."""
        return self.by_day and _days_over(watermark_ns) > self._days_over

    def _close_days_before(self, day_index: int) -> None:
        """(On the background thread.)"""
        for key in [k for k in self._writers if k[0] < day_index]:
            self._close_file(key)

    def _submit(self, job: Callable[[], None]) -> None:
        """Queue ``job`` on the background thread, after waiting for the write-outs past the bound."""
        while len(self._queued) >= MAX_PENDING_WRITE_OUTS:
            self._queued.popleft().result()  # a failed write-out raises here
        self._queued.append(_writer_thread().submit(job))

    def _wait(self) -> None:
        """Every queued write-out done (the first failure raised, after all have run)."""
        failure: BaseException | None = None
        while self._queued:
            try:
                self._queued.popleft().result()
            except BaseException as exc:  # re-raised below, once the queue is empty
                failure = failure or exc
        if failure is not None:
            raise failure

    def _close_file(self, key: tuple[int, int]) -> None:
        """Close a part and fsync it (publish then finds its bytes on disk already)."""
        writer = self._writers.pop(key)
        writer.close()
        fsync_file(self.root / self._file_of[key])

    def _write(self, key: tuple[int, int], table: pa.Table) -> None:
        writer = self._writers.pop(key, None)
        if writer is None:
            if len(self._writers) >= MAX_OPEN_WRITERS:
                # Close the least recently written file; this partition's later rows go to a new part.
                self._close_file(next(iter(self._writers)))
            rel = self._path(key)
            path = self.root / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            writer = _writer(path, table.schema)
            self.written.append(rel)
            self._file_of[key] = rel
        elif not table.schema.equals(writer.schema):
            table = table.cast(writer.schema)
        self._writers[key] = writer  # now the most recently written
        writer.write_table(table, row_group_size=ROW_GROUP_ROWS)

    def close(self) -> list[str]:
        """Flush every buffer and close every file; the parts written (relative paths)."""
        self._write_out()
        self._submit(self._close_all)
        self._wait()
        return self.written

    def _close_all(self) -> None:
        """Every open part closed, then fsynced several at a time (at the end of a read, one after the other,
        they held up the ingest for a few ms each)."""
        keys = list(self._writers)
        for key in keys:
            self._writers.pop(key).close()
        sync_paths(self.root / self._file_of[key] for key in keys)

    def abort(self) -> None:
        with contextlib.suppress(BaseException):  # the parts are unlisted garbage anyway
            self._wait()
        for w in self._writers.values():
            with contextlib.suppress(Exception):
                w.close()
        self._writers.clear()
        self._pieces = []


def read_part(root: Path, rel: str) -> pa.Table:
    """One part's rows as written (no partition columns from its path)."""
    return pq.ParquetFile(root / rel).read()


def part_rows(root: Path, rel: str) -> int:
    return int(pq.ParquetFile(root / rel).metadata.num_rows)


def compact(root: Path, rels: Sequence[str], out_rel: str, sort_by: Sequence[str] = ()) -> str:
    """Merge parts of one partition into ``out_rel`` (a fresh name), rows in ``sort_by`` order."""
    tables = [read_part(root, rel) for rel in rels]
    schema = tables[-1].schema
    table = pa.concat_tables([t if t.schema.equals(schema) else t.cast(schema) for t in tables])
    del tables
    table = sorted_rows(table.unify_dictionaries().combine_chunks(), sort_by)
    return write_part(root, out_rel, table)


def write_part(root: Path, rel: str, table: pa.Table) -> str:
    """One whole part at ``rel`` (a fresh name), with the archive's encodings."""
    writer = _writer(root / rel, table.schema)
    try:
        writer.write_table(table, row_group_size=ROW_GROUP_ROWS)
    finally:
        writer.close()
    return rel


def write_small(root: Path, table_name: str, generation: int, tag: str, table: pa.Table) -> str | None:
    """One unpartitioned part (ledger tables, findings): the relative path, or None when empty."""
    if table.num_rows == 0:
        return None
    w = PartWriter(root, table_name, generation, tag, by_device=False, by_day=False)
    w.add(table)
    written = w.close()
    return written[0] if written else None


_KEY_IN_PATH = re.compile(r"day=(\d{4}-\d{2}-\d{2})/device_id=(-?\d+)/")


def key_of_part(rel: str) -> tuple[dt.date, int] | None:
    """(day, device id) of a part partitioned by both (its path says), else None."""
    m = _KEY_IN_PATH.search(rel)
    return (dt.date.fromisoformat(m[1]), int(m[2])) if m else None
