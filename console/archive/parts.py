"""Writing Parquet parts: zstd, partitioned hive-style by day and device, bounded memory.

A :class:`PartWriter` takes Arrow tables for one archive table, splits them
by partition, buffers a little per partition and writes row groups as the
buffer fills, so a 12 M-record log is written with a few MB per open
partition.  Every file it writes is listed in :attr:`PartWriter.written`
(relative to the archive) for the manifest.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from console.archive.store import DATA

NS_PER_DAY = 86_400 * 1_000_000_000
ROW_GROUP_ROWS = 256_000
COMPRESSION = "zstd"
COMPRESSION_LEVEL = 6


def day_text(day_index: int) -> str:
    return str(np.datetime64(int(day_index), "D"))


class PartWriter:
    """Parquet parts of one table, one file per partition, written as they fill."""

    def __init__(
        self, root: Path, table: str, generation: int, tag: str, *, by_device: bool = True, by_day: bool = True
    ) -> None:
        self.root = root
        self.table = table
        self.generation = generation
        self.tag = tag
        self.by_device = by_device
        self.by_day = by_day
        self.written: list[str] = []
        self.rows = 0
        self._writers: dict[tuple[int, int], pq.ParquetWriter] = {}
        self._buffers: dict[tuple[int, int], list[pa.Table]] = {}
        self._buffered: dict[tuple[int, int], int] = {}
        self._schema: pa.Schema | None = None

    def _path(self, key: tuple[int, int]) -> str:
        parts = [DATA, self.table]
        if self.by_day:
            parts.append(f"day={day_text(key[0])}")
        if self.by_device:
            parts.append(f"device_id={key[1]}")
        parts.append(f"g{self.generation:06d}-{self.tag}.parquet")
        return os.path.join(*parts)

    def add(self, table: pa.Table, day_index: np.ndarray | None = None, device_id: np.ndarray | None = None) -> None:
        """Add rows; ``day_index`` (days since 1970) and ``device_id`` choose each row's partition."""
        if table.num_rows == 0:
            return
        n = table.num_rows
        days = day_index if self.by_day and day_index is not None else np.zeros(n, np.int64)
        devs = device_id if self.by_device and device_id is not None else np.zeros(n, np.int64)
        key = days.astype(np.int64) * (1 << 32) + devs.astype(np.int64)
        first = key[0]
        if (key == first).all():  # the common case: one day, one board per chunk
            self._add_part((int(days[0]), int(devs[0])), table)
            return
        uniq, inverse = np.unique(key, return_inverse=True)
        for i, k in enumerate(uniq.tolist()):
            idx = np.flatnonzero(inverse == i)
            self._add_part((k >> 32, k & 0xFFFFFFFF), table.take(pa.array(idx)))

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
        writer = self._writers.get(key)
        if writer is None:
            rel = self._path(key)
            path = self.root / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            self._schema = table.schema
            writer = pq.ParquetWriter(
                path,
                table.schema,
                compression=COMPRESSION,
                compression_level=COMPRESSION_LEVEL,
                use_dictionary=[f.name for f in table.schema if pa.types.is_dictionary(f.type)],
                column_encoding={
                    f.name: "DELTA_BINARY_PACKED"
                    for f in table.schema
                    if pa.types.is_integer(f.type) or pa.types.is_timestamp(f.type)
                },
                write_statistics=True,
            )
            self._writers[key] = writer
            self.written.append(rel)
        elif not table.schema.equals(writer.schema):
            table = table.cast(writer.schema)
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


def write_small(root: Path, table_name: str, generation: int, tag: str, table: pa.Table) -> str | None:
    """One unpartitioned part (ledger tables, findings): the relative path, or None when empty."""
    if table.num_rows == 0:
        return None
    w = PartWriter(root, table_name, generation, tag, by_device=False, by_day=False)
    w.add(table)
    written = w.close()
    return written[0] if written else None
