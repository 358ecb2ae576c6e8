"""The report's diagnostic part read from the archive's derived tables, not recomputed from its records.

``report --archive`` over a day of a busy station would otherwise parse
that day's millions of records again and run every analysis over them.
The derivation (:mod:`console.archive.derive`) has already written the
analyses down: passages (with their per-axle speeds), section states and
the count ledger, the channel events health judges, the sections' final
state.  Here they are read back for a window and handed to the report as
the batch analyses would have returned them; only small things are
computed: the device inventory (one SQL aggregate per register over the
window's records) and the health verdicts (from the window's channel events
and health-register records, by the same :func:`console.jobs.health_findings`).

A window is the archive's history cut to it, not the window's records
analysed as a log on their own: a passage belongs to the window it starts
in, a section enters the window in the state the history left it, and its
final state is the one at the window's end.  Without a window the report
equals the report on all the archived files (tests/test_archive_report.py).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.passages.diag_analysis import DiagAnalysis
from console.archive.derive_sink import DERIVE_VERSION
from console.archive.reader import Window, health_records, parse_reports
from console.archive.store import Manifest
from console.archive.views import connect
from console.drivers.batch import DiagJob

if TYPE_CHECKING:
    import duckdb
    import pandas as pd

    from console.analysis.events.detection import DetectionEvent
    from console.analysis.inventory import DeviceInventory
    from console.analysis.passages.buckets import Columns
    from console.analysis.passages.speed_settings import SpeedSettings
    from console.analysis.sections.engine import SectionsResult
    from console.layout import Layout
    from parsers.report import ParseReport


@dataclass
class HistoryDiag:
    """The diagnostic part of a report, from the derived tables."""

    job: DiagJob
    sections: SectionsResult | None
    channel_events: list[DetectionEvent]  # the events health reads (channel faults, single-channel pulses)
    warnings: list[str]  # heads of the log the layout does not count


def derived_for(manifest: Manifest, layout_spec: str | None) -> bool:
    """Whether the derived tables hold this report: derived by this version, with this layout."""
    d = manifest.derived
    fingerprint = d.get("fingerprint") or {}
    return (
        bool(manifest.parts("records"))
        and "states" in d
        and "sections_final" in d
        and fingerprint.get("version") == DERIVE_VERSION
        and (layout_spec is None or layout_spec == d.get("layout"))
    )


def history_diag(
    root: Path,
    manifest: Manifest,
    layout: Layout | None,
    settings: SpeedSettings,
    window: Window,
    reports: dict[str, ParseReport] | None = None,
) -> HistoryDiag | None:
    """The window's diagnostic analyses from the derived tables (None: no diagnostic records in it).

    ``reports``: the archive's parse reports when the caller has read them (:func:`parse_reports`).
    """
    # The health registers' records are read by pyarrow on a thread while DuckDB answers the rest:
    # both release the GIL for their reads (a 3 M-record day: 0.7 s and 1.0 s, now overlapped).
    pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trackside-health")
    kept = pool.submit(health_records, root, manifest, window)
    pool.shutdown(wait=False)
    con, _ = connect(root, manifest, tables=("records", "passages", "section_states", "count_ledger"))
    try:
        devices = _inventory(con, window, root, manifest)
        if not devices:
            kept.cancel()
            return None
        heads = _heads(manifest)
        columns = _passage_columns(con, window, heads)
        passages = _passages(con, window, heads) if columns is None else None
        sections = _sections(con, manifest, layout, window)
    finally:
        con.close()
    report = (reports if reports is not None else parse_reports(root, manifest))["diagnostic"]
    # Every wheel onset lies in a passage; the unpaired are those no axle took (the table or the columns alike).
    held = passages if passages is not None else columns
    unpaired = (
        int(held["detections_sys1"].sum() + held["detections_sys2"].sum() - 2 * held["axles"].sum())
        if held is not None and len(held)  # an empty table, or {}: no passage
        else 0
    )
    analysis = DiagAnalysis(
        settings=settings,
        devices=devices,
        passage_columns=columns or None,  # {}: no passage in the window
        axle_columns={},
        overlap_records=_overlap(manifest, window),
        unpaired_detections=unpaired,
        heads=heads,
    )
    if passages is not None:
        analysis.__dict__["passages"] = passages  # the cached table, as DiagAnalysis.passages builds it
    job = DiagJob(
        files=[f.file for f in report.files],
        report=report,
        analysis=analysis,
        kept_records=kept.result(),
    )
    return HistoryDiag(job, sections, channel_events(root, manifest, window), _warnings(layout, heads))


def _heads(manifest: Manifest) -> list[tuple[int, Any]]:
    """The heads in the order a read of every archived file meets them (the pipeline kept it)."""
    return [(int(d), n) for d, n in manifest.derived.get("heads", [])]


def _overlap(manifest: Manifest, window: Window) -> int:
    """Records set aside as another file's overlap, in the window's days."""
    import datetime as dt

    lo = window.start.date() if window.start is not None else None
    hi = window.end.date() if window.end is not None else None
    total = 0
    for per_day in manifest.derived.get("overlap_by_day", {}).values():  # per group of heads
        for day, n in per_day.items():
            d = dt.date.fromisoformat(day)
            if (lo is None or d >= lo) and (hi is None or d <= hi):
                total += int(n)
    return total


def _warnings(layout: Layout | None, heads: list[tuple[int, Any]]) -> list[str]:
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.sections.stream import EventStream

    return EventStream(layout, DiagEventSettings()).warnings(heads)


def _where(window: Window, time_column: str, *, heads: bool = True) -> tuple[str, list[Any]]:
    """A window's WHERE over a derived table (times as ns integers or timestamps)."""
    conds: list[str] = []
    params: list[Any] = []
    for bound, op in ((window.start, ">="), (window.end, "<")):
        if bound is not None:
            conds.append(f"{time_column} {op} ?")
            params.append(bound if not time_column.endswith("_ns") else _ns(bound))
    if heads and window.head is not None:
        conds.append("counting_head = ?")
        params.append(window.head)
    if heads and window.device_id is not None:
        conds.append("device_id = ?")
        params.append(window.device_id)
    return (" WHERE " + " AND ".join(conds)) if conds else "", params


def _ns(t: Any) -> int:
    import datetime as dt

    return (t - dt.datetime(1970, 1, 1)) // dt.timedelta(microseconds=1) * 1000


def _passage_columns(con: duckdb.DuckDBPyConnection, window: Window, heads: list[tuple[int, Any]]) -> Columns | None:
    """The window's passages as the pipeline's columns (``DiagAnalysis.passage_columns``, head keys into
    ``heads``), in the batch's order: head by head (heads in the order they first appear), each in time order.

    Read straight into numpy, without a table: ``{}`` when the window has none; None where the columns cannot
    hold them (a head ``heads`` does not list, a null head, count or flag, a text with no code): the caller
    reads them as a table (:func:`_passages`).
    """
    from console.analysis.passages.passage_frame import (
        PASSAGE_BASES,
        PASSAGE_COLUMNS,
        PASSAGE_DIRECTIONS,
        PASSAGE_KINDS,
    )
    from console.archive.arrow_np import list_values, to_numpy

    names = con.sql("SELECT * FROM passages LIMIT 0").columns
    if "axle_speeds_kmh" not in names:  # no passage at all: the view has the empty table's columns
        return {}
    # Each (device, head) once, with its place (a repeated head: its last, as a dict of them keeps it).
    rank = {h: i for i, h in enumerate(heads)}
    if any(name is None for _, name in rank):
        return None
    where, params = _where(window, "start_ns")
    ints = ("start_ns", "end_ns", "records", "detections_sys1", "detections_sys2", "axles")
    texts = ("direction", "whole_train_basis", "kind")
    others = (*ints, *texts, "subsecond", "axle_speeds_start", "axle_speeds_stop")
    # The rest are floats, NaN where the archive has a null (it stores integers where the analysis has floats).
    floats = [c for c in PASSAGE_COLUMNS[2:] if c not in others]

    def code(column: str, values: tuple[str | None, ...]) -> str:
        # Into ``values``; -1: a text with no code (and a null where ``values`` has none).
        known = "[" + ", ".join("'" + v + "'" for v in values if v is not None) + "]"
        found = f"list_position({known}, {column}) - {0 if values[0] is None else 1}"
        null = "0" if values[0] is None else "-1"
        return f"(CASE WHEN {column} IS NULL THEN {null} ELSE coalesce({found}, -1) END)::TINYINT AS {column}"

    select = ", ".join(
        [
            "k_rank AS head",
            *ints,
            *(f'coalesce("{c}"::DOUBLE, \'NaN\'::DOUBLE) AS "{c}"' for c in floats),
            code("direction", PASSAGE_DIRECTIONS),
            code("whole_train_basis", PASSAGE_BASES),
            code("kind", PASSAGE_KINDS),
            "subsecond::UTINYINT AS subsecond",  # bytes, not Arrow's bits
            "coalesce(len(axle_speeds_kmh), 0)::BIGINT AS n_speeds",
            "axle_speeds_kmh",
        ]
    )
    table = con.sql(
        "WITH k AS (SELECT unnest(?::BIGINT[]) AS k_device, unnest(?::VARCHAR[]) AS k_head, "
        "unnest(?::BIGINT[]) AS k_rank) "
        f"SELECT {select} FROM passages LEFT JOIN k ON device_id = k_device AND counting_head = k_head{where} "
        "ORDER BY k_rank NULLS LAST, start_ns",
        params=[[d for d, _ in rank], [n for _, n in rank], list(rank.values()), *params],
    ).to_arrow_table()
    if any(table.column(c).null_count for c in ("head", *ints, *texts, "subsecond", "n_speeds")):
        return None
    cols: Columns = {c: to_numpy(table.column(c)) for c in table.column_names if c != "axle_speeds_kmh"}
    if any((cols[c] < 0).any() for c in texts):
        return None
    cols["subsecond"] = cols["subsecond"].astype(bool)
    n = cols.pop("n_speeds")
    stop = np.cumsum(n)
    speeds = list_values(table.column("axle_speeds_kmh")).astype(np.float64)
    if len(speeds) != (int(stop[-1]) if len(stop) else 0):
        return None
    cols["axle_speeds_start"], cols["axle_speeds_stop"] = stop - n, stop
    cols["axle_speeds_kmh"] = speeds
    return cols


def _passages(con: duckdb.DuckDBPyConnection, window: Window, heads: list[tuple[int, Any]]) -> pd.DataFrame:
    """The window's passages as ``DiagAnalysis.passages`` gives them (per-axle speeds in ``attrs``)."""
    import pandas as pd

    from console.analysis.passages.passage_frame import PASSAGE_COLUMNS

    where, params = _where(window, "start_ns")
    columns = [c for c in PASSAGE_COLUMNS if c not in ("axle_speeds_start", "axle_speeds_stop")]
    names = con.sql("SELECT * FROM passages LIMIT 0").columns
    if "axle_speeds_kmh" not in names:  # no passage at all: the view has the empty table's columns
        return pd.DataFrame(columns=list(PASSAGE_COLUMNS))
    # The analysis' passages hold floats (NaN where there is none) where the archive stores integers.
    as_float = {"detection_second_ns", "records_in_detection_second"}
    select = ", ".join(f'"{c}"::DOUBLE AS "{c}"' if c in as_float else f'"{c}"' for c in [*columns, "axle_speeds_kmh"])
    query = con.sql(f"SELECT {select} FROM passages{where} ORDER BY start_ns", params=params)
    table = query.to_arrow_table()
    # Arrow's columns as DuckDB's DataFrame gives them (an empty one has no string dtype to take).
    df = table.drop_columns(["axle_speeds_kmh"]).to_pandas() if table.num_rows else query.df()
    # The batch lists passages head by head (heads in the order they first appear), each in time order:
    # each (device, head) pair of the window looked up once.
    device_code, devices = pd.factorize(df["device_id"], use_na_sentinel=False)
    name_code, names = pd.factorize(df["counting_head"], use_na_sentinel=False)
    pair_code, pairs = pd.factorize(device_code.astype(np.int64) * max(len(names), 1) + name_code)
    index = {h: i for i, h in enumerate(heads)}

    def rank(pair: int) -> int:
        name = names[pair % len(names)]
        return index.get((int(devices[pair // len(names)]), None if name != name else name), len(index))

    pair_rank = np.array([rank(k) for k in pairs.tolist()], np.int64)
    order = np.argsort(pair_rank[pair_code], kind="stable")
    df = df.iloc[order].reset_index(drop=True)
    speeds = table.column("axle_speeds_kmh").combine_chunks().take(order)
    n = speeds.value_lengths().fill_null(0).to_numpy().astype(np.int64)
    stop = np.cumsum(n)
    df.insert(columns.index("speed_kmh_per_axle_mean"), "axle_speeds_start", stop - n)
    df.insert(columns.index("speed_kmh_per_axle_mean") + 1, "axle_speeds_stop", stop)
    df = df[list(PASSAGE_COLUMNS)]
    df.attrs["axle_speeds_kmh"] = speeds.flatten().to_numpy(zero_copy_only=False).astype(np.float64)
    return df


def _inventory(
    con: duckdb.DuckDBPyConnection, window: Window, root: Path | None = None, manifest: Manifest | None = None
) -> list[DeviceInventory]:
    """The devices of the window's records, as the batch inventory gives them: per device and head, the
    figures of the window's whole days as derived at ingest (:mod:`console.archive.head_days`, with
    ``manifest``), the rest aggregated over the records; the devices' figures gathered from their heads'."""
    import dataclasses
    import datetime as dt

    from console.analysis.inventory import IDENTITY_LABELS, DeviceInventory, IdentityValue, apply_identity
    from console.archive.head_days import IDENTITY_GROUP, head_rows_sql, identity_rows_sql, stored_rows, whole_days

    labels = sorted(IDENTITY_LABELS)
    days = whole_days(window.start, window.end) if root is not None and manifest is not None else None
    stored = (
        stored_rows(con, root, manifest, days, window.head, window.device_id) if days and root and manifest else None
    )
    per_head: list[tuple[Any, ...]] = []
    ident_rows: list[tuple[Any, ...]] = []
    pieces = [window]
    if days is not None and stored is not None:
        per_head, ident_rows = list(stored[0]), list(stored[1])
        lo, hi = (dt.datetime.combine(d, dt.time()) for d in days)
        pieces = [
            w
            for w in (dataclasses.replace(window, end=lo), dataclasses.replace(window, start=hi))
            if w.start is not None and w.end is not None and w.start < w.end
        ]
    for piece in pieces:
        where, params = piece.where()
        # The first record's names: arg_min over the read position (a line is one record: no ties), cheaper
        # than an ordered first().
        per_head += con.execute(head_rows_sql(where) + " GROUP BY device_id, counting_head", params).fetchall()
        # Identity registers: each one's latest value (by time; ties: the later line).
        ident_where = where + (" AND " if where else " WHERE ") + "label_canonical IN (SELECT unnest(?))"
        ident_rows += con.execute(
            identity_rows_sql(ident_where) + f" GROUP BY {IDENTITY_GROUP}", [*params, labels]
        ).fetchall()
    if not per_head:
        return []
    # Per (device, head): its pieces (days, partial days) gathered; then in the order heads first appear.
    merged: dict[tuple[Any, Any], list[Any]] = {}
    for device_id, head, first, device, type_, gs, diag_ids, channels, n, t0, t1 in per_head:
        row = merged.get((device_id, head))
        if row is None:
            merged[(device_id, head)] = [first, device, type_, gs, set(diag_ids), set(channels), n, t0, t1]
            continue
        if first < row[0]:
            row[0:4] = [first, device, type_, gs]
        row[4].update(diag_ids)
        row[5].update(channels)
        row[6] += n
        row[7] = t0 if row[7] is None or (t0 is not None and t0 < row[7]) else row[7]
        row[8] = t1 if row[8] is None or (t1 is not None and t1 > row[8]) else row[8]
    # Heads per device in the order they first appear (the batch numbers heads so).
    heads: dict[int, list[str]] = {}
    rows = []
    for (device_id, head), (_, device, type_, gs, diag_ids, channels, n, first, last) in sorted(
        merged.items(), key=lambda kv: (kv[0][0], kv[1][0])
    ):
        device_id = int(device_id)
        if device_id not in heads:
            heads[device_id] = []
            rows.append([device_id, device, type_, gs, diag_ids, channels, n, first, last])
        else:
            row = rows[-1]
            row[4].update(diag_ids)
            row[5].update(channels)
            row[6] += n
            row[7], row[8] = min(row[7], first), max(row[8], last)
        heads[device_id].append(head)
    # Per register, its latest value among the pieces (time, then file and line).
    latest: dict[tuple[Any, ...], tuple[Any, ...]] = {}
    for r in ident_rows:
        key = r[:11]
        if key not in latest or _recency(r) > _recency(latest[key]):
            latest[key] = r
    # Most recently read first (time, file, line: no two records share a line), so that where a device's
    # heads give one register different values the latest reading is the device's, whatever order DuckDB
    # gave the groups in (it gave them in a different order from run to run).
    identity: dict[int, list[IdentityValue]] = {}
    for r in sorted(latest.values(), key=_recency, reverse=True):
        device_id, canonical, address, value, kind, data = r[0], r[9], r[7], r[11], r[12], r[13]
        identity.setdefault(int(device_id), []).append(
            IdentityValue(str(canonical), int(address), int(value), str(kind), str(data))
        )
    out = []
    for device_id, device, type_, gs, diag_ids, channels, n, first, last in rows:
        inv = DeviceInventory(
            device_id=int(device_id),
            device=str(device),
            type=str(type_),
            gs=str(gs),
            diag_ids=sorted(int(x) for x in diag_ids),
            counting_heads=heads.get(int(device_id), []),
            channels=sorted(int(x) for x in channels),
            records=int(n),
            first_ns=_ns(first),
            last_ns=_ns(last),
        )
        values = identity.get(int(device_id))
        if values:
            apply_identity(inv, values)
        out.append(inv)
    return out


def _sections(
    con: duckdb.DuckDBPyConnection, manifest: Manifest, layout: Layout | None, window: Window
) -> SectionsResult | None:
    """The section history cut to the window; the final state at its end (stored for the whole history)."""
    if layout is None or not layout.sections:
        return None
    import pandas as pd

    from console.analysis.sections.engine import SectionEngine, SectionsResult
    from console.analysis.sections.state import SectionState

    where, params = _where(window, "time_ns", heads=False)
    order = [s.id for s in layout.sections] if layout is not None else []
    timeline = _rows(con, "section_states", ["time_ns", "section", "state", "count", "reason"], where, params, order)
    ledger = _rows(con, "count_ledger", ["time_ns", "section", "head", "delta", "count"], where, params, order)
    resets = pd.DataFrame(columns=["time_ns", "section", "accepted", "reason"])
    if window.start is None and window.end is None:
        stored = manifest.derived["sections_final"]
        whole = {sid: (str(v[0]), int(v[1]), int(v[2]), int(v[3]), str(v[4])) for sid, v in stored.items()}
        return SectionsResult(timeline, ledger, resets, whole)
    # The state at the window's end: the last change before it (else the state the engine starts in),
    # the count of the last axle before it; axles in and out counted within the window.
    end_where, end_params = _where(Window(end=window.end), "time_ns", heads=False)
    start = SectionEngine(layout, initial=SectionState.PREPARATORY, start_ns=0).sections
    final: dict[str, tuple[str, int, int, int, str]] = {
        sid: (str(s.state), s.count, 0, 0, s.reason) for sid, s in start.items()
    }
    for sid, state, count, reason in _last_rows(con, "section_states", "state, count, reason", end_where, end_params):
        if sid in final:
            final[sid] = (str(state), int(count), 0, 0, str(reason))
    if len(ledger):
        counts = {sid: c for sid, c in _last_rows(con, "count_ledger", "count", end_where, end_params)}
        inward = ledger[ledger["delta"] > 0].groupby("section").size()
        outward = ledger[ledger["delta"] < 0].groupby("section").size()
        for sid, (state, count, _, _, reason) in list(final.items()):
            final[sid] = (
                state,
                int(counts.get(sid, count)),
                int(inward.get(sid, 0)),
                int(outward.get(sid, 0)),
                reason,
            )
    return SectionsResult(timeline, ledger, resets, final)


def _last_rows(
    con: duckdb.DuckDBPyConnection, table: str, columns: str, where: str, params: list[Any]
) -> list[tuple[Any, ...]]:
    """Per section, its last row (in the table's order: the engine's) among those ``where`` selects."""
    if "time_ns" not in con.sql(f"SELECT * FROM {table} LIMIT 0").columns:
        return []
    latest = con.execute(f"SELECT section, max(time_ns) FROM {table}{where} GROUP BY section", params).fetchall()
    if not latest:
        return []
    last_ns = dict(latest)
    # Rows at those instants, in the engine's order (the rows' sequence): the last per section wins.
    seq = "seq" if "seq" in con.sql(f"SELECT * FROM {table} LIMIT 0").columns else "0"
    out: dict[Any, tuple[Any, ...]] = {}
    for row in con.execute(
        f"SELECT section, time_ns, {columns} FROM {table} WHERE time_ns IN (SELECT unnest(?)) ORDER BY {seq}",
        [sorted(set(last_ns.values()))],
    ).fetchall():
        if last_ns.get(row[0]) == row[1]:
            out[row[0]] = (row[0], *row[2:])
    return list(out.values())


def _rows(
    con: duckdb.DuckDBPyConnection, table: str, columns: list[str], where: str, params: list[Any], order: list[str]
) -> pd.DataFrame:
    """A derived table's rows in time order (an empty table when it has none: no rows were ever derived)."""
    import pandas as pd

    have = set(con.sql(f"SELECT * FROM {table} LIMIT 0").columns)
    if not set(columns) <= have:
        return pd.DataFrame(columns=columns)
    # By time; at one instant the sections in the layout's order, each section's rows in the engine's.
    rank = "CASE section " + " ".join(f"WHEN ? THEN {i}" for i in range(len(order))) + " END" if order else "0"
    seq = "seq" if "seq" in have else "0"
    sql = f"SELECT {', '.join(columns)} FROM {table}{where} ORDER BY time_ns, {rank}, {seq}"
    return con.execute(sql, [*params, *order]).df()


def channel_events(root: Path, manifest: Manifest, window: Window) -> list[DetectionEvent]:
    """The stored channel events (the events health reads) in the window, in time order."""
    import pyarrow.parquet as pq

    from console.analysis.events.detection import DetectionEvent, EventKind

    out: list[DetectionEvent] = []
    lo = _ns(window.start) if window.start is not None else None
    hi = _ns(window.end) if window.end is not None else None
    for rel in manifest.parts("channel_events"):
        t = pq.read_table(root / rel).to_pylist()
        for r in t:  # channel events are rare: a few per fault
            if (lo is not None and r["time_ns"] < lo) or (hi is not None and r["time_ns"] >= hi):
                continue
            if window.head is not None and r["head"] != window.head:
                continue
            out.append(
                DetectionEvent(
                    int(r["time_ns"]),
                    EventKind(r["kind"]),
                    r["head"],
                    int(r["direction"]),
                    None if r["channel"] is None else int(r["channel"]),
                    r["source"],
                    r["detail"],
                )
            )
    out.sort(key=lambda e: e.time_ns)  # parts per day and ingest; within one, in the pipeline's order
    return out


def _recency(row: tuple[Any, ...]) -> tuple[Any, ...]:
    """An identity row's (time, file, line) read, in an order without None (an untimed register's: first)."""
    at_time, file_seq, line = row[14:17]
    return (at_time is not None, at_time if at_time is not None else 0, file_seq or 0, line or 0)
