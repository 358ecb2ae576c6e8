"""Records buffered with their register's number (RecordEncoder.encode_compact) are stored as the columns
gathered per record (the reference :func:`_encode` below)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from console.archive import arrow_np
from console.archive.parse_pass import RECORD_ORDER
from console.archive.parts import PartWriter
from console.archive.records import RecordEncoder, expand_records
from parsers.diag.fields import DATA_KINDS
from parsers.diag.read import DiagReader
from parsers.diag.records import DiagChunk
from parsers.units import NS_PER_DAY

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
LOGS = sorted(SAMPLES.glob("*.log"))


def _chunks(paths: list[Path]) -> tuple[RecordEncoder, list]:
    reader = DiagReader(paths, chunk_bytes=16 << 10, workers=1)  # small chunks: registers appear between them
    enc = RecordEncoder(reader.registry)
    return enc, list(reader.chunks())


def _encode(
    enc: RecordEncoder, chunk: DiagChunk, file_name: str, file_seq: int, line_offset: int
) -> tuple[pa.Table, np.ndarray]:
    """The stored records' table of one chunk, every register column gathered per record: the reference the
    compact records (a register number per record, expanded as written) must equal."""
    reg = enc.registry
    a = enc._refresh()
    rid = chunk.register_id
    n = len(rid)
    canon_codes = enc._canon_codes[rid]
    canon_dict, canon_null = enc._canon_arrays()
    canon = pa.DictionaryArray.from_arrays(
        arrow_np.array(canon_codes, pa.int32(), mask=canon_null[canon_codes]), canon_dict
    )
    device_id = a["device_id"][rid]
    cols = {
        "time": arrow_np.array(chunk.time_ns.view("datetime64[ns]")),
        "diag_id": arrow_np.array(a["diag_id"][rid]),
        "device": enc._dict("device", a["device"][rid], reg.devices.values),
        "type": enc._dict("type", a["type"][rid], reg.types.values),
        "gs": enc._dict("gs", a["gs"][rid], reg.gs.values),
        "counting_head": enc._dict("counting_head", a["counting_head"][rid], reg.heads.values),
        "channel": arrow_np.array(a["channel"][rid]),
        "address": arrow_np.array(a["address"][rid].astype(np.int16)),
        "label": enc._dict("label", a["label"][rid], reg.labels.values),
        "label_canonical": canon,
        "label_encoding": enc._dict("label_encoding", enc._enc_codes[rid], enc._enc_values),
        "data": enc._dict("data", chunk.data_code, reg.data.values),
        "value": arrow_np.array(chunk.value),
        "data_kind": enc._dict("data_kind", chunk.data_kind.astype(np.int32), list(DATA_KINDS)),
        "subsecond": arrow_np.array(chunk.subsecond),
        "file": pa.DictionaryArray.from_arrays(
            arrow_np.array(np.zeros(n, np.int32), pa.int32()), arrow_np.strings([file_name])
        ),
        "file_seq": arrow_np.array(np.full(n, file_seq, np.int32)),
        "line": arrow_np.array(chunk.line + line_offset),
    }
    # Stored as required columns, but for the canonical label (null: a label the catalogue does not know).
    schema = pa.schema(pa.field(name, col.type, nullable=name == "label_canonical") for name, col in cols.items())
    return pa.table(cols, schema=schema), device_id


def _dense(t: pa.Table) -> pa.Table:
    return pa.table(
        [c.cast(c.type.value_type) if pa.types.is_dictionary(c.type) else c for c in t.columns], names=t.column_names
    )


def test_compact_records_expand_to_the_encoded_columns() -> None:
    enc, chunks = _chunks(LOGS)
    assert len(chunks) > 3
    nulls = sizes = 0
    for chunk in chunks:
        full, devices = _encode(enc, chunk, "x.log", 4, 100)
        compact, compact_devices, registers = enc.encode_compact(chunk, "x.log", 4, 100)
        out = expand_records(compact, registers)
        assert out.schema.equals(full.schema)
        assert out.equals(full)
        assert (compact_devices == devices).all()
        nulls += full.column("label_canonical").null_count  # labels the catalogue does not know
        sizes += compact.nbytes < full.nbytes
    assert nulls > 0
    assert sizes == len(chunks)


def test_a_writer_of_compact_records_stores_each_registrys_records_as_encoded(tmp_path: Path) -> None:
    """Two registries' records interleaved in one writer: each expanded with its own registers (rows of another
    registry are written out first), stored as the reference's columns."""
    a_enc, a_chunks = _chunks(LOGS[: len(LOGS) // 2])
    b_enc, b_chunks = _chunks(LOGS[len(LOGS) // 2 :])
    w = PartWriter(tmp_path, "records", 1, "r", sort_by=RECORD_ORDER, expand=expand_records)
    expected = []
    for i in range(max(len(a_chunks), len(b_chunks))):
        for seq, enc, chunks in ((1, a_enc, a_chunks), (2, b_enc, b_chunks)):
            if i >= len(chunks):
                continue
            chunk, file_seq = chunks[i], seq * 1000 + i  # (file_seq, line): one record
            expected.append(_encode(enc, chunk, f"{seq}.log", file_seq, 0)[0])
            compact, devices, registers = enc.encode_compact(chunk, f"{seq}.log", file_seq, 0)
            w.add(compact, chunk.time_ns // NS_PER_DAY, devices, context=(enc.registry, registers))
    written = w.close()
    stored = pa.concat_tables([_dense(pq.read_table(tmp_path / rel, partitioning=None)) for rel in written])
    want = _dense(pa.concat_tables(expected, promote_options="permissive"))
    assert stored.num_rows == want.num_rows
    order = np.lexsort((stored.column("line").to_numpy(), stored.column("file_seq").to_numpy()))
    want_order = np.lexsort((want.column("line").to_numpy(), want.column("file_seq").to_numpy()))
    assert stored.take(pa.array(order)).equals(want.take(pa.array(want_order)))


def test_one_partitions_compact_rows_are_expanded_a_quarter_buffer_at_a_time(tmp_path: Path) -> None:
    enc, chunks = _chunks(LOGS)
    buffer = 400_000
    w = PartWriter(
        tmp_path, "records", 1, "r", by_day=False, by_device=False, buffer_bytes=buffer, expand=expand_records
    )
    expected = []
    for i, chunk in enumerate(chunks):
        expected.append(_encode(enc, chunk, "x.log", i, 0)[0])
        compact, _, registers = enc.encode_compact(chunk, "x.log", i, 0)
        w.add(compact, context=(enc.registry, registers))
    (rel,) = w.close()
    f = pq.ParquetFile(tmp_path / rel)
    sizes = [f.metadata.row_group(g).num_rows for g in range(f.num_row_groups)]
    want = pa.concat_tables(expected, promote_options="permissive")
    row_bytes = want.nbytes / want.num_rows  # an upper bound: each chunk's dictionaries counted again
    assert len(sizes) > 3  # one write-out of the whole (a buffer of compact rows), written a step at a time
    assert max(sizes) <= max(1024, buffer / 4 / 80, buffer / 4 / row_bytes * 1.5)  # the first step guesses 80
    assert _dense(f.read()).equals(_dense(want))
