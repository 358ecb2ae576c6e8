"""Derived passages and axles per partition (device, day), with the state that crosses midnight carried.

The unit of work of the archive's derivation (issue 13's incremental derive,
issue 15's Dask engine)::

    keys = partitions(manifest)                  # every (device_id, day) holding records
    carried = carried_state(keys)                # per key: the day before, the days after
    rows = derive_partition(root, manifest, key, carried[key], settings)   # pure: reads, computes, writes nothing
    tables = combine(rows_list)                  # passages, axles, wheel records, heads: one DataFrame each

:func:`derive_partition` returns the rows of the passages that *start* in
its day (UTC day of the naive log time, the records' ``day`` partition),
with their axles and wheel-sensor records, computed by the batch analysis
(:class:`~console.analysis.diagnostics.DiagAccumulator`) over a window of
the device's records:

* **before**: the whole day before, when the device has records that day.
  A passage open at midnight began there: in the window its records come
  before the day's, so the day's first records are not taken for a new
  passage.  Passage boundaries are idle gaps, which do not depend on where
  a window starts, and a gap of a whole day is always a boundary (the idle
  gap is seconds), so the day before is enough.
* **after**: the days after, one at a time, while a passage started in the
  day still has records on the last day of the window (a passage over
  midnight, or one longer than a day).

So the result does not depend on how the history was split: the property
test (tests/test_archive_derive.py) derives simulator logs that run over
midnight per partition and compares with ``analyze`` of the whole file.
:func:`derive_run` does several consecutive days of one device in one window
(the local engine's batches: each record is read about once, where one
window per day reads each day three times).

The cross-head tables (section states, the count ledger, health findings,
crossing timelines) are not per partition: see :mod:`console.archive.derive`.
"""

from __future__ import annotations

import datetime as dt
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from console.archive.store import Manifest
from console.memory import read_memory, trim_heap

if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.diagnostics import DiagAnalysis, SpeedSettings

NS_PER_DAY = 86_400 * 1_000_000_000
# Records a partition task analyses at most (but for one busy day alone): a task's memory grows with
# its records, about 0.5 kB each at the peak (an 8-day window of a device writing 75 k records a day
# peaked at 484 MB; 4 days, 322 MB), and a Dask worker is bounded to 512 MB.
TASK_RECORDS = 300_000
_KEY_IN_PATH = re.compile(r"day=(\d{4}-\d{2}-\d{2})/device_id=(-?\d+)/")
WHEEL_COLUMNS = ("device_id", "counting_head", "channel", "time_ns", "value", "subsecond")
HEAD_COLUMNS = ("device_id", "counting_head", "first_file_seq", "first_line")


@dataclass(frozen=True, order=True)
class PartitionKey:
    """One device's records of one day: the unit the derived tables are computed and stored by."""

    device_id: int
    day: dt.date

    @property
    def name(self) -> str:
        return f"{self.device_id}/{self.day.isoformat()}"

    @classmethod
    def parse(cls, name: str) -> PartitionKey:
        dev, day = name.split("/")
        return cls(int(dev), dt.date.fromisoformat(day))


@dataclass(frozen=True)
class Carried:
    """What crosses a partition's edges: which neighbouring days of its device hold records.

    ``day_before``: the day before, when it holds records (a passage open at
    midnight began there).  ``days_after``: the run of consecutive following
    days with records (a passage started in the partition may run on into them).
    """

    day_before: dt.date | None = None
    days_after: tuple[dt.date, ...] = ()


@dataclass
class DerivedRows:
    """A partition's derived rows: passages starting in it, their axles, wheel records and the heads seen."""

    keys: tuple[PartitionKey, ...]
    passages: pd.DataFrame
    axles: pd.DataFrame
    wheel: pd.DataFrame  # WHEEL_COLUMNS: the section engine's input, in the batch's order per head
    heads: pd.DataFrame  # HEAD_COLUMNS: each head's first record (file, line) in these days
    last_end_day: dict[str, str]  # key name → day of its latest passage end (ISO)
    overlap: dict[str, int] = field(default_factory=dict)  # key name → records set aside as another file's overlap

    def split(self) -> dict[PartitionKey, DerivedRows]:
        """The rows of each key (each table's days converted once, not once per key)."""

        def days(values: object) -> np.ndarray:
            return np.asarray(values, dtype="datetime64[D]")

        p_day = (np.asarray(self.passages["start_ns"], np.int64) // NS_PER_DAY).astype("datetime64[D]")
        a_day = days(self.axles["_key_day"])
        w_day = days(self.wheel["_key_day"])
        h_day = days(self.heads["_key_day"])
        out: dict[PartitionKey, DerivedRows] = {}
        for key in self.keys:
            d = np.datetime64(key.day, "D")
            out[key] = DerivedRows(
                keys=(key,),
                passages=self.passages[p_day == d].reset_index(drop=True),
                axles=self.axles[a_day == d].reset_index(drop=True),
                wheel=self.wheel[w_day == d].reset_index(drop=True),
                heads=self.heads[h_day == d].reset_index(drop=True),
                last_end_day={k: v for k, v in self.last_end_day.items() if k == key.name},
                overlap={k: v for k, v in self.overlap.items() if k == key.name},
            )
        return out


def _day_of(ns: pd.Series | np.ndarray) -> np.ndarray:
    return (np.asarray(ns, np.int64) // NS_PER_DAY).astype("datetime64[D]").astype(object)


def key_of_part(rel: str) -> PartitionKey | None:
    """The partition of a records part, from its hive path (None: not a day/device part)."""
    m = _KEY_IN_PATH.search(rel.replace("\\", "/"))
    return PartitionKey(int(m.group(2)), dt.date.fromisoformat(m.group(1))) if m else None


def partitions(manifest: Manifest) -> list[PartitionKey]:
    """Every (device, day) holding records, sorted; ValueError if a records part is not partitioned."""
    keys: set[PartitionKey] = set()
    for rel in manifest.parts("records"):
        k = key_of_part(rel)
        if k is None:
            raise ValueError(f"records part {rel} is not under day=/device_id=")
        keys.add(k)
    return sorted(keys)


def carried_state(keys: Iterable[PartitionKey]) -> dict[PartitionKey, Carried]:
    """Per key, its neighbouring days with records (from the key list alone: no data read)."""
    days: dict[int, set[dt.date]] = {}
    for k in keys:
        days.setdefault(k.device_id, set()).add(k.day)
    out: dict[PartitionKey, Carried] = {}
    one = dt.timedelta(days=1)
    for dev, have in days.items():
        for d in sorted(have):
            after: list[dt.date] = []
            nxt = d + one
            while nxt in have:
                after.append(nxt)
                nxt += one
            out[PartitionKey(dev, d)] = Carried(d - one if d - one in have else None, tuple(after))
    return out


def derive_partition(
    root: Path, manifest: Manifest, key: PartitionKey, carried: Carried, settings: SpeedSettings
) -> DerivedRows:
    """The derived rows of one partition (reads the archive, writes nothing)."""
    return derive_run(root, manifest, key.device_id, [key.day], carried, settings)


def derive_run(
    root: Path,
    manifest: Manifest,
    device_id: int,
    days: Sequence[dt.date],
    carried: Carried,
    settings: SpeedSettings,
) -> DerivedRows:
    """The derived rows of consecutive ``days`` of one device, in one window.

    ``carried``: the neighbours of the run (``day_before`` of its first day,
    ``days_after`` of its last day).
    """
    if settings.idle_gap_s >= 86_400:
        raise ValueError("idle gap must be shorter than a day (a partition is a day)")
    days = sorted(days)
    lo = carried.day_before if carried.day_before is not None else days[0]
    later = list(carried.days_after)
    hi = days[-1]
    idle_ns = int(settings.idle_gap_s * 1e9)
    while True:
        analysis, heads = _analyse_window(root, manifest, device_id, lo, hi, settings)
        rows = _rows(analysis, heads, device_id, days)
        # A passage started in the run whose last record is within an idle gap of the window's end may go on
        # into the next day: read that day too (a passage over midnight; rarely, one longer than a day).
        window_end_ns = (np.datetime64(hi, "D").astype(np.int64) + 1) * NS_PER_DAY
        if later and len(rows.passages) and int(rows.passages["end_ns"].max()) + idle_ns >= window_end_ns:
            hi = later.pop(0)
            continue
        return rows


@dataclass(frozen=True)
class PartitionTask:
    """One unit of derivation, small and picklable (it may run in another process: the Dask engine).

    ``records``: the device's records parts of every day the run may read
    (the day before, the days, the days after); ``days``: consecutive days
    of the device whose rows are wanted.
    """

    root: str
    records: tuple[str, ...]
    device_id: int
    days: tuple[dt.date, ...]
    carried: Carried
    settings: SpeedSettings

    @property
    def keys(self) -> tuple[PartitionKey, ...]:
        return tuple(PartitionKey(self.device_id, d) for d in self.days)


def run_task(task: PartitionTask) -> DerivedRows:
    """The rows of a task's days (module-level: a mapper may pickle it to a worker)."""
    m = Manifest(tables={"records": list(task.records)})
    # Arrow on the system allocator, its freed pages trimmed (a worker runs task after task: each
    # task's peak would otherwise stay as the worker's RSS).
    with read_memory():
        return derive_run(Path(task.root), m, task.device_id, task.days, task.carried, task.settings)


def make_tasks(
    root: Path,
    manifest: Manifest,
    wanted: Iterable[PartitionKey],
    carried: dict[PartitionKey, Carried],
    settings: SpeedSettings,
    max_days: int = 8,
    max_records: int | None = None,
) -> list[PartitionTask]:
    """The wanted keys as tasks, in key order: runs of consecutive days of one device, at most
    ``max_days`` of them and (but for a run of one day) at most ``max_records`` records in all
    (default :data:`TASK_RECORDS`)."""
    if max_records is None:
        max_records = TASK_RECORDS
    parts_of: dict[PartitionKey, list[str]] = {}
    for rel in manifest.parts("records"):
        k = key_of_part(rel)
        if k is not None:
            parts_of.setdefault(k, []).append(rel)
    one = dt.timedelta(days=1)
    runs: list[list[PartitionKey]] = []
    held = 0  # records in the last run
    for k in sorted(set(wanted)):
        n = _records_in(root, parts_of.get(k, []))
        last = runs[-1][-1] if runs else None
        if (
            last is not None
            and last.device_id == k.device_id
            and last.day + one == k.day
            and len(runs[-1]) < max_days
            and held + n <= max_records
        ):
            runs[-1].append(k)
            held += n
        else:
            runs.append([k])
            held = n
    tasks = []
    for run in runs:
        c = Carried(carried[run[0]].day_before, carried[run[-1]].days_after)
        days = [d for d in (c.day_before, *(k.day for k in run), *c.days_after) if d is not None]
        dev = run[0].device_id
        records = tuple(rel for d in days for rel in sorted(parts_of.get(PartitionKey(dev, d), [])))
        tasks.append(PartitionTask(str(root), records, dev, tuple(k.day for k in run), c, settings))
    return tasks


def _records_in(root: Path, parts: Iterable[str]) -> int:
    """Records in the parts, from their Parquet footers (no data read; a part gone counts none)."""
    import pyarrow.parquet as pq

    n = 0
    for rel in parts:
        try:
            n += pq.read_metadata(root / rel).num_rows
        except (OSError, pa.ArrowInvalid):
            continue
    return n


def _window_manifest(manifest: Manifest, device_id: int, lo: dt.date, hi: dt.date) -> Manifest:
    parts = []
    for rel in manifest.parts("records"):
        k = key_of_part(rel)
        if k is not None and k.device_id == device_id and lo <= k.day <= hi:
            parts.append(rel)
    return replace(manifest, tables={"records": parts})


def _window_records(root: Path, manifest: Manifest, device_id: int, lo: dt.date, hi: dt.date) -> pa.Table:
    """The device's records of days [lo, hi] in file, line order (the order a batch read sees them).

    Read with pyarrow, not DuckDB: a partition is small, and a DuckDB connection
    costs about 0.1 s to open.  Text columns as plain strings, ``device_id`` from
    the path: the columns :func:`console.archive.history.record_batches` gives.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    from console.archive.history import RECORD_COLUMNS

    tables = []
    for rel in sorted(_window_manifest(manifest, device_id, lo, hi).parts("records")):
        t = pq.read_table(root / rel)
        tables.append(t.append_column("device_id", pa.array(np.full(t.num_rows, device_id, np.int32))))
    if not tables:
        return pa.table({})
    # The Parquet decoder's freed buffers given back before the table is copied into read order:
    # otherwise they stay in the C heap under the copies (an 8-day window: 259 -> 200 MB peak).
    trim_heap()
    # Text columns stay dictionary-coded (a few bytes a record, where plain strings take tens): the
    # parts' dictionaries unified into one per column, which ChunkRebuilder reads as codes.
    table = pa.concat_tables(tables, promote_options="permissive").unify_dictionaries().select(list(RECORD_COLUMNS))
    seq = table.column("file_seq").to_numpy().astype(np.int64)
    line = table.column("line").to_numpy().astype(np.int64)
    order = np.lexsort((line, seq))
    table = table.combine_chunks()
    if not (order[1:] > order[:-1]).all():
        table = table.take(pa.array(order))
    return table


def _analyse_window(
    root: Path, manifest: Manifest, device_id: int, lo: dt.date, hi: dt.date, settings: SpeedSettings
) -> tuple[DiagAnalysis | None, pd.DataFrame]:
    """The batch analysis of the device's records of days [lo, hi]; each head's first record per day."""
    import pandas as pd

    from console.analysis.diagnostics import DiagAccumulator
    from console.archive.history import BATCH_ROWS
    from console.archive.records import ChunkRebuilder

    table = _window_records(root, manifest, device_id, lo, hi)
    rebuild = ChunkRebuilder()
    acc = DiagAccumulator(rebuild.registry, keep_releases=True)
    for batch in table.to_batches(BATCH_ROWS):
        for chunk in rebuild.chunks(batch):
            acc.add(chunk)
    if table.num_rows == 0:
        empty = {"device_id": pd.Series(dtype="int64"), "counting_head": pd.Series(dtype=object)}
        heads = pd.DataFrame(empty | {"_key_day": [], "first_file_seq": [], "first_line": []})
        return None, heads
    # Each head's first record per day: rows are in read order, so the first row of each (head, day).
    # Read order is (file_seq, line): one integer orders both (lines < 2**32).
    frame = pd.DataFrame(
        {
            "counting_head": table.column("counting_head").to_pandas(),
            "_key_day": table.column("time").cast(pa.int64()).to_numpy() // NS_PER_DAY,
            "pos": table.column("file_seq").to_numpy().astype(np.int64) * 4294967296
            + table.column("line").to_numpy().astype(np.int64),
        }
    )
    heads = frame.groupby(["_key_day", "counting_head"], dropna=False, sort=True)["pos"].min().reset_index()
    heads.insert(0, "device_id", np.int64(device_id))
    heads["_key_day"] = heads["_key_day"].to_numpy(np.int64).astype("datetime64[D]").astype(object)
    pos = heads.pop("pos").to_numpy(np.int64)
    heads["first_file_seq"] = pos >> 32
    heads["first_line"] = pos & 0xFFFFFFFF
    return acc.result(settings), heads


def _rows(analysis: DiagAnalysis | None, heads: pd.DataFrame, device_id: int, days: Sequence[dt.date]) -> DerivedRows:
    import pandas as pd

    keys = tuple(PartitionKey(device_id, d) for d in days)
    heads = heads.copy()
    heads["_key_day"] = pd.to_datetime(heads["_key_day"]).dt.date
    heads = heads[heads["_key_day"].isin(set(days))].reset_index(drop=True)
    if analysis is None:
        empty = pd.DataFrame({"_key_day": pd.Series(dtype=object)})
        return DerivedRows(keys, passages_table(analysis), empty, empty, heads, {})
    p = passages_table(analysis)
    start_day = _day_of(p["start_ns"])
    # The same days as datetime64 for the per-row columns (python dates per axle and record cost seconds).
    start_day64 = (p["start_ns"].to_numpy(np.int64) // NS_PER_DAY).astype("datetime64[D]")
    keep = np.isin(start_day, np.array(list(days), dtype=object))
    # Every axle and wheel record lies in one passage of its head: the passage starting at or before it.
    head_index = pd.MultiIndex.from_tuples(analysis.heads, names=["device_id", "counting_head"])
    p_head = head_index.get_indexer(pd.MultiIndex.from_frame(p[["device_id", "counting_head"]])).astype(np.int64)
    starts = p["start_ns"].to_numpy(np.int64)

    def owner(head: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
        """Row in ``p`` of the passage holding each (head, time)."""
        out = np.full(len(head), -1, np.int64)
        for h in np.unique(head).tolist():
            rows = np.flatnonzero(p_head == h)
            at = head == h
            i = np.searchsorted(starts[rows], time_ns[at], side="right") - 1
            out[at] = np.where(i >= 0, rows[np.maximum(i, 0)], -1)
        return out

    axles = axles_table(analysis)
    a_owner = owner(analysis.axle_columns["head"].astype(np.int64), axles["time_ns"].to_numpy(np.int64))
    a_keep = (a_owner >= 0) & keep[np.maximum(a_owner, 0)]
    axles = axles[a_keep].reset_index(drop=True)
    axles["_key_day"] = start_day64[a_owner[a_keep]]

    wr = analysis.wheel_records
    if len(wr):
        w_head = wr["head"].to_numpy(np.int64)
        w_owner = owner(w_head, wr["time_ns"].to_numpy(np.int64))
        w_keep = (w_owner >= 0) & keep[np.maximum(w_owner, 0)]
        dev = np.array([h[0] for h in analysis.heads], np.int64)
        name = np.array([h[1] for h in analysis.heads], object)
        wheel = pd.DataFrame(
            {
                "device_id": dev[w_head[w_keep]],
                "counting_head": name[w_head[w_keep]],
                "channel": wr["channel"].to_numpy()[w_keep],
                "time_ns": wr["time_ns"].to_numpy()[w_keep],
                "value": wr["value"].to_numpy()[w_keep],
                "subsecond": wr["subsecond"].to_numpy()[w_keep],
                "_key_day": start_day64[w_owner[w_keep]],
            }
        )
    else:
        wheel = pd.DataFrame({c: pd.Series(dtype="int64") for c in WHEEL_COLUMNS} | {"_key_day": []})
    kept = p[keep].reset_index(drop=True)
    # Per start day, the day its latest passage ends (the incremental derive's reach back over midnight).
    reach = pd.Series(kept["end_ns"].to_numpy(np.int64)).groupby(start_day[keep]).max()
    ends = _day_of(reach.to_numpy(np.int64))
    last = {f"{device_id}/{d.isoformat()}": e.isoformat() for d, e in zip(reach.index, ends, strict=True)}
    overlap_day = _day_of(analysis.overlap_times_ns)
    overlap = {k.name: int((overlap_day == k.day).sum()) for k in keys}
    return DerivedRows(keys, kept, axles, wheel, heads, last, overlap)


def passages_table(analysis: DiagAnalysis | None) -> pd.DataFrame:
    """The archived passages of an analysis: analyze's passage table with a ``start`` timestamp.

    ``axle_speeds_start``/``stop`` index an in-memory array of per-axle speeds
    (the JSON's lists): archived as a list per passage, ``axle_speeds_kmh``.
    """
    import pandas as pd

    from console.analysis.diagnostics import PASSAGE_COLUMNS

    if analysis is None:
        p = pd.DataFrame(columns=list(PASSAGE_COLUMNS))
        speeds: list[list[float]] = []
    else:
        p = analysis.passages.copy()
        flat = np.asarray(p.attrs.get("axle_speeds_kmh", np.zeros(0)), np.float64).tolist()
        bounds = zip(p["axle_speeds_start"].tolist(), p["axle_speeds_stop"].tolist(), strict=True)
        speeds = [flat[a:b] for a, b in bounds]
        p.attrs = {}
    p = p.drop(columns=["axle_speeds_start", "axle_speeds_stop"])
    p["axle_speeds_kmh"] = pd.Series(speeds, index=p.index, dtype=object)
    p["start"] = pd.to_datetime(p["start_ns"], unit="ns")
    return _string_columns(p)


def _string_columns(df: pd.DataFrame) -> pd.DataFrame:
    """Text columns as one string dtype: passages that all lack a direction hold None in an
    object column, others a string column; concatenated they would mix None and NaN."""
    for column in [c for c in df.columns if df[c].dtype == object]:
        if df[column].map(lambda v: isinstance(v, str) or v is None or v != v).all():
            df[column] = df[column].astype("str")
    return df


def axles_table(analysis: DiagAnalysis) -> pd.DataFrame:
    """The archived axles: analyze's axle table with the head named (device id, counting head) and a timestamp."""
    import pandas as pd

    ax = analysis.axles.copy()
    heads = analysis.heads
    if len(ax):
        idx = ax["head"].to_numpy(np.int64)
        ax["device_id"] = np.array([h[0] for h in heads], np.int64)[idx]
        ax["counting_head"] = np.array([h[1] for h in heads], object)[idx]
    else:
        ax["device_id"] = pd.Series(dtype="int64")
        ax["counting_head"] = pd.Series(dtype=object)
    ax["time"] = pd.to_datetime(ax["time_ns"], unit="ns")
    return ax.drop(columns=["head"], errors="ignore")


def combine(rows: Iterable[DerivedRows]) -> dict[str, pd.DataFrame]:
    """Partitions' rows → one table each (``passages``, ``axles``, ``wheel``, ``heads``), in key order."""
    import pandas as pd

    ordered = sorted(rows, key=lambda r: r.keys)
    out: dict[str, pd.DataFrame] = {}
    for name in ("passages", "axles", "wheel", "heads"):
        frames = [getattr(r, name) for r in ordered]
        # Empty partitions left out of the concatenation, but their columns kept when all are empty.
        frames = [f for f in frames if len(f)] or frames[:1]
        df = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
        out[name] = _string_columns(df.drop(columns=["_key_day"], errors="ignore"))
    return out
