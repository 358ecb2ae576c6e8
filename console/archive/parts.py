"""Writing Parquet parts: zstd, partitioned hive-style by day and device, bounded memory.

A :class:`PartWriter` takes Arrow tables for one archive table, splits them
by partition (one sort per table added, no loop per row), and appends each
partition's rows to one open Parquet file: at most one part per partition
per ingest, rows appended across the parser's chunks.  Memory is bounded by
:data:`BUFFER_BYTES` of buffered rows in all: past it, every partition's
buffer is written out as a row group (so a partition that gets a few rows
per chunk cannot pin the chunks it came from).  A row group is sorted by
``sort_by`` (records: counting head, then time), so a reader looking for
one head's hour finds it in one row group.  At most :data:`MAX_OPEN_WRITERS`
files are open; past it the least recently written one is closed and a
later row of its partition starts a second part (compaction merges them).
Every file written is listed in :attr:`PartWriter.written` (relative to the
archive) for the manifest; :func:`compact` merges a partition's small parts.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from console.archive.store import DATA

NS_PER_DAY = 86_400 * 1_000_000_000
ROW_GROUP_ROWS = 256_000
# Rows waiting to be written, all partitions together (Arrow bytes of the tables added since the last
# write-out): about 2 s of parsing, a fifth of the 256 MB an ingest may use.
BUFFER_BYTES = 48 << 20
MAX_OPEN_WRITERS = 128
COMPRESSION = "zstd"
COMPRESSION_LEVEL = 6
# Compaction merges a partition's parts while the merged part stays under this many rows
# (its rows are held in memory to be sorted: ~60 bytes a record row).
COMPACT_MAX_ROWS = 1_500_000


def day_text(day_index: int) -> str:
    return str(np.datetime64(int(day_index), "D"))


def _writer(path: Path, schema: pa.Schema) -> pq.ParquetWriter:
    return pq.ParquetWriter(
        path,
        schema,
        compression=COMPRESSION,
        compression_level=COMPRESSION_LEVEL,
        use_dictionary=[f.name for f in schema if pa.types.is_dictionary(f.type)],
        column_encoding={
            f.name: "DELTA_BINARY_PACKED"
            for f in schema
            if pa.types.is_integer(f.type) or pa.types.is_timestamp(f.type)
        },
        write_statistics=True,
    )


def sorted_rows(table: pa.Table, sort_by: Sequence[str]) -> pa.Table:
    """``table`` in ``sort_by`` order (dictionary columns by their codes: grouped, not alphabetical)."""
    if not sort_by or table.num_rows < 2:
        return table
    keys = []
    for name in reversed(sort_by):  # np.lexsort: the last key is the primary one
        col = table.column(name).combine_chunks()
        if pa.types.is_dictionary(col.type):
            col = col.indices
        if pa.types.is_timestamp(col.type):
            col = col.cast(pa.int64())
        keys.append(col.fill_null(-1).to_numpy(zero_copy_only=False))
    order = np.lexsort(keys)
    if (order[1:] > order[:-1]).all():
        return table
    return table.take(pa.array(order))


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
    ) -> None:
        self.root = root
        self.table = table
        self.generation = generation
        self.tag = tag
        self.by_device = by_device
        self.by_day = by_day
        self.sort_by = tuple(sort_by)
        self.written: list[str] = []
        self.rows = 0
        self._writers: dict[tuple[int, int], pq.ParquetWriter] = {}  # insertion order = least recently written
        self._parts_of: dict[tuple[int, int], int] = {}
        self._buffers: dict[tuple[int, int], list[pa.Table]] = {}
        self._buffered: dict[tuple[int, int], int] = {}
        self._pending_bytes = 0

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

    def add(self, table: pa.Table, day_index: np.ndarray | None = None, device_id: np.ndarray | None = None) -> None:
        """Add rows; ``day_index`` (days since 1970) and ``device_id`` choose each row's partition."""
        if table.num_rows == 0:
            return
        n = table.num_rows
        days = day_index if self.by_day and day_index is not None else np.zeros(n, np.int64)
        devs = device_id if self.by_device and device_id is not None else np.zeros(n, np.int64)
        key = days.astype(np.int64) * (1 << 32) + devs.astype(np.int64)
        self._pending_bytes += table.nbytes
        if (key == key[0]).all():  # one day, one board in this table
            self._add_part((int(days[0]), int(devs[0])), table)
        else:
            # One stable sort by partition, one take, then zero-copy slices (not a take per partition).
            order = np.argsort(key, kind="stable")
            grouped = table.take(pa.array(order))
            sorted_key = key[order]
            cuts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1], True])
            for a, b in zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True):
                k = int(sorted_key[a])
                self._add_part((k >> 32, k & 0xFFFFFFFF), grouped.slice(a, b - a))
        if self._pending_bytes > BUFFER_BYTES:
            for buffered in list(self._buffers):
                self._flush(buffered)
            self._pending_bytes = 0

    def _add_part(self, key: tuple[int, int], table: pa.Table) -> None:
        self.rows += table.num_rows
        self._buffers.setdefault(key, []).append(table)
        self._buffered[key] = self._buffered.get(key, 0) + table.num_rows
        if self._buffered[key] >= ROW_GROUP_ROWS:
            self._flush(key)

    def _flush(self, key: tuple[int, int]) -> None:
        pieces = self._buffers.pop(key, [])
        self._buffered.pop(key, None)
        if not pieces:
            return
        table = pa.concat_tables(pieces).unify_dictionaries().combine_chunks()
        del pieces
        table = sorted_rows(table, self.sort_by)
        writer = self._writers.pop(key, None)
        if writer is None:
            if len(self._writers) >= MAX_OPEN_WRITERS:
                # Close the least recently written file; this partition's later rows go to a new part.
                oldest = next(iter(self._writers))
                self._writers.pop(oldest).close()
            rel = self._path(key)
            path = self.root / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            writer = _writer(path, table.schema)
            self.written.append(rel)
        elif not table.schema.equals(writer.schema):
            table = table.cast(writer.schema)
        self._writers[key] = writer  # now the most recently written
        writer.write_table(table, row_group_size=ROW_GROUP_ROWS)

    def close(self) -> list[str]:
        """Flush every buffer and close every file; the parts written (relative paths)."""
        for key in list(self._buffers):
            self._flush(key)
        for w in self._writers.values():
            w.close()
        self._writers.clear()
        return self.written

    def abort(self) -> None:
        for w in self._writers.values():
            with contextlib.suppress(Exception):  # the parts are unlisted garbage anyway
                w.close()
        self._writers.clear()
        self._buffers.clear()


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
