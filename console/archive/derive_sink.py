"""The archive's derived rows as the pipeline makes them: one sink writing Parquet parts.

Passages and axles are partitioned by day and device (a passage and its
axles on the day the passage starts), section states, the count ledger and
the channel events health reads by day.  Every part gets the generation
and a tag in its name, so sinks of several groups of one ingest (the Dask
engine's tasks) never write the same file.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from console.analysis.counting.wheels import DIRECTIONS
from console.analysis.head_table import heads_at
from console.analysis.passages.passage_frame import PASSAGE_BASES, PASSAGE_COLUMNS, PASSAGE_DIRECTIONS, PASSAGE_KINDS
from console.archive import arrow_np
from console.archive.parts import PartWriter
from console.engine.pipeline import HEALTH_EVENT_KINDS
from console.engine.sinks import Sink
from parsers.units import NS_PER_DAY

if TYPE_CHECKING:
    import pandas as pd

    from console.analysis.events.block import EventBlock
    from console.analysis.head_table import Heads
    from console.analysis.passages.buckets import Columns
    from console.analysis.sections.state import LedgerEntry, Transition

# Bump when derived rows change meaning: an archive derived by another version is rebuilt.
# 4: integers stored as integers (passages' detection second), finding times as TIMESTAMP_NS.
# 5: derived by the pipeline in the ingest's one pass, its state kept between ingests.
# 6: the kept state's section records moved (console.analysis.sections.state): a state pickled by 5 is not read.
# 7: the parsers grouped by family (parsers.diag.registry, parsers.diag.fields): a state pickled by 6 names
#    modules that are gone, so it is not read; the records are derived again.
# 8: the analysis grouped by job (console.analysis.passages.stream, .counting.bank, ...): likewise.
# 9: an axle stamped at its passage's start is on that passage's day (it was put on the head's previous passage's,
#    or another head's, as the pipeline's batches fell: the Dask engine's days differed from the local engine's).
# 10: the inventory's figures per day, device and head (console.archive.head_days), read by a report over whole days.
# 11: a head's records going back in time are a doubt event (clock_step) that disturbs its sections; the state
#    holds where each file's heads stood.
# 12: a section bounded by a head not heard yet (no event of it: absent from the log) holds, never clear on its
#    other heads' counts alone; the kept engine has the heads not heard yet.
DERIVE_VERSION = 12
# Rows each derived table buffers before a write-out (the records' writer has BUFFER_BYTES): derived rows come
# a few per chunk, and five tables' full buffers cost memory (a 3 M-record ingest peaked 35 MB lower at 4 MB than
# at 16 MB, for the same CPU).
SINK_BUFFER_BYTES = 4 << 20
# Passages and axles gathered over the pipeline's calls before their tables are made: a call brings a few
# hundred passages, and each table costs some thirty Arrow calls on the ingest's main thread whatever its
# size (a 3 M-record ingest made 97 of each; 9 at this size, the day closes included; 21 at 16,384 rows,
# for more main-thread CPU).  The rows are the same; the write-outs (row groups) fall at other rows than
# with a table per call.
PASSAGE_BATCH_ROWS = 65_536


class ArchiveSink(Sink):
    """The pipeline's rows, written into parts of this generation (``tag``: committed or tail)."""

    def __init__(self, root: Path, generation: int, tag: str) -> None:
        buf = SINK_BUFFER_BYTES
        self.writers = {
            "passages": PartWriter(root, "passages", generation, tag, buffer_bytes=buf),
            "axles": PartWriter(root, "axles", generation, tag, buffer_bytes=buf),
            "section_states": PartWriter(root, "section_states", generation, tag, by_device=False, buffer_bytes=buf),
            "count_ledger": PartWriter(root, "count_ledger", generation, tag, by_device=False, buffer_bytes=buf),
            "channel_events": PartWriter(root, "channel_events", generation, tag, by_device=False, buffer_bytes=buf),
        }
        self._axles: list[tuple[Columns, Heads]] = []
        # Per head key, the start of its latest passage written: an axle whose passage came in an earlier call.
        self._last_start: dict[int, int] = {}
        # Passages and axles (with each axle's day, settled per call) waiting to be made into tables.
        self._batch: list[Columns] = []
        self._batch_axles: list[tuple[Columns, np.ndarray]] = []
        self._batch_rows = 0
        self._heads: Heads | None = None
        # The order of the section history's rows (ties in time are broken by it): by generation, then as made.
        self._seq = generation << 32

    def axles(self, cols: Columns, heads: Heads) -> None:
        self._axles.append((cols, heads))  # written with their passages: an axle's day is its passage's

    def passages(self, cols: Columns, heads: Heads) -> None:
        """A call's passages, and the axles given since the last call, each axle on its passage's day (settled
        now, as the calls fall); their tables are made a batch of calls at a time (:data:`PASSAGE_BATCH_ROWS`)."""
        start_ns = np.asarray(cols["start_ns"], np.int64)
        for axle_cols, _ in self._axles:
            if len(axle_cols["head"]):
                self._batch_axles.append((axle_cols, self._axle_days(axle_cols, cols)))
                self._batch_rows += len(axle_cols["head"])
        self._axles = []
        self._batch.append(cols)
        self._batch_rows += len(start_ns)
        self._heads = heads  # head keys only grow: the latest table names every head of the batch
        ph = np.asarray(cols["head"], np.int64)
        order = np.lexsort((start_ns, ph))
        last = np.r_[ph[order][1:] != ph[order][:-1], True]  # each head's latest start
        self._last_start.update(zip(ph[order][last].tolist(), start_ns[order][last].tolist(), strict=True))
        # The stream's time (a median: one damaged time does not move it): past days' files are closed, once
        # every row given so far is with the writers (a row of a closed day would open a further part).
        watermark = int(np.median(start_ns)) if len(start_ns) else None
        closing = watermark is not None and self.writers["passages"].closes_day(watermark)
        if closing or self._batch_rows >= PASSAGE_BATCH_ROWS:
            self._write_batch()
        if closing and watermark is not None:
            self.writers["passages"].advance(watermark)
            self.writers["axles"].advance(watermark)

    def _write_batch(self) -> None:
        """The batch's passages and axles, one table each (in the order the calls gave them)."""
        heads, batch, axles = self._heads, self._batch, self._batch_axles
        self._batch, self._batch_axles, self._batch_rows = [], [], 0
        if heads is None:
            return
        if batch:
            cols = concat_passages(batch)
            if len(cols["head"]):
                day = np.asarray(cols["start_ns"], np.int64) // NS_PER_DAY
                device_id, table = passages_table(cols, heads)
                self.writers["passages"].add(table.append_column("day", day_column(day)), day, device_id)
        if axles:
            names = list(axles[0][0])
            together = {c: np.concatenate([np.asarray(a[c]) for a, _ in axles]) for c in names}
            start_day = np.concatenate([d for _, d in axles])
            device_id, table = axles_table(together, heads)
            self.writers["axles"].add(table.append_column("day", day_column(start_day)), start_day, device_id)

    def _axle_days(self, axles: Columns, passages: Columns) -> np.ndarray:
        """Each axle's day: that of the passage of its head that starts at or before it."""
        # Each axle lies in the passage of its head that starts at or before it.
        head, t = np.asarray(axles["head"], np.int64), np.asarray(axles["time_ns"], np.int64)
        ph, ps = np.asarray(passages["head"], np.int64), np.asarray(passages["start_ns"], np.int64)
        order = np.lexsort((ps, ph))
        ph, ps = ph[order], ps[order]
        # Rank each (head, time) among the passages' (head, start) pairs: one sort of both.
        keys = np.r_[ph, head]
        times = np.r_[ps, t]
        is_axle = np.r_[np.zeros(len(ph), bool), np.ones(len(head), bool)]
        # A passage sorts before an axle at its start (a whole-second head's first axle is stamped at it).
        merged = np.lexsort((is_axle, times, keys))
        pos = np.cumsum(~is_axle[merged]) - 1  # the last passage at or before each row
        owner = np.empty(len(keys), np.int64)
        owner[merged] = pos
        owner = owner[len(ph) :]
        # No passage of its head at or before it among these (the last one found was another head's): its
        # head's latest passage written before, else its own time.  Whatever the batches, the same day.
        at = np.maximum(owner, 0)
        lost = (owner < 0) | (ph[at] != head) if len(ph) else np.ones(len(head), bool)
        start = np.where(lost, t, ps[at]) if len(ph) else t.copy()
        if lost.any():
            start[lost] = [
                self._last_start.get(h, s) for h, s in zip(head[lost].tolist(), start[lost].tolist(), strict=True)
            ]
        return start // NS_PER_DAY

    def transitions(self, rows: Iterable[Transition]) -> None:
        import pandas as pd

        df = pd.DataFrame(
            [(r.time_ns, r.section, str(r.state), r.count, r.reason) for r in rows],
            columns=["time_ns", "section", "state", "count", "reason"],
        )
        self._timed("section_states", df)

    def ledger(self, rows: Iterable[LedgerEntry]) -> None:
        import pandas as pd

        df = pd.DataFrame(
            [(x.time_ns, x.section, x.head, x.delta, x.count) for x in rows],
            columns=["time_ns", "section", "head", "delta", "count"],
        )
        self._timed("count_ledger", df)

    def detections(self, block: EventBlock) -> None:
        health = block.of_kinds(HEALTH_EVENT_KINDS)
        if len(health):
            self._timed("channel_events", channel_events_frame(health.events()))

    def _timed(self, table: str, df: pd.DataFrame) -> None:
        if not len(df):
            return
        if table in ("section_states", "count_ledger"):
            df["seq"] = np.arange(self._seq, self._seq + len(df), dtype=np.int64)
            self._seq += len(df)
        t = df["time_ns"].to_numpy(np.int64)
        df["time"] = t.astype("datetime64[ns]")
        day = t // NS_PER_DAY
        self.writers[table].add(arrow_table(df).append_column("day", day_column(day)), day)

    def close(self) -> dict[str, list[str]]:
        self._write_batch()
        return {name: w.close() for name, w in self.writers.items()}

    def abort(self) -> None:
        self._batch, self._batch_axles, self._batch_rows = [], [], 0
        for w in self.writers.values():
            w.abort()


# Passage columns stored as integers that the pipeline gives as floats (NaN: none).
_NULLABLE_INTEGERS = frozenset({"detection_second_ns", "records_in_detection_second"})
# The pipeline's code columns, by their codes: the text stored (taken by code in Arrow, not made per row in Python).
_PASSAGE_CODES = {
    "direction": arrow_np.strings(PASSAGE_DIRECTIONS, pa.large_string()),
    "whole_train_basis": arrow_np.strings(PASSAGE_BASES, pa.large_string()),
    "kind": arrow_np.strings(PASSAGE_KINDS, pa.large_string()),
}
_AXLE_DIRECTIONS = arrow_np.strings(DIRECTIONS, pa.large_string())


def _heads_columns(heads: Heads, keys: np.ndarray) -> tuple[np.ndarray, pa.Array]:
    """(device ids, counting heads as text) of the heads at ``keys``: each head looked up once."""
    used, inverse = np.unique(np.asarray(keys, np.int64), return_inverse=True)
    used_dev, used_names = heads_at(heads, used)
    inverse = inverse.reshape(-1)
    return used_dev[inverse], arrow_np.strings(list(used_names), pa.large_string()).take(arrow_np.array(inverse))


def _column(values: Any) -> pa.Array:
    """A numeric column as Arrow, NaN as null (as pandas hands floats to Arrow)."""
    return arrow_np.array(np.asarray(values), nan_is_null=True)


def passages_table(cols: Columns, heads: Heads) -> tuple[np.ndarray, pa.Table]:
    """(device ids, the passages as Arrow): the columns of
    :func:`~console.analysis.passages.passage_frame.passages_frame` with the start as a time and each passage's
    axle speeds as a list, built from the pipeline's arrays (no pandas: this runs for every chunk of an ingest)."""
    device_id, counting_head = _heads_columns(heads, cols["head"])
    arrays: list[pa.Array] = [arrow_np.array(device_id, pa.int64()), counting_head]
    names = ["device_id", "counting_head"]
    for c in PASSAGE_COLUMNS[2:]:
        if c in ("axle_speeds_start", "axle_speeds_stop"):
            continue
        if c in _PASSAGE_CODES:
            arrays.append(_PASSAGE_CODES[c].take(arrow_np.array(np.asarray(cols[c]))))
        elif c in _NULLABLE_INTEGERS:
            arrays.append(_column(cols[c]).cast(pa.int64()))
        else:
            arrays.append(_column(cols[c]))
        names.append(c)
    arrays.append(arrow_np.array(np.asarray(cols["start_ns"], np.int64).astype("datetime64[ns]")))
    names.append("start")
    # Per passage, its slice [start, stop) of the flat axle speeds, as one list column.
    first = np.asarray(cols["axle_speeds_start"], np.int64)
    lengths = np.asarray(cols["axle_speeds_stop"], np.int64) - first
    offsets = np.r_[0, np.cumsum(lengths)].astype(np.int32)
    picked = np.repeat(first - offsets[:-1], lengths) + np.arange(offsets[-1], dtype=np.int64)
    flat = np.asarray(cols["axle_speeds_kmh"], np.float64)[picked]
    arrays.append(pa.ListArray.from_arrays(arrow_np.array(offsets), arrow_np.array(flat)))
    names.append("axle_speeds_kmh")
    return device_id, pa.Table.from_arrays(arrays, names=names)


def concat_passages(batch: list[Columns]) -> Columns:
    """Several calls' passage columns as one call's: each passage's slice of the flat axle speeds moved to
    where its call's speeds land in the joined ones."""
    if len(batch) == 1:
        return batch[0]
    speeds = ("axle_speeds_start", "axle_speeds_stop", "axle_speeds_kmh")
    out: dict[str, Any] = {
        c: np.concatenate([np.asarray(cols[c]) for cols in batch]) for c in batch[0] if c not in speeds
    }
    flats = [np.asarray(cols["axle_speeds_kmh"], np.float64) for cols in batch]
    bases = np.cumsum([0] + [len(f) for f in flats[:-1]]).tolist()
    for c in speeds[:2]:
        out[c] = np.concatenate([np.asarray(cols[c], np.int64) + b for cols, b in zip(batch, bases, strict=True)])
    out["axle_speeds_kmh"] = np.concatenate(flats)
    return out


def axles_table(axles: Columns, heads: Heads) -> tuple[np.ndarray, pa.Table]:
    """(device ids, the axles as Arrow): :func:`~console.analysis.counting.wheels.axles_frame`'s columns, the head as
    its device and name, and the time."""
    arrays: list[pa.Array] = []
    names: list[str] = []
    for c, values in axles.items():
        if c == "head":
            continue
        arrays.append(
            _AXLE_DIRECTIONS.take(arrow_np.array(np.asarray(values))) if c == "direction" else _column(values)
        )
        names.append(c)
    device_id, counting_head = _heads_columns(heads, axles["head"])
    arrays += [arrow_np.array(device_id, pa.int64()), counting_head]
    arrays.append(arrow_np.array(np.asarray(axles["time_ns"], np.int64).astype("datetime64[ns]")))
    names += ["device_id", "counting_head", "time"]
    return device_id, pa.Table.from_arrays(arrays, names=names)


def day_column(day_index: np.ndarray) -> pa.Array:
    """Days since 1970 as the archive's ``day`` column (DATE)."""
    return arrow_np.array(np.asarray(day_index, np.int64).astype(np.int32), pa.date32())


def channel_events_frame(events: Iterable[Any]) -> pd.DataFrame:
    """The events health judges (channel faults and recoveries, single-channel pulses), as a table."""
    import pandas as pd

    from console.analysis.events.detection import EVENT_COLUMNS

    rows = [(e.time_ns, str(e.kind), e.head, e.direction, e.channel, e.source, e.detail) for e in events]
    df = pd.DataFrame(rows, columns=list(EVENT_COLUMNS))
    df["channel"] = df["channel"].astype("Int64")
    return df


def arrow_table(df: pd.DataFrame) -> pa.Table:
    """A derived frame as Arrow: text columns as strings (None kept), the rest as pandas gives them."""
    import datetime as dt

    for c in df.columns:
        if df[c].dtype != object:
            continue
        if df[c].isna().all():
            # No value at all: the column still gets its type (numbers for units, text otherwise).
            df[c] = df[c].astype("float64" if c.endswith(("_s", "_ns", "_m", "_kmh")) else "string")
            continue
        try:
            pa.array(df[c], from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError):
            df[c] = df[c].map(
                lambda v: None if v is None else v if isinstance(v, str | int | float | bool | dt.date) else str(v)
            )
    return pa.Table.from_pandas(df, preserve_index=False)
