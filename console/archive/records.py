"""Diagnostic records between the parser's chunks and the archive's ``records`` table.

:func:`chunk_to_arrow` turns a parsed :class:`~parsers.diag.records.DiagChunk` into
Arrow columns (dictionary-encoded straight from the parser's interners, no
per-record Python).  :class:`ChunkRebuilder` goes back: Arrow batches read
from the archive become chunks keyed into a fresh
:class:`~parsers.diag.registry.DiagRegistry`, registers numbered in first-seen order,
so the analysis that ran on the files runs on the archive's records and
gives the same answer.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa

from console.archive import arrow_np
from parsers.diag.fields import DATA_KINDS, RegisterKey
from parsers.diag.records import RECORD_COLUMNS, DiagChunk
from parsers.diag.registry import DiagRegistry

# The archive's record columns as read back: the parser's RECORD_COLUMNS with label_encoding and file_seq.
# day and device_id are the partition keys (in the path): the parts store the others (RECORD_FIELDS).
ARCHIVED_RECORD_COLUMNS = tuple(
    c
    for col in RECORD_COLUMNS
    for c in ((col, "label_encoding") if col == "label_canonical" else ("file_seq", col) if col == "line" else (col,))
)
RECORD_FIELDS = tuple(c for c in ARCHIVED_RECORD_COLUMNS if c != "device_id")
REGISTER_COLUMNS = (
    "diag_id",
    "device_id",
    "device",
    "type",
    "gs",
    "counting_head",
    "channel",
    "address",
    "label",
    "label_canonical",
    "label_encoding",
)
_STR = pa.dictionary(pa.int32(), pa.string())


def _dict(codes: np.ndarray, values: list[str]) -> pa.DictionaryArray:
    """``codes`` into ``values``, the codes known to be in range (no bounds check: a pass over them)."""
    return pa.DictionaryArray.from_arrays(arrow_np.array(codes, pa.int32()), arrow_np.strings(values), safe=False)


class RecordEncoder:
    """Per-register lookup arrays of one parse, extended as registers appear."""

    def __init__(self, registry: DiagRegistry) -> None:
        self.registry = registry
        self._n = -1
        self._canon_codes = np.zeros(0, np.int32)
        self._canon_values: list[str | None] = []
        self._enc_codes = np.zeros(0, np.int32)
        self._enc_values: list[str] = []
        # Each dictionary column's values as Arrow, made again only when the registry's grow (they only grow).
        self._values: dict[str, pa.Array] = {}
        self._canon: tuple[pa.Array, np.ndarray] | None = None
        self._registers: pa.Table | None = None

    def _refresh(self) -> dict[str, np.ndarray]:
        arrays = self.registry.arrays()
        if self._n != self.registry.n_registers:
            # Canonical labels (None for an unknown label) numbered in order of first register, from the columns.
            key = np.where(arrays["label_known"], arrays["label_canonical"], -1)
            distinct, first, inverse = np.unique(key, return_index=True, return_inverse=True)
            rank = np.empty(len(distinct), np.int32)
            rank[np.argsort(first, kind="stable")] = np.arange(len(distinct), dtype=np.int32)
            self._canon_codes = rank[inverse.reshape(-1)]
            in_order = distinct[np.argsort(first, kind="stable")].tolist()
            canonicals = self.registry.canonicals
            self._canon_values = [canonicals.value(c) if c >= 0 else None for c in in_order]
            # Encodings are interned in order of first register already.
            self._enc_codes = arrays["label_encoding"]
            self._enc_values = list(self.registry.encodings.values)
            self._n = self.registry.n_registers
            self._canon = None
        return arrays

    def _canon_arrays(self) -> tuple[pa.Array, np.ndarray]:
        """The canonical labels' dictionary and which of its entries stand for no label."""
        if self._canon is None:
            # A null entry cannot sit in a dictionary that is unified later: "" stands there, masked.
            self._canon = (
                arrow_np.strings([v or "" for v in self._canon_values]),
                np.asarray([v is None for v in self._canon_values], bool),
            )
        return self._canon

    def _dict(self, name: str, codes: np.ndarray, values: list[str]) -> pa.DictionaryArray:
        """``codes`` into ``values`` as a dictionary column (the values made into Arrow once per size)."""
        known = self._values.get(name)
        if known is None or len(known) != len(values):
            known = self._values[name] = arrow_np.strings(values)
        # The codes are the registry's, into its values: no bounds check (a pass over every record's codes).
        return pa.DictionaryArray.from_arrays(arrow_np.array(codes, pa.int32()), known, safe=False)

    def registers(self) -> pa.Table:
        """The registry's registers as the stored records' register columns (row = register id): made again
        only when registers appear, so a table given earlier stays as it was (the writer thread reads it)."""
        reg = self.registry
        a = self._refresh()
        if self._registers is not None and self._registers.num_rows == reg.n_registers:
            return self._registers
        canon_dict, canon_null = self._canon_arrays()
        codes = self._canon_codes
        cols = {
            "diag_id": arrow_np.array(a["diag_id"]),
            "device": self._dict("device", a["device"], reg.devices.values),
            "type": self._dict("type", a["type"], reg.types.values),
            "gs": self._dict("gs", a["gs"], reg.gs.values),
            "counting_head": self._dict("counting_head", a["counting_head"], reg.heads.values),
            "channel": arrow_np.array(a["channel"]),
            "address": arrow_np.array(a["address"].astype(np.int16)),
            "label": self._dict("label", a["label"], reg.labels.values),
            "label_canonical": pa.DictionaryArray.from_arrays(
                arrow_np.array(codes, pa.int32(), mask=canon_null[codes]), canon_dict
            ),
            "label_encoding": self._dict("label_encoding", self._enc_codes, self._enc_values),
        }
        self._registers = pa.table(cols)
        return self._registers

    def encode_compact(
        self, chunk: DiagChunk, file_name: str, file_seq: int, line_offset: int
    ) -> tuple[pa.Table, np.ndarray, pa.Table]:
        """(records with their register's number in place of its columns, device_id per row, the registers
        they number): :func:`expand_records` of the two is the stored records' table."""
        reg = self.registry
        registers = self.registers()
        rid = chunk.register_id
        n = len(rid)
        cols = {
            "time": arrow_np.array(chunk.time_ns.view("datetime64[ns]")),
            REGISTER_NUMBER: arrow_np.array(rid.astype(np.int32, copy=False)),
            "data": self._dict("data", chunk.data_code, reg.data.values),
            "value": arrow_np.array(chunk.value),
            "data_kind": self._dict("data_kind", chunk.data_kind.astype(np.int32), list(DATA_KINDS)),
            "subsecond": arrow_np.array(chunk.subsecond),
            "file": _dict(np.zeros(n, np.int32), [file_name]),
            "file_seq": arrow_np.array(np.full(n, file_seq, np.int32)),
            "line": arrow_np.array(chunk.line + line_offset),
        }
        return pa.table(cols), self.registry.arrays()["device_id"][rid], registers


# The stored record columns that are the register's (the same on every record of a register), and the others.
REGISTER_FIELDS = tuple(c for c in REGISTER_COLUMNS if c != "device_id")
# A record as buffered before it is written (:meth:`RecordEncoder.encode_compact`): its register's number in
# place of the register's ten columns, 44 bytes where the stored columns take 75.
REGISTER_NUMBER = "register"


# The one stored record column that may hold nulls (a register of a label the catalogue does not know).  The
# others are stored as required (not null): Parquet writes no definition levels for them (a tenth of writing the
# records, on a 3 M-record log).  Parts written before, all columns nullable, read the same.
NULLABLE_RECORD_FIELDS = frozenset({"label_canonical"})


def expand_records(compact: pa.Table, registers: pa.Table) -> pa.Table:
    """Compact records (:meth:`RecordEncoder.encode_compact`) as the stored columns: each register's columns
    taken from ``registers`` (a snapshot of the registry at or after these records were parsed)."""
    import pyarrow.compute as pc  # deferred: a query's start-up imports this module, not the writing

    # A record's register number is a row of ``registers`` (a snapshot at or after it): no bounds check.
    per_register = pc.take(registers, compact.column(REGISTER_NUMBER), boundscheck=False)
    names = [n for n in RECORD_FIELDS if n != "time"]
    cols = [compact.column("time")]
    cols += [per_register.column(n) if n in REGISTER_FIELDS else compact.column(n) for n in names]
    schema = pa.schema(
        pa.field(n, c.type, nullable=n in NULLABLE_RECORD_FIELDS) for n, c in zip(["time", *names], cols, strict=True)
    )
    return pa.Table.from_arrays(cols, schema=schema)


class ChunkRebuilder:
    """Arrow record batches (from the archive, in file order) → DiagChunks of one registry."""

    def __init__(self, registry: DiagRegistry | None = None) -> None:
        self.registry = registry if registry is not None else DiagRegistry()
        # A registry that has registers already (a pipeline's, whose chunks came from a parser) keeps their ids.
        self._rids: dict[RegisterKey, int] = {key: rid for rid, key in enumerate(self.registry.registers)}
        self._files: dict[int, int] = {}  # file_seq → file_id

    @property
    def registers_by_key(self) -> dict[RegisterKey, int]:
        """The registry's registers by what they are (shared with a :class:`ChunkTranslator` into it)."""
        return self._rids

    def file_id(self, file_seq: int, name: str) -> int:
        found = self._files.get(file_seq)
        if found is None:
            found = self._files[file_seq] = len(self.registry.files)
            # A rotated file leaves two files of one name: names of a read are unique.
            shown, n = name, 1
            while shown in self.registry.files:
                n += 1
                shown = f"{name} ({n})"
            self.registry.files.append(shown)
        return found

    def seed(self, registers: pa.RecordBatch | None) -> None:
        """Number these registers first, in this order (the order the files meet them), whatever order
        the records then come in."""
        if registers is not None and registers.num_rows:
            self._register_ids(registers)

    def file_seq_of(self, file_id: int) -> int:
        """The archive's file number of a chunk's file id."""
        for seq, fid in self._files.items():  # a few files
            if fid == file_id:
                return seq
        raise KeyError(file_id)

    def _register_ids(self, batch: pa.RecordBatch) -> np.ndarray:
        codes = []
        dicts = []
        for name in REGISTER_COLUMNS:
            col = batch.column(name)
            if not pa.types.is_dictionary(col.type):
                col = col.dictionary_encode()
            codes.append(col.indices.fill_null(0).to_numpy(zero_copy_only=False).astype(np.int64))
            dicts.append(col.dictionary.to_pylist())
            # Nulls (no canonical label) get their own code.
            if col.null_count:
                c = codes[-1]
                c[np.asarray(col.is_null())] = len(dicts[-1])
                dicts[-1].append(None)
        sizes = [len(d) + 1 for d in dicts]
        if float(np.prod(np.array(sizes, np.float64))) < 2.0**62:
            # One mixed-radix integer per row, factorized by hash in first-seen order (as the parser numbers
            # registers): a few ms per million rows, where a row-wise unique sorts.
            import pandas as pd

            mixed = np.zeros(len(codes[0]), np.int64)
            for c, size in zip(codes, sizes, strict=True):
                mixed = mixed * size + c
            inverse, uniq_keys = pd.factorize(mixed)
            uniq = np.empty((len(uniq_keys), len(codes)), np.int64)
            rest = np.asarray(uniq_keys, np.int64)
            for j in range(len(codes) - 1, -1, -1):
                uniq[:, j] = rest % sizes[j]
                rest = rest // sizes[j]
            order: list[int] = list(range(len(uniq)))
        else:
            stacked = np.stack(codes, axis=1)
            uniq, first, inverse = np.unique(stacked, axis=0, return_index=True, return_inverse=True)
            order = np.argsort(first, kind="stable").tolist()
        lut = np.empty(len(uniq), np.int32)
        for u in order:
            vals = [dicts[j][int(uniq[u, j])] for j in range(len(REGISTER_COLUMNS))]
            key = RegisterKey(
                diag_id=int(vals[0]),
                device_id=int(vals[1]),
                device=vals[2],
                type=vals[3],
                gs=vals[4],
                counting_head=vals[5],
                channel=int(vals[6]),
                address=int(vals[7]),
                label=vals[8],
                label_canonical=vals[9],
                label_encoding=vals[10],
            )
            lut[u] = self._add_register(key)
        return lut[inverse.reshape(-1)]

    def _add_register(self, key: RegisterKey) -> int:
        found = self._rids.get(key)
        if found is not None:
            return found
        rid = self._rids[key] = self.registry.add_register(key)
        return rid

    def chunks(self, batch: pa.RecordBatch) -> list[DiagChunk]:
        """One chunk per input file in the batch (rows must be in file, line order)."""
        if batch.num_rows == 0:
            return []
        rid = self._register_ids(batch)
        data = batch.column("data")
        if not pa.types.is_dictionary(data.type):
            data = data.dictionary_encode()
        data_lut = np.array([self.registry.data.code(v) for v in data.dictionary.to_pylist()], np.int32)
        data_code = data_lut[data.indices.to_numpy(zero_copy_only=False)]
        kind = batch.column("data_kind")
        kind_values = kind.dictionary.to_pylist() if pa.types.is_dictionary(kind.type) else None
        if kind_values is not None:
            kind_lut = np.array([DATA_KINDS.index(v) for v in kind_values], np.int8)
            data_kind = kind_lut[kind.indices.to_numpy(zero_copy_only=False)]
        else:
            data_kind = np.array([DATA_KINDS.index(v) for v in kind.to_pylist()], np.int8)
        time_ns = batch.column("time").cast(pa.int64()).to_numpy(zero_copy_only=False)
        seq = batch.column("file_seq").to_numpy(zero_copy_only=False)
        files = batch.column("file")
        cuts = np.flatnonzero(np.r_[True, seq[1:] != seq[:-1], True])
        out = []
        value = batch.column("value").to_numpy(zero_copy_only=False).astype(np.int64)
        subsecond = batch.column("subsecond").to_numpy(zero_copy_only=False).astype(bool)
        line = batch.column("line").to_numpy(zero_copy_only=False).astype(np.int64)
        for a, b in zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True):
            fid = self.file_id(int(seq[a]), str(files[a].as_py()))
            ch = DiagChunk(
                file_id=fid,
                register_id=rid[a:b].astype(np.int32),
                time_ns=time_ns[a:b],
                subsecond=subsecond[a:b],
                value=value[a:b],
                data_code=data_code[a:b],
                data_kind=data_kind[a:b],
                line=line[a:b],
            )
            self.registry.count_records(ch.register_id)
            out.append(ch)
        return out


class ChunkTranslator:
    """Chunks keyed into one registry (a reader's) as chunks keyed into another (a pipeline's own).

    Registers, data values and files are mapped by what they are, once each: a pipeline that lives across
    ingests keeps its registry while every file is parsed with a fresh one.
    """

    def __init__(self, src: DiagRegistry, dst: DiagRegistry, rids: dict[RegisterKey, int]) -> None:
        self.src, self.dst = src, dst
        self._rids = rids  # the destination's registers by key (shared by every translator into it)
        self._rid_map = np.zeros(0, np.int32)
        self._data_map = np.zeros(0, np.int32)
        self._file_map: dict[int, int] = {}

    def translate(self, chunk: DiagChunk) -> DiagChunk:
        src, dst = self.src, self.dst
        if len(self._rid_map) < src.n_registers:
            self._rid_map = np.r_[self._rid_map, np.full(src.n_registers - len(self._rid_map), -1, np.int32)]
        # Only the registers the chunk holds, in the source's order (first seen first): the destination
        # numbers them as a read of these records alone would.
        used = np.unique(chunk.register_id)
        for rid in used[self._rid_map[used] < 0].tolist():  # once per register
            key = src.register(rid)
            found = self._rids.get(key)
            if found is None:
                found = self._rids[key] = dst.add_register(key)
            self._rid_map[rid] = found
        n_data = len(src.data)
        if len(self._data_map) < n_data:
            values = [src.data.value(i) for i in range(len(self._data_map), n_data)]
            self._data_map = np.r_[self._data_map, dst.data.codes(values).astype(np.int32)]
        fid = self._file_map.get(chunk.file_id)
        if fid is None:
            name = src.files[chunk.file_id] if chunk.file_id < len(src.files) else str(chunk.file_id)
            fid = self._file_map[chunk.file_id] = len(dst.files)
            dst.files.append(name)
        rid = self._rid_map[chunk.register_id]
        dst.count_records(rid)
        return DiagChunk(
            file_id=fid,
            register_id=rid,
            time_ns=chunk.time_ns,
            subsecond=chunk.subsecond,
            value=chunk.value,
            data_code=self._data_map[chunk.data_code],
            data_kind=chunk.data_kind,
            line=chunk.line,
        )
