"""Derived tables: what the batch analyses compute on the archive's inputs read together.

Two steps, at each ingest that adds something:

1. **Per partition** (device, day), through :mod:`console.archive.partition`:
   passages, axles and the wheel-sensor records the section engine needs,
   with the state over midnight carried.  Only the partitions the ingest
   touched are derived again — those whose records parts changed, the day
   after each (it reads the changed day as its "day before") and the earlier
   days whose passages may run into a changed day (their last passage ends
   within an idle gap of its midnight) — the others are kept as they are.
   Each partition's rows are stored in ``data/<table>/day=…/device_id=…/``
   parts; ``manifest.derived["partitions"]`` records, per partition, the
   records parts it was derived from (a hash), the generation that derived it
   (its parts' names follow: :func:`partition_parts`), the tables it has rows
   in, its heads' first records and how far its passages reach.
2. **Across heads** (section states, the count ledger, health findings,
   crossing timelines): computed over the whole archive from the combined
   per-partition rows — the wheel records become detection events, as
   :func:`console.jobs.detection_events` does on a batch analysis — and the
   health registers' records (read alone, by label), by
   :func:`console.archive.history.report_data`, never re-reading every record.

The equality with the batch analysis of all files read together is the
property tested in tests/test_archive_equality.py and
tests/test_archive_incremental.py.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import hashlib
import itertools
import os
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from console.archive.partition import (
    NS_PER_DAY,
    DerivedRows,
    PartitionKey,
    carried_state,
    key_of_part,
    make_tasks,
    partitions,
    run_task,
)
from console.archive.parts import write_part, write_small
from console.archive.store import DATA, Manifest
from console.memory import trim_heap

if TYPE_CHECKING:
    from console.analysis.diagnostics import DiagAnalysis, SpeedSettings
    from console.drivers.batch import DiagJob

DERIVED = ("passages", "axles", "section_states", "count_ledger", "crossing_timelines", "health_findings")
# Stored per (day, device) partition; wheel_records is the section engine's input (not a query view).
PER_PARTITION = ("passages", "axles", "wheel_records")
CROSS_HEAD = ("section_states", "count_ledger", "crossing_timelines", "health_findings", "channel_events")
# Bump when the per-partition rows change meaning: every partition is then derived again.
# 3: passages carry their per-axle speeds; channel events and the sections' final state kept (report --archive).
DERIVE_VERSION = 3

# mapper(fn, items) → the results in the order of items (a list, or an iterator giving them as they come).
Mapper = Callable[[Callable[..., Any], list[Any]], Iterable[Any]]


def _arrow(df: pd.DataFrame) -> pa.Table:
    df = df.copy()
    df.attrs = {}  # per-axle speed lists of passages: not a column, not archived
    for c in df.columns:
        if df[c].dtype != object:
            continue
        if df[c].isna().all():
            # No value at all: the column still gets its type (numbers for units, text otherwise).
            df[c] = df[c].astype("float64" if c.endswith(("_s", "_ns", "_m", "_kmh")) else "string")
            continue
        try:
            pa.array(df[c], from_pandas=True)  # plain values (text, numbers, dates): as they are
        except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
            df[c] = df[c].map(
                lambda v: None if v is None else v if isinstance(v, str | int | float | bool | dt.date) else str(v)
            )
    return pa.Table.from_pandas(df, preserve_index=False)


def tables_from(data: Any) -> dict[str, pd.DataFrame]:
    """The derived tables of one ReportData, as DataFrames (times as ns integers and timestamps)."""
    out: dict[str, pd.DataFrame] = {}
    job = data.job
    if job is not None:
        p = job.analysis.passages.copy()
        p["start"] = pd.to_datetime(p["start_ns"], unit="ns")
        out["passages"] = p
        ax = job.analysis.axles.copy()
        heads = job.analysis.heads
        if len(ax):
            ax["device_id"] = np.array([h[0] for h in heads], np.int64)[ax["head"].to_numpy()]
            ax["counting_head"] = np.array([h[1] for h in heads], object)[ax["head"].to_numpy()]
        else:
            ax["device_id"] = pd.Series(dtype="int64")
            ax["counting_head"] = pd.Series(dtype=object)
        ax["time"] = pd.to_datetime(ax["time_ns"], unit="ns")
        out["axles"] = ax.drop(columns=["head"])
    out.update(cross_head_tables(data))
    return out


def cross_head_tables(data: Any) -> dict[str, pd.DataFrame]:
    """Section states, count ledger, health findings and crossing timelines of one ReportData."""
    out: dict[str, pd.DataFrame] = {}
    if data.sections is not None:
        tl = data.sections.timeline.copy()
        tl["time"] = pd.to_datetime(tl["time_ns"], unit="ns")
        out["section_states"] = tl
        led = data.sections.ledger.copy()
        led["time"] = pd.to_datetime(led["time_ns"], unit="ns")
        out["count_ledger"] = led
    if data.findings:
        out["health_findings"] = pd.DataFrame([f.to_dict() for f in data.findings])
    if data.crossing is not None and data.crossing.timelines:
        rows = []
        for r in data.crossing.timelines:
            d = dict(r.__dict__)
            d["alarms"] = "; ".join(r.alarms)
            d["violations"] = "; ".join(r.violations)
            late_by = d.get("late_by_s")
            d["late"] = bool(r.violations) or (late_by is not None and late_by > 0)
            rows.append(d)
        ct = pd.DataFrame(rows)
        for c in ("t_on_ns", "t_head_arrival_ns", "t_tail_clear_ns", "t_off_ns", "baseline_off_ns"):
            ct[c] = ct[c].astype("Int64")
            ct[c.replace("_ns", "")] = pd.to_datetime(ct[c], unit="ns")
        out["crossing_timelines"] = ct
    return out


@dataclass
class _WheelAnalysis:
    """What :func:`console.jobs.detection_events` reads of a DiagAnalysis: the heads (in the batch's order,
    first record first) and each head's wheel-sensor records (in the batch's order)."""

    heads: list[tuple[int, str]]
    wheel_records: pd.DataFrame
    activity: pd.DataFrame = field(default_factory=pd.DataFrame)


def _signature(parts: Iterable[str]) -> str:
    return hashlib.sha256("\n".join(sorted(parts)).encode()).hexdigest()[:20]


def _fingerprint(settings: SpeedSettings) -> dict[str, Any]:
    return {"version": DERIVE_VERSION, "settings": dataclasses.asdict(settings)}


def affected_partitions(
    keys: Iterable[PartitionKey],
    changed: Iterable[PartitionKey],
    info: dict[str, dict[str, Any]],
    idle_gap_s: float,
) -> set[PartitionKey]:
    """The partitions to derive again when ``changed`` (records added, removed, or new) changed.

    A partition's rows depend on its own records, the whole day before (is
    its first passage a continuation?) and the days after as far as its
    passages run.  So: each changed partition that still exists, the day
    after it, and the earlier days of its device (consecutive) whose
    passages, as last derived (``info[..]["reach_ns"]``: the latest end of a
    passage starting there), end within an idle gap of its midnight.
    """
    have = set(keys)
    one = dt.timedelta(days=1)
    idle_ns = int(idle_gap_s * 1e9)
    by_device: dict[int, list[dt.date]] = {}
    for k in have:
        by_device.setdefault(k.device_id, []).append(k.day)
    # Per key, the latest reach of its day and the consecutive days before it (a running maximum).
    reach_upto: dict[PartitionKey, int] = {}
    for dev, days in by_device.items():
        running: int | None = None
        prev: dt.date | None = None
        for d in sorted(days):
            k = PartitionKey(dev, d)
            r = info.get(k.name, {}).get("reach_ns")
            if prev is None or prev + one != d:
                running = None
            if r is not None:
                running = int(r) if running is None else max(running, int(r))
            if running is not None:
                reach_upto[k] = running
            prev = d
    out: set[PartitionKey] = set()
    for k in changed:
        if k in have:
            out.add(k)
        after = PartitionKey(k.device_id, k.day + one)
        if after in have:
            out.add(after)
        midnight = (k.day - dt.date(1970, 1, 1)).days * NS_PER_DAY
        e = PartitionKey(k.device_id, k.day - one)
        while e in have and reach_upto.get(e, -(1 << 62)) + idle_ns >= midnight:
            if int(info.get(e.name, {}).get("reach_ns") or -(1 << 62)) + idle_ns >= midnight:
                out.add(e)
            e = PartitionKey(e.device_id, e.day - one)
    return out


def _part_path(table: str, key: PartitionKey, generation: int) -> str:
    return os.path.join(
        DATA, table, f"day={key.day.isoformat()}", f"device_id={key.device_id}", f"g{generation:06d}-d.parquet"
    )


def _store_partition(root: Path, key: PartitionKey, rows: DerivedRows, generation: int) -> dict[str, str]:
    """Write one partition's passages, axles and wheel records; the parts written per table."""
    frames: dict[str, pd.DataFrame] = {}
    p = rows.passages.drop(columns=["_key_day"], errors="ignore")
    if len(p):
        p = p.sort_values("start_ns", kind="stable").reset_index(drop=True)
        p["day"] = key.day
        frames["passages"] = p
    ax = rows.axles.drop(columns=["_key_day"], errors="ignore")
    if len(ax):
        ax = ax.sort_values("time_ns", kind="stable").reset_index(drop=True)
        ax["day"] = key.day
        frames["axles"] = ax
    wheel = rows.wheel.drop(columns=["_key_day"], errors="ignore")
    if len(wheel):
        frames["wheel_records"] = wheel.reset_index(drop=True)  # the batch's order: kept
    out: dict[str, str] = {}
    for table, df in frames.items():
        rel = _part_path(table, key, generation)
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        out[table] = write_part(root, rel, _arrow(df))
    return out


def partition_parts(name: str, info: dict[str, Any]) -> dict[str, str]:
    """A derived partition's parts per table, from its ``manifest.derived["partitions"]`` entry."""
    key = PartitionKey.parse(name)
    return {table: _part_path(table, key, int(info["generation"])) for table in info.get("tables", ())}


def _heads_of(rows: DerivedRows) -> list[list[Any]]:
    h = rows.heads
    return [
        [None if name is None or name != name else str(name), int(seq), int(line)]
        for name, seq, line in zip(h["counting_head"], h["first_file_seq"], h["first_line"], strict=True)
    ]


def _reach(rows: DerivedRows) -> int | None:
    return int(rows.passages["end_ns"].max()) if len(rows.passages) else None


def _results(mapper: Mapper | None, tasks: list[Any]) -> Iterator[DerivedRows]:
    """The tasks' rows in task order, as the mapper gives them (fleet_mapper: one at a time)."""
    if mapper is None:
        yield from (run_task(t) for t in tasks)
        return
    yield from mapper(run_task, tasks)


def derive_tables(
    root: Path,
    manifest: Manifest,
    layout: str | None,
    *,
    mapper: Mapper | None = None,
) -> list[str]:
    """Derive the tables into new parts of ``manifest`` (not yet published); the parts written.

    Passages, axles and wheel records are derived again only for the
    partitions the records changed (see :func:`affected_partitions`); the
    cross-head tables are computed from all partitions' rows.  ``mapper``:
    how the partition tasks run, ``mapper(run_task, tasks)`` returning the
    results in task order (the Dask engine); else one after the other here.
    """
    from console.archive.history import _layout, speed_settings

    spec = layout if layout is not None else manifest.derived.get("layout")
    settings = speed_settings(manifest, _layout(spec))
    fingerprint = _fingerprint(settings)
    old = manifest.derived
    info: dict[str, dict[str, Any]] = dict(old.get("partitions", {})) if old.get("fingerprint") == fingerprint else {}
    gen = manifest.generation
    written: list[str] = []

    parts_of: dict[str, list[str]] = {}
    for rel in manifest.parts("records"):
        k = key_of_part(rel)
        if k is not None:
            parts_of.setdefault(k.name, []).append(rel)
    keys = partitions(manifest)
    signature = {k.name: _signature(parts_of[k.name]) for k in keys}
    changed = [k for k in keys if info.get(k.name, {}).get("records") != signature[k.name]]
    changed += [PartitionKey.parse(n) for n in info if n not in signature]
    redo = affected_partitions(keys, changed, info, settings.idle_gap_s)

    # Parts of partitions derived again, or gone, leave the manifest; so does anything not per partition
    # (an archive derived whole by an older trackside, or with other settings).
    keep = {n: i for n, i in info.items() if n in signature and PartitionKey.parse(n) not in redo}
    kept_parts = {rel for n, i in keep.items() for rel in partition_parts(n, i).values()}
    for table in PER_PARTITION:
        manifest.tables[table] = [rel for rel in manifest.parts(table) if rel in kept_parts]

    carried = carried_state(keys)
    tasks = make_tasks(root, manifest, redo, carried, settings)
    # One task's rows at a time (stored, then dropped): the cross-head step reads them back from their parts.
    for _task, rows in zip(tasks, _results(mapper, tasks), strict=True):  # strict: one result per task
        for key, one in rows.split().items():
            stored = _store_partition(root, key, one, gen)
            for table, rel in stored.items():
                manifest.tables[table].append(rel)
                written.append(rel)
            keep[key.name] = {
                "records": signature[key.name],
                "generation": gen,
                "reach_ns": _reach(one),
                "heads": _heads_of(one),
                "tables": sorted(stored),  # its parts: partition_parts
                "overlap": one.overlap.get(key.name, 0),  # records set aside as another file's overlap
            }
        del rows
        trim_heap()  # a task's working memory given back before the next one's (RSS would keep the highest)
    manifest.derived = {
        "layout": spec,
        "tables": list(DERIVED),
        "fingerprint": fingerprint,
        "partitions": {k: keep[k] for k in sorted(keep)},
    }

    written += _derive_cross_head(root, manifest, spec, keys)
    return written


def _head_order(manifest: Manifest, keys: list[PartitionKey]) -> list[tuple[int, Any]]:
    """The heads in the batch's order (first record first), from the partitions' entries."""
    info = manifest.derived["partitions"]
    first: dict[tuple[int, Any], tuple[int, int]] = {}
    for k in keys:
        for name, seq, line in info[k.name]["heads"]:
            h = (k.device_id, name)
            first[h] = min(first.get(h, (seq, line)), (seq, line))
    return sorted(first, key=lambda h: first[h])


def _wheel_of(root: Path, manifest: Manifest, key: PartitionKey, columns: list[str] | None = None) -> pd.DataFrame:
    """A partition's stored wheel records (in the batch's order), empty when it has none."""
    import pyarrow.parquet as pq

    rel = partition_parts(key.name, manifest.derived["partitions"][key.name]).get("wheel_records")
    if rel is None:
        return pd.DataFrame(columns=columns or ["device_id", "counting_head"])
    return pq.read_table(root / rel, columns=columns).to_pandas()


def _head_index(wheel: pd.DataFrame, index: dict[tuple[int, Any], int]) -> np.ndarray:
    """Each row's head index: factorized (device, head) pairs, then one lookup per distinct head."""
    if not len(wheel):
        return np.zeros(0, np.int64)
    pairs = pd.MultiIndex.from_arrays(
        [wheel["device_id"].to_numpy(np.int64), wheel["counting_head"].astype(object).to_numpy()]
    )
    codes, distinct = pd.factorize(pairs)
    lut = np.array([index[(int(d), None if n != n else n)] for d, n in distinct], np.int64)
    return cast("np.ndarray", lut[codes])


def _combined_job(root: Path, manifest: Manifest, keys: list[PartitionKey]) -> DiagJob | None:
    """A DiagJob holding what the cross-head analyses read: heads, wheel records, health-register records."""
    from console.archive.history import health_records
    from console.drivers.batch import DiagJob
    from parsers.report import ParseReport

    if not keys:
        return None
    heads = _head_order(manifest, keys)
    index = {h: i for i, h in enumerate(heads)}
    frames = [w for k in keys if len(w := _wheel_of(root, manifest, k))]  # per head, day after day
    wheel = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=["device_id", "counting_head"])
    records = pd.DataFrame(
        {
            "head": _head_index(wheel, index),
            "channel": wheel.get("channel", pd.Series(dtype="int64")).to_numpy(),
            "time_ns": wheel.get("time_ns", pd.Series(dtype="int64")).to_numpy(np.int64),
            "value": wheel.get("value", pd.Series(dtype="int64")).to_numpy(),
            "subsecond": wheel.get("subsecond", pd.Series(dtype=bool)).to_numpy(),
        }
    )
    view = _WheelAnalysis(heads=heads, wheel_records=records)
    return DiagJob(
        files=[], report=ParseReport(), analysis=cast("DiagAnalysis", view), kept_records=health_records(root, manifest)
    )


def _health_job(root: Path, manifest: Manifest, heads: list[tuple[int, Any]]) -> DiagJob:
    """A DiagJob with the heads and the health registers' records, no wheel record (they were streamed)."""
    from console.archive.history import health_records
    from console.drivers.batch import DiagJob
    from parsers.report import ParseReport

    empty = pd.DataFrame(
        {c: pd.Series(dtype=t) for c, t in (("head", "int64"), ("channel", "int64"), ("time_ns", "int64"))}
        | {"value": pd.Series(dtype="int64"), "subsecond": pd.Series(dtype=bool)}
    )
    view = _WheelAnalysis(heads=heads, wheel_records=empty)
    return DiagJob(
        files=[], report=ParseReport(), analysis=cast("DiagAnalysis", view), kept_records=health_records(root, manifest)
    )


@dataclass
class _Plan:
    """The streamed cross-head step's read plan: the days' partitions, where each day's wheel records
    start, and the per-head facts the batch path takes from all of a head's records."""

    days: list[list[PartitionKey]]
    starts: list[int]  # per day, its earliest wheel record (ALL_TIME: none)
    facts: dict[int, Any]  # head index → HeadFacts


def _plan(root: Path, manifest: Manifest, keys: list[PartitionKey], index: dict[tuple[int, Any], int]) -> _Plan | None:
    """One read of the wheel records' keys and times; None when a head's records go back in time from one
    day's partition to a later one's (the batch path's per-head time sort would interleave them)."""
    from console.analysis.stream_sections import ALL_TIME, HeadFacts

    by_day: dict[dt.date, list[PartitionKey]] = {}
    for k in keys:
        by_day.setdefault(k.day, []).append(k)
    days = [sorted(by_day[d]) for d in sorted(by_day)]
    latest: dict[int, int] = {}  # head → its latest record so far
    release: set[int] = set()
    whole: set[int] = set()
    starts: list[int] = []
    for group in days:
        start = ALL_TIME
        ends: dict[int, int] = {}
        for k in group:
            w = _day_arrays(root, manifest, [k], index)
            if not len(w["head"]):
                continue
            hi, t, v, sub = w["head"], w["time_ns"], w["value"], w["subsecond"]
            for h in np.unique(hi).tolist():
                m = hi == h
                th = t[m]
                lo, hi_t = int(th.min()), int(th.max())
                if h in latest and lo < latest[h]:
                    return None
                ends[h] = max(ends.get(h, hi_t), hi_t)
                start = min(start, lo)
                if (v[m] == 0).any():
                    release.add(h)
                if not sub[m].all():
                    whole.add(h)
        latest.update(ends)
        starts.append(start)
    facts = {h: HeadFacts(point_mode=h not in release, whole_second=h in whole) for h in range(len(index))}
    return _Plan(days, starts, facts)


# Wheel records fed to the event stream between two releases (about: a day is cut in equal times).
SLICE_ROWS = 100_000


def _day_arrays(
    root: Path, manifest: Manifest, group: list[PartitionKey], index: dict[tuple[int, Any], int]
) -> dict[str, np.ndarray]:
    """One day's wheel records (its partitions in key order, each in the batch's order) as compact arrays."""
    import pyarrow.parquet as pq

    cols: dict[str, list[np.ndarray]] = {c: [] for c in ("head", "channel", "time_ns", "value", "subsecond")}
    info = manifest.derived["partitions"]
    for k in group:
        rel = partition_parts(k.name, info[k.name]).get("wheel_records")
        if rel is None:
            continue
        t = pq.read_table(root / rel, columns=["counting_head", "channel", "time_ns", "value", "subsecond"])
        if not t.num_rows:
            continue
        # Every row is of the partition's device: the head from the name's dictionary code.
        names = pc.dictionary_encode(t["counting_head"]).combine_chunks()
        lut = np.array([index[(k.device_id, n)] for n in names.dictionary.to_pylist()] or [0], np.int32)
        codes = names.indices.to_numpy(zero_copy_only=False)
        if names.null_count:
            codes = np.where(names.is_null().to_numpy(zero_copy_only=False), len(lut), codes)
            lut = np.r_[lut, np.int32(index[(k.device_id, None)])]
        cols["head"].append(lut[codes.astype(np.int64)])
        cols["channel"].append(t["channel"].to_numpy().astype(np.int16))
        cols["time_ns"].append(t["time_ns"].to_numpy().astype(np.int64))
        cols["value"].append(t["value"].to_numpy().astype(np.int8))
        cols["subsecond"].append(t["subsecond"].to_numpy().astype(bool))
        del t, names
    if not cols["head"]:
        return {"head": np.zeros(0, np.int32), "time_ns": np.zeros(0, np.int64)}
    return {c: np.concatenate(v) for c, v in cols.items()}


class _HistoryWriter:
    """The section engine's history (state timeline, count ledger) written out as it is made."""

    def __init__(self, root: Path, generation: int) -> None:
        from console.archive.parts import PartWriter

        self.writers = {
            name: PartWriter(root, name, generation, "d", by_device=False, by_day=False)
            for name in ("section_states", "count_ledger")
        }

    @staticmethod
    def _timed(df: pd.DataFrame) -> pa.Table:
        df["time"] = pd.to_datetime(df["time_ns"], unit="ns")
        df["day"] = df["time"].dt.date
        return _arrow(df)

    def take(self, engine: Any) -> None:
        if engine.transitions:
            trs, engine.transitions = engine.transitions, []
            df = pd.DataFrame(
                [(t.time_ns, t.section, str(t.state), t.count, t.reason) for t in trs],
                columns=["time_ns", "section", "state", "count", "reason"],
            )
            self.writers["section_states"].add(self._timed(df))
        if engine.ledger:
            led, engine.ledger = engine.ledger, []
            df = pd.DataFrame(
                [(x.time_ns, x.section, x.head, x.delta, x.count) for x in led],
                columns=["time_ns", "section", "head", "delta", "count"],
            )
            self.writers["count_ledger"].add(self._timed(df))
        engine.resets = []  # no operator reset in an archive: nothing to keep

    def close(self) -> dict[str, list[str]]:
        return {name: w.close() for name, w in self.writers.items()}

    def abort(self) -> None:
        for w in self.writers.values():
            w.abort()


def _stream_cross_head(
    root: Path, manifest: Manifest, layout: Any, keys: list[PartitionKey]
) -> tuple[DiagJob, tuple[list[Any], list[str], Any], dict[str, list[str]]] | None:
    """Detection events and section states in memory bounded by heads and one day's wheel records.

    The wheel records are read a day at a time (every device's partitions of
    that day) into :class:`console.analysis.stream_sections.EventStream`,
    events released below the next day's earliest record into the section
    engine, whose history is written out as it is made.  The events are the
    batch path's, in its order (``tests/test_stream_sections.py``); only the
    channel events health reads are kept.  None: not streamable (no
    diagnostic partition, three-element heads, a head whose records go back
    in time from one day to the next): the caller reads it whole.
    Returns (the job for health, (health events, warnings, sections result), parts per table).
    """
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.sections import SectionEngine, SectionState
    from console.analysis.stream_sections import EventStream
    from console.engine.pipeline import HEALTH_EVENT_KINDS

    if not keys or (layout is not None and any(h.channels == 3 for h in layout.heads)):
        return None
    heads = _head_order(manifest, keys)
    index = {h: i for i, h in enumerate(heads)}
    plan = _plan(root, manifest, keys, index)
    if plan is None:
        return None
    with_sections = layout is not None and bool(layout.sections)
    stream = EventStream(layout, DiagEventSettings(), facts=plan.facts)
    health: list[Any] = []
    engine: SectionEngine | None = None
    history = _HistoryWriter(root, manifest.generation) if with_sections else None

    def step(events: Any) -> None:
        # Events as columns (EventBlock): objects only for the health kinds, the engine takes the block.
        nonlocal engine
        health.extend(events.of_kinds(HEALTH_EVENT_KINDS).events())
        if history is None or not len(events):
            return
        if engine is None:
            engine = SectionEngine(layout, initial=SectionState.PREPARATORY, start_ns=int(events.time_ns[0]))
        engine.step_block(events)
        history.take(engine)

    # Where the records still to come start: the earliest of the days after.
    after = np.minimum.accumulate(np.array([*plan.starts[1:], np.iinfo(np.int64).max][::-1], np.int64))[::-1]
    try:
        for group, watermark in zip(plan.days, after.tolist(), strict=True):
            day = _day_arrays(root, manifest, group, index)
            # The day in time slices (each slice's rows in the batch's order), released slice by slice:
            # the events held wait for one slice, not the day.
            t = day["time_ns"]
            n = len(t)
            slices = max(1, n // SLICE_ROWS)
            if n:
                lo, hi = int(t.min()), int(t.max()) + 1
                cuts = [lo + (hi - lo) * i // slices for i in range(slices + 1)]
                for a, b in itertools.pairwise(cuts):
                    if a == b:
                        continue
                    m = (t >= a) & (t < b)
                    if m.any():
                        stream.add({c: v[m] for c, v in day.items()}, None, heads)
                    step(stream.release_block(min(b, watermark)))
            del day, t
            step(stream.release_block(watermark))
        step(stream.finish_block())
        if history is not None and engine is None:
            engine = SectionEngine(layout, initial=SectionState.PREPARATORY, start_ns=0)  # no event: as run_sections
            history.take(engine)
    except BaseException:
        if history is not None:
            history.abort()
        raise
    parts = history.close() if history is not None else {}
    result = engine.result([], [], []) if engine is not None else None
    return _health_job(root, manifest, heads), (health, stream.warnings(heads), result), parts


def _channel_events(events: Iterable[Any]) -> pd.DataFrame:
    """The events health judges (channel faults and recoveries, single-channel pulses), as a table."""
    from console.analysis.events import EVENT_COLUMNS
    from console.engine.pipeline import HEALTH_EVENT_KINDS

    rows = [
        (e.time_ns, str(e.kind), e.head, e.direction, e.channel, e.source, e.detail)
        for e in events
        if e.kind in HEALTH_EVENT_KINDS
    ]
    df = pd.DataFrame(rows, columns=list(EVENT_COLUMNS))
    df["channel"] = df["channel"].astype("Int64")
    return df


def _derive_cross_head(root: Path, manifest: Manifest, spec: str | None, keys: list[PartitionKey]) -> list[str]:
    from console.archive.history import _layout, report_data

    for name in CROSS_HEAD:
        manifest.tables[name] = []
    streamed = _stream_cross_head(root, manifest, _layout(spec), keys)
    written: list[str] = []
    if streamed is not None:
        job, events, history = streamed
        data = report_data(root, spec, manifest=manifest, job=job, streamed=events)
        for name, rels in history.items():
            manifest.tables[name] = list(rels)
            written += rels
        frames = {k: v for k, v in cross_head_tables(data).items() if k not in history}
        channel = events[0]
    else:
        data = report_data(root, spec, manifest=manifest, job=_combined_job(root, manifest, keys))
        frames = cross_head_tables(data)
        channel = data.events
    frames["channel_events"] = _channel_events(channel)
    # The report of the whole archive shows each section's final state (report --archive reads it here).
    final = data.sections.final if data.sections is not None else {}
    manifest.derived["sections_final"] = {sid: list(v) for sid, v in final.items()}
    time_col = {"section_states": "time_ns", "count_ledger": "time_ns", "channel_events": "time_ns"}
    for name in CROSS_HEAD:
        df = frames.get(name)
        if df is None or df.empty:
            continue
        if name in time_col:
            # One part per table, in time order with a day column: cross-head tables are rewritten whole.
            df = df.sort_values(time_col[name], kind="stable")
            df["day"] = pd.to_datetime(df[time_col[name]], unit="ns").dt.date
        rel = write_small(root, name, manifest.generation, "d", _arrow(df))
        if rel:
            manifest.tables[name] = [rel]
            written.append(rel)
    return written
