"""The device inventory's figures per day, device and counting head, derived at ingest.

``report --archive`` lists the devices of its window (:func:`console.archive.history_diag._inventory`):
per device and head, the first record's names, the diagnostic ids and channels, the records and their
first and last times, and the identity registers' latest values.  Over a day of a busy station that is
two aggregates over millions of records (about half a CPU second for 3 M); here they are made once per
day at ingest, so a report over whole days reads a few hundred rows.

Two tables, partitioned by day, each day's part made again from all of that day's records whenever an
ingest adds records to it (so the rows do not depend on how the files were split between ingests):

* ``head_days``: per (day, device_id, counting_head): the first record's read position (``file_seq`` ×
  2³² + ``line``) and its ``device``, ``type`` and ``gs``; the distinct ``diag_ids`` and ``channels``;
  ``records``; ``first_time`` and ``last_time``;
* ``identity_days``: per day and identity register (the inventory's grouping): its latest value, kind
  and data, and when (time, file, line) it was read.

Only records with a time are summarised: a window is a time range, and a record without a time is in no
bounded window (a report without ``--from``/``--to`` scans the records, as before).
"""

from __future__ import annotations

import datetime as dt
import os
import re
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.archive.day_rows import DayRows, stored_day_table
from console.archive.store import DATA, Manifest

if TYPE_CHECKING:
    import duckdb

HEAD_DAYS = "head_days"
IDENTITY_DAYS = "identity_days"
TABLES = (HEAD_DAYS, IDENTITY_DAYS)

# The read position of a record: a line is one record, so no two records share it.
POSITION = "file_seq::BIGINT * 4294967296 + line"
# The identity registers' grouping and order of "latest" (time; ties: the later file and line).
IDENTITY_GROUP = (
    "device_id, diag_id, device, type, gs, counting_head, channel, address, label, label_canonical, label_encoding"
)
LATEST = "(time, file_seq, line)"

_DAY_IN_PATH = re.compile(r"/day=(\d{4}-\d{2}-\d{2})/")


def head_rows_sql(where: str) -> str:
    """Per (device, head) of the records ``where`` selects: the inventory's figures (``day`` first when
    grouped by it: ``where`` decides nothing about that, the caller's GROUP BY does)."""
    pos = POSITION
    return (
        f"SELECT device_id, counting_head, min({pos}) AS first_pos, arg_min(device, {pos}) AS device, "
        f"arg_min(type, {pos}) AS type, arg_min(gs, {pos}) AS gs, list(DISTINCT diag_id ORDER BY diag_id) AS diag_ids, "
        "list(DISTINCT channel ORDER BY channel) AS channels, count(*) AS records, min(time) AS first_time, "
        f"max(time) AS last_time FROM records{where}"
    )


def identity_rows_sql(where: str) -> str:
    """Per identity register of the records ``where`` selects (labels already chosen by it): its latest value."""
    return (
        f"SELECT {IDENTITY_GROUP}, arg_max(value, {LATEST}) AS value, arg_max(data_kind, {LATEST}) AS data_kind, "
        f"arg_max(data, {LATEST}) AS data, max(time) AS at_time, arg_max(file_seq, {LATEST}) AS at_file_seq, "
        f"arg_max(line, {LATEST}) AS at_line FROM records{where}"
    )


def days_of_parts(rels: Iterable[str]) -> set[str]:
    """The days (YYYY-MM-DD) that record parts lie in (their paths say)."""
    return {m[1] for rel in rels if (m := _DAY_IN_PATH.search("/" + rel))}


def derive_days(
    root: Path, manifest: Manifest, generation: int, days: set[str] | None, day_rows: DayRows | None = None
) -> list[str]:
    """Both tables' parts for ``days`` (None: every day) made again from the records, replacing theirs in
    ``manifest``; the parts written.

    A day is a task of the current engine (:func:`console.fleet.engine.map_partitions`): on Dask the
    workers aggregate the days, where the client's one DuckDB pass over a 100 M-record archive took
    10 s alone and set its peak memory.  ``day_rows``: what this ingest's read gathered; the days it can
    make exactly (:mod:`console.archive.day_rows`) are merged with their stored rows, not read back."""
    from console.fleet.engine import map_partitions

    merged: list[str] = []
    if days is not None and day_rows is not None and day_rows.complete:
        days = set(days)
        for day in sorted(days):
            made = _merged_day(root, manifest, generation, day, day_rows)
            if made is not None:
                days.discard(day)
                for table in TABLES:
                    kept = [r for r in manifest.parts(table) if day not in days_of_parts([r])]
                    manifest.tables[table] = kept + [r for r in made if r.startswith(os.path.join(DATA, table, ""))]
                merged += made
    for table in TABLES:
        keep = [] if days is None else [r for r in manifest.parts(table) if not (days_of_parts([r]) & days)]
        manifest.tables[table] = keep
    if days is not None and not days:
        return _in_day_order(manifest, merged)
    by_day: dict[str, list[str]] = {}
    for rel in manifest.parts("records"):
        for day in days_of_parts([rel]):
            if days is None or day in days:
                by_day.setdefault(day, []).append(rel)
    items = [{"day": day, "records": by_day[day]} for day in sorted(by_day)]
    written: list[str] = []
    for parts in map_partitions(_day_parts, items, common={"root": root, "generation": generation}, label="head days"):
        for table, rel in parts:
            written.append(rel)
            manifest.tables[table] = [*manifest.parts(table), rel]
    return _in_day_order(manifest, merged + written)


def _in_day_order(manifest: Manifest, written: list[str]) -> list[str]:
    """``written`` (this call's parts, one per table and day) listed after the others, by day, in both
    tables: the order every day made from the records gives, whichever way each day was made."""
    new = set(written)
    for table in TABLES:
        rels = manifest.parts(table)
        manifest.tables[table] = [r for r in rels if r not in new] + sorted((r for r in rels if r in new), key=_day_of)
    return sorted(written, key=_day_of)


def _day_of(rel: str) -> str:
    m = _DAY_IN_PATH.search("/" + rel)
    return m[1] if m else ""


def _merged_day(root: Path, manifest: Manifest, generation: int, day: str, day_rows: DayRows) -> list[str] | None:
    """``day``'s parts of both tables from the read's figures and the stored rows (the parts written), or
    None when the read saw no timed record of that day (made from the records, as before)."""
    from console.archive.parts import write_part

    index = int(np.datetime64(day, "D").astype(np.int64))
    if index not in day_rows.days():
        return None
    out: list[str] = []
    for table in TABLES:
        rels = [] if day_rows.first else [r for r in manifest.parts(table) if day in days_of_parts([r])]
        stored = stored_day_table(root, rels)
        rows = day_rows.head_rows(index, stored) if table == HEAD_DAYS else day_rows.identity_rows(index, stored)
        if rows.num_rows == 0:
            continue
        rel = os.path.join(DATA, table, f"day={day}", f"g{generation:06d}-s.parquet")
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        out.append(write_part(root, rel, rows))
    return out


def _day_parts(root: Path, generation: int, day: str, records: list[str]) -> list[tuple[str, str]]:
    """One day's rows of both tables, from that day's record parts, written as their parts: (table, part)."""
    from console.analysis.inventory import IDENTITY_LABELS
    from console.archive.parts import write_part
    from console.archive.views import connect

    where = " WHERE time IS NOT NULL"
    labels = ", ".join(f"'{x}'" for x in sorted(IDENTITY_LABELS))
    con, _ = connect(root, Manifest(tables={"records": records}), tables=("records",))
    try:
        heads = con.sql(_grouped(head_rows_sql(where), "device_id, counting_head")).to_arrow_table()
        ident_sql = _grouped(identity_rows_sql(f"{where} AND label_canonical IN ({labels})"), IDENTITY_GROUP)
        ident = con.sql(ident_sql).to_arrow_table()
    finally:
        con.close()
    out: list[tuple[str, str]] = []
    for table, rows in ((HEAD_DAYS, heads), (IDENTITY_DAYS, ident)):
        if rows.num_rows == 0:
            continue
        # A record's day partition is its time's (parse_pass), so the rows are all of ``day``.
        rel = os.path.join(DATA, table, f"day={day}", f"g{generation:06d}-s.parquet")
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        out.append((table, write_part(root, rel, rows.drop_columns(["day"]))))
    return out


def _grouped(select: str, group: str) -> str:
    """``select`` (one SELECT ... FROM records WHERE ...) per day as well: ``day`` first, ordered for a stable part."""
    rest = select.removeprefix("SELECT ")
    return f"SELECT day, {rest} GROUP BY day, {group} ORDER BY day, {group}"


def whole_days(start: dt.datetime | None, end: dt.datetime | None) -> tuple[dt.date, dt.date] | None:
    """The whole days [first, last) inside the window [start, end), if any (both bounds needed)."""
    if start is None or end is None:
        return None
    first = start.date() if start.time() == dt.time() else start.date() + dt.timedelta(days=1)
    last = end.date()
    return (first, last) if first < last else None


def stored_rows(
    con: duckdb.DuckDBPyConnection,
    root: Path,
    manifest: Manifest,
    days: tuple[dt.date, dt.date],
    head: str | None,
    device_id: int | None,
) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]]] | None:
    """Both tables' rows of the days [first, last), cut to the head and device (None: the archive has no
    ``head_days`` part at all: derived before them, or no timed record; the caller reads the records)."""
    if not manifest.parts(HEAD_DAYS):
        return None
    lo, hi = days[0].isoformat(), days[1].isoformat()
    conds: list[str] = []
    params: list[Any] = []
    if head is not None:
        conds.append("counting_head = ?")
        params.append(head)
    if device_id is not None:
        conds.append("device_id = ?")
        params.append(device_id)
    where = (" WHERE " + " AND ".join(conds)) if conds else ""
    out: list[list[tuple[Any, ...]]] = []
    for table in TABLES:
        rels = [r for r in manifest.parts(table) if any(lo <= d < hi for d in days_of_parts([r]))]
        if not rels:
            out.append([])
            continue
        files = "[" + ", ".join("'" + str(root / r).replace("'", "''") + "'" for r in rels) + "]"
        sql = f"SELECT * FROM read_parquet({files}, hive_partitioning = false){where}"
        out.append(con.execute(sql, params).fetchall())
    return out[0], out[1]
