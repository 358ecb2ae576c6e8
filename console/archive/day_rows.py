"""The per-day rows (``head_days``, ``identity_days``) of an ingest's days, gathered as its records are
stored instead of read back.

:mod:`console.archive.head_days` makes a day's rows with a DuckDB pass over all of that day's records
(about half a CPU second for a 3 M-record day, plus the connection's memory at the ingest's end).  The
rows are counts, minima, maxima, distinct sets and latest values per (day, device, head) or identity
register: they merge.  So the local ingest keeps, per day and register, the records' count, first and
last time and first read position, and each identity register's latest record, as each chunk is stored
(a few numpy passes over ids the parser has already made); at the end it merges them with the day's
stored rows, which summarise the day's records of earlier ingests.

A day's rows are made this way only when that merge is exact, else from the records as before:

* every record this ingest stored went through :meth:`DayRows.add` (the local engine's read; not the
  workers' parse, nor a rewrite of replaced files' records);
* the derivation is the stored one (the days asked for are the days of this ingest's records), or the
  archive held no records before (then there are no earlier rows).

The rows equal the DuckDB aggregate's, type for type (tests/test_archive_day_rows.py, over splits).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from console.archive import arrow_np
from parsers.units import ALL_TIME, NO_TIME, NS_PER_DAY

if TYPE_CHECKING:
    from parsers.diag.records import DiagChunk
    from parsers.diag.registry import DiagRegistry

_POS_MAX = int(np.iinfo(np.int64).max)  # a minimum of positions starts above every position

# The schema DuckDB gives the head rows (head_rows_sql grouped, without ``day``): the part is written with it.
HEAD_SCHEMA = pa.schema(
    [
        ("device_id", pa.int32()),
        ("counting_head", pa.string()),
        ("first_pos", pa.int64()),
        ("device", pa.string()),
        ("type", pa.string()),
        ("gs", pa.string()),
        ("diag_ids", pa.list_(pa.field("l", pa.int32()))),
        ("channels", pa.list_(pa.field("l", pa.int8()))),
        ("records", pa.int64()),
        ("first_time", pa.timestamp("ns")),
        ("last_time", pa.timestamp("ns")),
    ]
)


# The schema DuckDB gives the identity rows (identity_rows_sql grouped, without ``day``).
IDENTITY_SCHEMA = pa.schema(
    [
        ("device_id", pa.int32()),
        ("diag_id", pa.int32()),
        ("device", pa.string()),
        ("type", pa.string()),
        ("gs", pa.string()),
        ("counting_head", pa.string()),
        ("channel", pa.int8()),
        ("address", pa.int16()),
        ("label", pa.string()),
        ("label_canonical", pa.string()),
        ("label_encoding", pa.string()),
        ("value", pa.int64()),
        ("data_kind", pa.string()),
        ("data", pa.string()),
        ("at_time", pa.timestamp("ns")),
        ("at_file_seq", pa.int32()),
        ("at_line", pa.int64()),
    ]
)


@dataclass
class _Day:
    """Per register of one registry, one day's timed records: count, first/last time, first position."""

    count: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    t_min: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    t_max: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    pos_min: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def grow(self, n: int) -> None:
        old = len(self.count)
        if n <= old:
            return
        extra = n - old
        self.count = np.concatenate([self.count, np.zeros(extra, np.int64)])
        self.t_min = np.concatenate([self.t_min, np.full(extra, ALL_TIME, np.int64)])
        self.t_max = np.concatenate([self.t_max, np.full(extra, NO_TIME, np.int64)])
        self.pos_min = np.concatenate([self.pos_min, np.full(extra, _POS_MAX, np.int64)])


@dataclass
class _Registry:
    registry: DiagRegistry
    days: dict[int, _Day] = field(default_factory=dict)
    # Per day, per identity register: its latest record's (time, position, file_seq, line, value, kind, data code).
    latest: dict[int, dict[int, tuple[int, int, int, int, int, int, int]]] = field(default_factory=dict)
    identity: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))  # per register: an identity label


class DayRows:
    """This ingest's records, summarised per day and register as they are stored (see the module's doc)."""

    def __init__(self) -> None:
        self.complete = True  # every record this ingest stores went through add()
        self.first = False  # the archive held no records before: stored rows, if any, are not merged
        self._registries: dict[int, _Registry] = {}

    def _identity(self, reg: _Registry) -> np.ndarray:
        n = reg.registry.n_registers
        if len(reg.identity) != n:
            from console.analysis.inventory import IDENTITY_LABELS

            arrays = reg.registry.arrays()
            canon = reg.registry.canonicals
            codes = np.where(arrays["label_known"], arrays["label_canonical"], -1)
            ids = [c for c in np.unique(codes).tolist() if c >= 0 and canon.value(c) in IDENTITY_LABELS]
            reg.identity = np.isin(codes, np.asarray(ids, codes.dtype))
        return reg.identity

    def add(self, registry: DiagRegistry, chunk: DiagChunk, file_seq: int, line_offset: int) -> None:
        """One stored chunk's records (``line_offset``: the file's lines before the ones read)."""
        reg = self._registries.get(id(registry))
        if reg is None:
            reg = self._registries[id(registry)] = _Registry(registry)
        t = np.asarray(chunk.time_ns, np.int64)
        timed = t != NO_TIME
        if not timed.any():
            return
        rid = np.asarray(chunk.register_id)
        ident = self._identity(reg)
        if ident.any():
            self._latest(reg, chunk, timed & ident[rid], file_seq, line_offset)
        if not timed.all():
            t, rid = t[timed], rid[timed]
            line = np.asarray(chunk.line, np.int64)[timed]
        else:
            line = np.asarray(chunk.line, np.int64)
        pos = line + (line_offset + (file_seq << 32))
        day = t // NS_PER_DAY
        lo, hi = int(day[0]), int(day[-1])
        n = registry.n_registers
        if lo == hi and (day == lo).all():
            self._add_day(reg, lo, n, rid, t, pos)
            return
        for d in np.unique(day).tolist():
            sel = day == d
            self._add_day(reg, int(d), n, rid[sel], t[sel], pos[sel])

    def _latest(self, reg: _Registry, chunk: DiagChunk, sel: np.ndarray, file_seq: int, line_offset: int) -> None:
        """The identity registers' latest records of the chunk (per day), kept where later than those kept."""
        idx = np.flatnonzero(sel)
        if not len(idx):
            return
        r = np.asarray(chunk.register_id)[idx]
        t = np.asarray(chunk.time_ns, np.int64)[idx]
        line = np.asarray(chunk.line, np.int64)[idx] + line_offset
        day = t // NS_PER_DAY
        o = np.lexsort((line, t, r, day))  # per day and register, the latest last
        last_of_group = np.r_[(r[o][1:] != r[o][:-1]) | (day[o][1:] != day[o][:-1]), True]
        pick = idx[o[last_of_group]]
        values = np.asarray(chunk.value)[pick].tolist()
        kinds = np.asarray(chunk.data_kind)[pick].tolist()
        datas = np.asarray(chunk.data_code)[pick].tolist()
        sel_o = o[last_of_group]
        for i, (d, rr, tt, ln) in enumerate(
            zip(day[sel_o].tolist(), r[sel_o].tolist(), t[sel_o].tolist(), line[sel_o].tolist(), strict=True)
        ):
            kept = reg.latest.setdefault(d, {})
            new = (tt, (file_seq << 32) + ln, file_seq, ln, values[i], kinds[i], datas[i])
            old = kept.get(rr)
            if old is None or new[:2] > old[:2]:
                kept[rr] = new

    def _add_day(self, reg: _Registry, day: int, n: int, rid: np.ndarray, t: np.ndarray, pos: np.ndarray) -> None:
        acc = reg.days.get(day)
        if acc is None:
            acc = reg.days[day] = _Day()
        acc.grow(n)
        acc.count += np.bincount(rid, minlength=n)
        np.minimum.at(acc.t_min, rid, t)
        np.maximum.at(acc.t_max, rid, t)
        np.minimum.at(acc.pos_min, rid, pos)

    def days(self) -> set[int]:
        """The days (since 1970) this ingest stored timed records in."""
        return {d for reg in self._registries.values() for d in reg.days}

    def identity_rows(self, day: int, stored: pa.Table | None) -> pa.Table:
        """``day``'s identity_days rows: this ingest's identity registers' latest records merged with
        ``stored`` (the day's rows of earlier ingests, or None), in the part's order (IDENTITY_GROUP)."""
        rows: dict[tuple[Any, ...], list[Any]] = {}
        for reg in self._registries.values():
            kept = reg.latest.get(day)
            if kept:
                _merge_identity(rows, reg.registry, kept)
        if stored is not None and stored.num_rows:
            cols = [stored.column(name).to_pylist() for name in IDENTITY_SCHEMA.names[:14]]
            at = arrow_np.to_numpy(stored.column("at_time").cast(pa.int64())).tolist()
            seqs = stored.column("at_file_seq").to_pylist()
            lines = stored.column("at_line").to_pylist()
            for i, row in enumerate(zip(*cols, strict=True)):
                new = [at[i], seqs[i], lines[i], *row[11:14]]
                _latest_of(rows, row[:11], new)
        keys = sorted(rows)  # ORDER BY the identity group (byte order, as DuckDB sorts text)
        vals = [rows[k] for k in keys]
        f = IDENTITY_SCHEMA
        columns: list[pa.Array] = []
        for j, name in enumerate(f.names[:11]):
            columns.append(_column([k[j] for k in keys], f.field(name).type))
        for j, name in zip((3, 4, 5), ("value", "data_kind", "data"), strict=True):
            columns.append(_column([v[j] for v in vals], f.field(name).type))
        columns.append(_column([v[0] for v in vals], pa.int64()).view(pa.timestamp("ns")))
        columns.append(_column([v[1] for v in vals], f.field("at_file_seq").type))
        columns.append(_column([v[2] for v in vals], f.field("at_line").type))
        return pa.Table.from_arrays(columns, schema=IDENTITY_SCHEMA)

    def head_rows(self, day: int, stored: pa.Table | None) -> pa.Table:
        """``day``'s head_days rows: this ingest's records merged with ``stored`` (the day's rows of the
        earlier ingests, or None), in the part's order (device_id, counting_head)."""
        rows: dict[tuple[int, str], list[Any]] = {}
        for reg in self._registries.values():
            acc = reg.days.get(day)
            if acc is not None:
                _merge_registers(rows, reg.registry, acc)
        if stored is not None and stored.num_rows:
            _merge_stored(rows, stored)
        return _table(rows)


def _merge(rows: dict[tuple[int, str], list[Any]], key: tuple[int, str], new: list[Any]) -> None:
    """Row layout: [first_pos, device, type, gs, diag_ids, channels, records, first_time, last_time]."""
    old = rows.get(key)
    if old is None:
        rows[key] = new
        return
    if new[0] < old[0]:
        old[0:4] = new[0:4]
    old[4] |= new[4]
    old[5] |= new[5]
    old[6] += new[6]
    old[7] = min(old[7], new[7])
    old[8] = max(old[8], new[8])


def _merge_registers(rows: dict[tuple[int, str], list[Any]], registry: DiagRegistry, acc: _Day) -> None:
    seen = np.flatnonzero(acc.count)
    if not len(seen):
        return
    a = registry.arrays()
    dev_id = a["device_id"][seen].tolist()
    heads = registry.heads.values
    head = [heads[c] for c in a["counting_head"][seen].tolist()]
    devices, types, gss = registry.devices.values, registry.types.values, registry.gs.values
    device = a["device"][seen].tolist()
    typ = a["type"][seen].tolist()
    gs = a["gs"][seen].tolist()
    diag = a["diag_id"][seen].tolist()
    chan = a["channel"][seen].tolist()
    cols = zip(
        acc.pos_min[seen].tolist(),
        acc.count[seen].tolist(),
        acc.t_min[seen].tolist(),
        acc.t_max[seen].tolist(),
        strict=True,
    )
    for i, (p, c, t0, t1) in enumerate(cols):
        row = [p, devices[device[i]], types[typ[i]], gss[gs[i]], {diag[i]}, {chan[i]}, c, t0, t1]
        _merge(rows, (int(dev_id[i]), head[i]), row)


def _latest_of(rows: dict[tuple[Any, ...], list[Any]], key: tuple[Any, ...], new: list[Any]) -> None:
    """Row layout: [time, file_seq, line, value, data_kind, data]; the latest by (time, file_seq, line) kept."""
    old = rows.get(key)
    if old is None or new[:3] > old[:3]:
        rows[key] = new


def _merge_identity(
    rows: dict[tuple[Any, ...], list[Any]],
    registry: DiagRegistry,
    kept: dict[int, tuple[int, int, int, int, int, int, int]],
) -> None:
    from parsers.diag.fields import DATA_KINDS

    a = registry.arrays()
    canon = registry.canonicals
    data = registry.data.values
    for rid, (t, _pos, seq, line, value, kind, code) in kept.items():
        key = (
            int(a["device_id"][rid]),
            int(a["diag_id"][rid]),
            registry.devices.values[int(a["device"][rid])],
            registry.types.values[int(a["type"][rid])],
            registry.gs.values[int(a["gs"][rid])],
            registry.heads.values[int(a["counting_head"][rid])],
            int(a["channel"][rid]),
            int(a["address"][rid]),
            registry.labels.values[int(a["label"][rid])],
            canon.value(int(a["label_canonical"][rid])),
            registry.encodings.values[int(a["label_encoding"][rid])],
        )
        _latest_of(rows, key, [t, seq, line, value, DATA_KINDS[kind], data[code]])


def _column(values: list[Any], type: pa.DataType) -> pa.Array:
    if pa.types.is_string(type):
        return arrow_np.strings(values)
    return arrow_np.array(np.asarray(values, np.int64), type)


def _merge_stored(rows: dict[tuple[int, str], list[Any]], stored: pa.Table) -> None:
    cols = {name: stored.column(name) for name in HEAD_SCHEMA.names}
    first = arrow_np.to_numpy(cols["first_time"].cast(pa.int64())).tolist()
    last = arrow_np.to_numpy(cols["last_time"].cast(pa.int64())).tolist()
    for i, (d, h, p, dev, typ, gs, ids, ch, n) in enumerate(
        zip(*(cols[c].to_pylist() for c in HEAD_SCHEMA.names[:9]), strict=True)
    ):
        _merge(rows, (d, h), [p, dev, typ, gs, set(ids), set(ch), n, first[i], last[i]])


def _table(rows: dict[tuple[int, str], list[Any]]) -> pa.Table:
    keys = sorted(rows)  # ORDER BY device_id, counting_head (byte order, as DuckDB sorts text)
    vals = [rows[k] for k in keys]

    def ints(values: list[int], type: pa.DataType) -> pa.Array:
        return arrow_np.array(np.asarray(values, np.int64), type)

    def lists(sets: list[set[int]], type: pa.DataType) -> pa.Array:
        items = [sorted(s) for s in sets]
        offsets = np.cumsum([0, *(len(x) for x in items)], dtype=np.int32)
        flat = ints([v for x in items for v in x], type.value_type)
        return pa.ListArray.from_arrays(arrow_np.array(offsets, pa.int32()), flat, type=type)

    f = HEAD_SCHEMA
    columns = [
        ints([k[0] for k in keys], f.field("device_id").type),
        arrow_np.strings([k[1] for k in keys]),
        ints([v[0] for v in vals], pa.int64()),
        arrow_np.strings([v[1] for v in vals]),
        arrow_np.strings([v[2] for v in vals]),
        arrow_np.strings([v[3] for v in vals]),
        lists([v[4] for v in vals], f.field("diag_ids").type),
        lists([v[5] for v in vals], f.field("channels").type),
        ints([v[6] for v in vals], pa.int64()),
        ints([v[7] for v in vals], pa.int64()).view(pa.timestamp("ns")),
        ints([v[8] for v in vals], pa.int64()).view(pa.timestamp("ns")),
    ]
    return pa.Table.from_arrays(columns, schema=HEAD_SCHEMA)


def stored_day_table(root: Path, rels: list[str]) -> pa.Table | None:
    """The stored rows of one day's head_days parts (None: no part)."""
    from console.archive.parts import read_part

    tables = [read_part(root, rel) for rel in rels]
    return pa.concat_tables(tables) if tables else None
