"""Reading the archive back: a window of its records (in Arrow batches, or as chunks the pipeline reads),
the health registers' records, the stored fixes, frames and voltages per file, the files' parse reports.

The report-level functions over these (the report's data, the station's replay inputs, the tables an
ingest derives at its end) are :mod:`console.archive.history`.
"""

from __future__ import annotations

import datetime as dt
import fcntl
import os
import shutil
import tempfile
from collections import Counter
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.timefmt import parse_time, time_ns
from console.archive.parts import key_of_part
from console.archive.records import ARCHIVED_RECORD_COLUMNS, REGISTER_COLUMNS, ChunkRebuilder
from console.archive.store import READING, TMP, Manifest, read_current
from console.archive.views import connect
from console.drivers.batch import ChunkSource, ReadOptions
from console.engine.pipeline import HEALTH_REGISTERS
from console.layout import Layout, load_layout
from parsers.diag.records import DiagChunk, chunks_to_frame
from parsers.diag.registry import DiagRegistry
from parsers.report import FileReport, ParseReport, Rejection

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

BATCH_ROWS = 1 << 20


@dataclass(frozen=True)
class Window:
    """Which history: a time range [from, to), a counting head, a device id (None: all)."""

    start: dt.datetime | None = None
    end: dt.datetime | None = None
    head: str | None = None
    device_id: int | None = None

    def where(self) -> tuple[str, list[Any]]:
        conds: list[str] = []
        params: list[Any] = []
        if self.start is not None:
            conds.append("time >= ?")
            params.append(self.start)
        if self.end is not None:
            conds.append("time < ?")
            params.append(self.end)
        if self.head is not None:
            conds.append("counting_head = ?")
            params.append(self.head)
        if self.device_id is not None:
            conds.append("device_id = ?")
            params.append(self.device_id)
        if self.start is not None or self.end is not None:
            # Partition pruning: the day keys are in the paths.
            if self.start is not None:
                conds.append("day >= ?")
                params.append(self.start.date())
            if self.end is not None:
                conds.append("day <= ?")
                params.append(self.last_day)
        return (" WHERE " + " AND ".join(conds)) if conds else "", params

    @property
    def last_day(self) -> dt.date:
        """The last day a record before the end can lie in (a record's day is its time's: a window ending at
        midnight reads nothing of the day it ends on)."""
        assert self.end is not None
        return (self.end - dt.timedelta(microseconds=1)).date()

    @property
    def whole(self) -> bool:
        return self == Window()


def user_window(start: str | None, end: str | None, head: str | None = None, device_id: int | None = None) -> Window:
    """``--from``/``--to`` as given: ValueError on a time that is not one, and on an empty window (it would
    report nothing, which reads as "nothing happened")."""
    window = Window(parse_time(start) if start else None, parse_time(end) if end else None, head, device_id)
    for bound in (window.start, window.end):
        if bound is not None:
            time_ns(bound)  # a year like 9999 or 1600: DuckDB's ns timestamps cannot hold it (its internal error)
    if window.start is not None and window.end is not None and window.start >= window.end:
        raise ValueError(f"from {window.start.isoformat()} is not before to {window.end.isoformat()}")
    return window


def window_holds_data(root: Path, manifest: Manifest, window: Window) -> bool:
    """Whether a record, frame or GNSS fix of the archive lies in the window's time range (voltages, which have
    no time, are in every window)."""
    tables = [t for t in ("records", "frames", "fixes") if manifest.parts(t)]
    if manifest.parts("voltages") or not tables:
        return True
    conds = [c for c, v in (("time >= ?", window.start), ("time < ?", window.end)) if v is not None]
    params = [v for v in (window.start, window.end) if v is not None]
    con, _ = connect(root, manifest, tables=tables)
    try:
        where = " AND ".join(conds) or "true"
        return any(con.execute(f"SELECT 1 FROM {t} WHERE {where} LIMIT 1", params).fetchone() for t in tables)
    finally:
        con.close()


def names_a_unit(root: Path, manifest: Manifest, name: str) -> bool:
    """Whether ``name`` is a counting head (of records, frames or voltages) or a GNSS unit of the archive."""
    columns = {"records": "counting_head", "frames": "sensor", "voltages": "sensor", "fixes": "device"}
    tables = [t for t in columns if manifest.parts(t)]
    if not tables:
        return False
    con, _ = connect(root, manifest, tables=tables)
    try:
        return any(con.execute(f"SELECT 1 FROM {t} WHERE {columns[t]} = ? LIMIT 1", [name]).fetchone() for t in tables)
    finally:
        con.close()


_ARCHIVED_COLUMNS_SQL = ", ".join(ARCHIVED_RECORD_COLUMNS)


def heads_in(root: Path, manifest: Manifest, file_seqs: list[int] | None) -> list[tuple[int, Any]]:
    """The heads of these files' records (None: every file), in the order a read of the files meets them."""
    con, _ = connect(root, manifest, tables=("records",))
    try:
        cond = " WHERE file_seq IN (SELECT unnest(?))" if file_seqs is not None else ""
        rows = con.sql(
            f"SELECT device_id, counting_head, min(file_seq::BIGINT * 4294967296 + line) AS pos FROM records{cond} "
            "GROUP BY ALL ORDER BY pos",
            params=[list(file_seqs)] if file_seqs is not None else [],
        ).fetchall()
    finally:
        con.close()
    return [(int(d), h) for d, h, _ in rows]


def record_batches(
    root: Path,
    manifest: Manifest,
    window: Window = Window(),
    tables: Collection[str] | None = None,
    *,
    labels: Collection[str] | None = None,
    merged: bool = False,
    on_registers: Callable[[pa.RecordBatch], None] | None = None,
    where: tuple[str, list[Any]] = ("", []),
) -> Iterator[pa.RecordBatch]:
    """The records (in file, line order: the order a batch read sees them), in Arrow batches.

    ``tables``: only these views are built.
    ``labels``: only the records of these canonical labels (the health registers).
    ``merged``: in the order a batch read of all the files together gives each head's records instead
    (by time; equal times by file, the file whose records of that head begin earlier first, each file
    in its own order: :func:`console.analysis.passages.part_analysis._merged_order`), for files whose time ranges
    interleave.  ``on_registers`` is then first given every register, in the order the files meet them.
    ``where``: a further condition (SQL, parameters), e.g. a group's heads.
    """
    if not manifest.parts("records"):
        return
    try:
        (root / TMP).mkdir(parents=True, exist_ok=True)
        spill = Path(tempfile.mkdtemp(prefix="duckdb-", dir=root / TMP))
    except OSError:  # an archive only read (a snapshot, read-only media, another user's): spill to the system's
        spill = Path(tempfile.mkdtemp(prefix="trackside-duckdb-"))
    # Held while reading: an ingest starting meanwhile leaves the folder alone (store.collect_garbage).
    hold = os.open(spill / READING, os.O_CREAT | os.O_RDWR, 0o600)
    fcntl.flock(hold, fcntl.LOCK_SH)
    try:
        con, _ = connect(root, manifest, spill_dir=spill, tables=tables)
    except BaseException:
        os.close(hold)
        shutil.rmtree(spill, ignore_errors=True)
        raise
    try:
        where_sql, params = window.where()
        if labels is not None:
            where_sql += (" AND " if where_sql else " WHERE ") + "label_canonical IN (SELECT unnest(?))"
            params.append(sorted(labels))
        if where[0]:
            where_sql += (" AND " if where_sql else " WHERE ") + where[0]
            params += where[1]
        where = where_sql  # type: ignore[assignment]
        if not merged:
            rel = con.sql(f"SELECT {_ARCHIVED_COLUMNS_SQL} FROM records{where} ORDER BY file_seq, line", params=params)
            yield from rel.to_arrow_reader(BATCH_ROWS)
            return
        if on_registers is not None:
            registers = ", ".join(REGISTER_COLUMNS)
            first = con.sql(
                f"SELECT {registers}, min(file_seq::BIGINT * 4294967296 + line) AS pos FROM records{where} "
                f"GROUP BY ALL ORDER BY pos",
                params=params,
            ).to_arrow_table()
            on_registers(first.combine_chunks().to_batches()[0] if first.num_rows else None)
        rel = con.sql(
            f"SELECT {_ARCHIVED_COLUMNS_SQL} FROM (SELECT *, min(time) OVER (PARTITION BY device_id, counting_head, "
            f"file_seq) AS file_first FROM records{where}) ORDER BY time, file_first, file_seq, line",
            params=params,
        )
        yield from rel.to_arrow_reader(BATCH_ROWS)
    finally:
        con.close()
        os.close(hold)
        shutil.rmtree(spill, ignore_errors=True)


class ArchivedRecords(ChunkSource):
    """The archive's diagnostic records (a window of them) as a source of chunks, in ingest order."""

    def __init__(self, root: Path, manifest: Manifest, window: Window = Window()) -> None:
        self.root, self.manifest, self.window = root, manifest, window
        self.report = parse_reports(root, manifest)["diagnostic"]
        self.files = [f.file for f in self.report.files]

    def open(self, opts: ReadOptions) -> tuple[DiagRegistry, Iterator[DiagChunk], ParseReport]:
        rebuild = ChunkRebuilder()
        return rebuild.registry, self._chunks(rebuild), self.report

    def _chunks(self, rebuild: ChunkRebuilder) -> Iterator[DiagChunk]:
        for batch in record_batches(self.root, self.manifest, self.window):
            yield from rebuild.chunks(batch)
        self.report.unknown_labels.update(rebuild.registry.unknown_labels())


def health_records(root: Path, manifest: Manifest, window: Window = Window()) -> pd.DataFrame | None:
    """The records of the health registers, as a read through the pipeline keeps them (without reading the
    other records); None when there is none (no table made: a window without them needs no pandas).

    Read with pyarrow, part by part, filtered by label as each part is read: a DuckDB connection
    costs ~50 MB of memory to open, more than these few records.  On a cluster (an ingest's end, the
    workers idle) runs of parts are read by the workers, side by side (:func:`health_parts`).
    """
    import pyarrow as pa

    from console.fleet.engine import in_flight, map_partitions

    rels: list[str] = []
    for rel in manifest.parts("records"):
        key = key_of_part(rel)
        if key is None or (window.device_id is not None and key[1] != window.device_id):
            continue
        if (window.start is not None and key[0] < window.start.date()) or (
            window.end is not None and key[0] > window.last_day
        ):
            continue
        rels.append(rel)
    n = max(1, min(len(rels), 2 * in_flight())) if in_flight() > 1 else 1
    runs = [{"rels": rels[i * len(rels) // n : (i + 1) * len(rels) // n]} for i in range(n)]
    found = map_partitions(health_parts, runs, common={"root": root, "window": window}, label="health")
    tables = [t for run in found for t in run]
    if not tables:
        return None
    rebuild = ChunkRebuilder()
    kept: list[DiagChunk] = []
    table = pa.concat_tables(tables, promote_options="permissive").select(list(ARCHIVED_RECORD_COLUMNS))
    order = np.lexsort((table.column("line").to_numpy(), table.column("file_seq").to_numpy()))
    for batch in table.take(pa.array(order)).to_batches(BATCH_ROWS):
        kept += rebuild.chunks(batch)
    return chunks_to_frame(kept, rebuild.registry)


def health_parts(root: Path, window: Window, rels: list[str]) -> list[pa.Table]:
    """The health registers' records of the records parts ``rels`` in ``window`` (a task on a cluster)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    tables = []
    wanted = None
    for rel in rels:
        key = key_of_part(rel)
        if key is None or not _has_label(root / rel, HEALTH_REGISTERS):
            continue  # the usual part: no health register at all (its labels alone were read)
        # The filter made once a part holds a health register (pyarrow's expressions import pandas).
        wanted = _health_filter(window) if wanted is None else wanted
        t = pq.read_table(root / rel, filters=wanted, partitioning=None)
        if t.num_rows:
            t = t.cast(
                pa.schema(
                    [pa.field(f.name, f.type.value_type) if pa.types.is_dictionary(f.type) else f for f in t.schema]
                )
            )
            tables.append(t.append_column("device_id", pa.array(np.full(t.num_rows, key[1], np.int32))))
    return tables


def _health_filter(window: Window) -> Any:
    """The pyarrow filter of the health registers' records in ``window``."""
    import pyarrow as pa
    import pyarrow.compute as pc

    wanted = pc.field("label_canonical").isin(sorted(HEALTH_REGISTERS))
    if window.start is not None:
        wanted &= pc.field("time") >= pa.scalar(window.start, pa.timestamp("ns"))
    if window.end is not None:
        wanted &= pc.field("time") < pa.scalar(window.end, pa.timestamp("ns"))
    if window.head is not None:
        wanted &= pc.field("counting_head") == window.head
    return wanted


def _has_label(path: Path, labels: frozenset[str]) -> bool:
    """Whether a records part holds a record of one of ``labels`` (only its ``label_canonical`` column read).

    Read and looked at without the calls that wake pyarrow's pandas shim (``read_table``, ``pa.array``,
    ``to_numpy`` of a copy) and, for the usual dictionary-encoded column, without ``pyarrow.compute`` (its
    import is a tenth of a second): a part without those labels is the usual one, and a report over such
    parts needs neither.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from console.archive.arrow_np import to_numpy

    with pq.ParquetFile(path) as f:
        col = f.read(columns=["label_canonical"]).column(0)
    for chunk in col.chunks:
        if pa.types.is_dictionary(chunk.type) and not chunk.indices.null_count:
            # By the dictionary's codes: the values are decoded once per dictionary (a part's few distinct
            # labels), not once per row.
            codes = [i for i, name in enumerate(chunk.dictionary.to_pylist()) if name in labels]
            if codes and np.isin(to_numpy(chunk.indices), codes).any():
                return True
            continue
        import pyarrow.compute as pc

        plain = chunk.dictionary_decode() if pa.types.is_dictionary(chunk.type) else chunk
        if pc.any(pc.is_in(plain.cast(pa.string()), value_set=pa.array(sorted(labels), pa.string()))).as_py():
            return True
    return False


def speed_settings(manifest: Manifest, layout: Layout | None = None) -> SpeedSettings:
    lay = layout if layout is not None else layout_of(manifest.derived.get("layout"))
    return SpeedSettings.of_layout(lay)


def layout_of(spec: str | None) -> Layout | None:
    return load_layout(spec) if spec else None


def per_file_tables(root: Path, manifest: Manifest, table: str) -> list[tuple[int, pd.DataFrame]]:
    import pyarrow.parquet as pq

    out = []
    for rel in manifest.parts(table):
        t = pq.read_table(root / rel)
        df = t.to_pandas()
        seq = int(df["file_seq"].iloc[0]) if len(df) else -1
        if table == "fixes" and getattr(df["time"].dt, "tz", None) is None:
            df["time"] = df["time"].dt.tz_localize("UTC")  # stored naive UTC; the parser's fixes are zone-aware
        out.append((seq, df.drop(columns=["file_seq"])))
    return sorted(out, key=lambda x: x[0])


def frame_window(frames: pd.DataFrame, window: Window) -> pd.DataFrame:
    import pandas as pd

    if window.start is not None:
        frames = frames[frames["time"] >= pd.Timestamp(window.start)]
    if window.end is not None:
        frames = frames[frames["time"] < pd.Timestamp(window.end)]
    return frames


REPORT_KINDS = {
    "diagnostic": "diagnostic",
    "frames": "frames",
    "can": "can",
    "voltages": "voltages",
    "nmea": "gnss",
    "gnss-csv": "gnss",
    "gnss-jsonl": "gnss",
    "centre": "gnss",
}


def parse_reports(root: Path, manifest: Manifest, only: set[int] | None = None) -> dict[str, ParseReport]:
    """Per report section (diagnostic, frames, can, voltages, gnss): the parse report of the archived files.

    Rebuilt from each file's accounting in the ledger and its rejected lines,
    in file order, the first MAX_REJECTIONS_KEPT kept as a read of the files would.
    """
    out: dict[str, ParseReport] = {k: ParseReport() for k in set(REPORT_KINDS.values())}
    section_of: dict[int, str] = {}
    for e in sorted(manifest.files, key=lambda e: int(e["file_seq"])):
        section = REPORT_KINDS.get(str(e["kind"]))
        if section is None or not e.get("active", True) or "report" not in e:
            continue
        if only is not None and int(e["file_seq"]) not in only:
            continue  # a report scoped to a head: the files that hold it (console.archive.scope)
        section_of[int(e["file_seq"])] = section
        rep = out[section]
        known = set(FileReport.__dataclass_fields__)
        rep.files.append(FileReport(**{k: v for k, v in e["report"].items() if k in known}))
        rep.rejected_by_reason.update(Counter(e.get("rejected_by_reason", {})))
        rep.skipped.update(Counter(e.get("skipped", {})))
    if manifest.parts("rejected") and section_of:
        con, _ = connect(root, manifest, tables=("rejected",))
        try:
            rows = con.execute(
                "SELECT file_seq, file, line, reason, text FROM rejected ORDER BY file_seq, line"
            ).fetchall()
        finally:
            con.close()
        for seq, f, line, reason, text in rows:
            section = section_of.get(int(seq))
            if section is None:
                continue
            rep = out[section]
            if len(rep.rejections) < rep.max_rejections_kept:
                rep.rejections.append(Rejection(str(f), int(line), str(reason), str(text)))
    return out


def cut_fixes(fixes: pd.DataFrame, window: Window) -> pd.DataFrame:
    """Fixes inside the window (zone-aware fix times are compared in UTC)."""
    import pandas as pd

    tz = getattr(fixes["time"].dt, "tz", None)

    def stamp(t: dt.datetime) -> pd.Timestamp:
        ts = pd.Timestamp(t)
        return ts.tz_localize("UTC") if tz is not None else ts

    if window.start is not None:
        fixes = fixes[fixes["time"] >= stamp(window.start)]
    if window.end is not None:
        fixes = fixes[fixes["time"] < stamp(window.end)]
    return fixes


def replay(root: Path, window: Window = Window()) -> Iterator[pd.DataFrame]:
    """The records in time order (ties in file, line order), a DataFrame per batch, for the station view."""
    m = read_current(root)
    if not m.parts("records"):
        return
    con, _ = connect(root, m)
    try:
        where, params = window.where()
        rel = con.sql(
            f"SELECT {_ARCHIVED_COLUMNS_SQL} FROM records{where} ORDER BY time, file_seq, line", params=params
        )
        for batch in rel.to_arrow_reader(BATCH_ROWS):
            yield batch.to_pandas()
    finally:
        con.close()
