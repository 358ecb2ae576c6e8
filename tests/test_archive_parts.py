"""Record parts as the ingest writes them: one per partition, sorted row groups, bounded buffers, compaction."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from console.archive import parts
from console.archive.parts import PartWriter, compact, read_part
from parsers.units import NS_PER_DAY

HEADS = ["WS1", "WS2", "WS3"]


def _chunk(rng: np.random.Generator, n: int, t0: int) -> tuple[pa.Table, np.ndarray, np.ndarray]:
    """n records in time order, heads interleaved, over 3 boards and 2 days."""
    time_ns = t0 + np.sort(rng.integers(0, 10**9, n))
    head = rng.integers(0, len(HEADS), n)
    device = rng.integers(0, 3, n) + 5000
    day = time_ns // NS_PER_DAY
    table = pa.table(
        {
            "time": pa.array(time_ns.view("datetime64[ns]")),
            "counting_head": pa.DictionaryArray.from_arrays(pa.array(head, pa.int32()), pa.array(HEADS)),
            "value": pa.array(rng.integers(0, 100, n)),
            "line": pa.array(np.arange(t0, t0 + n)),
        }
    )
    return table, day, device


def _write(tmp_path: Path, chunks: int, rows: int) -> tuple[PartWriter, set[int]]:
    rng = np.random.default_rng(7)
    w = PartWriter(tmp_path, "records", 3, "r", sort_by=("counting_head", "time"))
    lines: set[int] = set()
    # Half a second before midnight: the first chunk straddles two days.
    start = 20_000 * NS_PER_DAY - 5 * 10**8
    for k in range(chunks):
        table, day, device = _chunk(rng, rows, start + k * 10**9)
        lines.update(table.column("line").to_pylist())
        w.add(table, day, device)
    w.close()
    return w, lines


def _check_sorted(table: pa.Table) -> None:
    head = np.asarray(table.column("counting_head").combine_chunks().indices)
    t = table.column("time").cast(pa.int64()).to_numpy()
    key = np.lexsort((t, head))
    assert (key == np.arange(len(key))).all()


def test_one_part_per_partition_rows_complete_and_row_groups_sorted_by_head_then_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(parts, "BUFFER_BYTES", 20_000)  # write out every few chunks: several row groups
    w, lines = _write(tmp_path, chunks=12, rows=700)
    # 3 boards x 2 days, one file each.
    assert len(w.written) == 6
    assert len({Path(rel).parent for rel in w.written}) == 6
    seen: list[int] = []
    row_groups = 0
    for rel in w.written:
        f = pq.ParquetFile(tmp_path / rel)
        row_groups += f.num_row_groups
        day = rel.split("day=")[1][:10]
        device = int(rel.split("device_id=")[1].split("/")[0])
        for g in range(f.num_row_groups):
            rg = f.read_row_group(g)
            _check_sorted(rg)
            days = {str(d)[:10] for d in rg.column("time").to_pylist()}
            assert days == {day}, (rel, days)
        seen += read_part(tmp_path, rel).column("line").to_pylist()
        assert device in (5000, 5001, 5002)
    assert row_groups > 6  # the buffer was written out before the end
    assert sorted(seen) == sorted(lines)


def test_open_files_are_bounded_and_a_closed_partition_continues_in_a_second_part(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(parts, "BUFFER_BYTES", 5_000)
    monkeypatch.setattr(parts, "MAX_OPEN_WRITERS", 2)
    w, lines = _write(tmp_path, chunks=6, rows=300)
    assert len(w.written) > 6  # some partitions were closed and reopened as a second part
    assert any(rel.endswith("-r1.parquet") for rel in w.written)
    seen = [x for rel in w.written for x in read_part(tmp_path, rel).column("line").to_pylist()]
    assert sorted(seen) == sorted(lines)


def test_compact_merges_parts_into_one_sorted_part(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(parts, "BUFFER_BYTES", 5_000)
    monkeypatch.setattr(parts, "MAX_OPEN_WRITERS", 1)
    w, _ = _write(tmp_path, chunks=4, rows=200)
    folders = [Path(rel).parent for rel in w.written]
    folder = max(folders, key=folders.count)
    same = [rel for rel in w.written if Path(rel).parent == folder]
    assert len(same) >= 2
    before = sorted(x for rel in same for x in read_part(tmp_path, rel).column("line").to_pylist())
    out = compact(tmp_path, same, str(folder / "g000004-c.parquet"), ("counting_head", "time"))
    merged = read_part(tmp_path, out)
    assert sorted(merged.column("line").to_pylist()) == before
    _check_sorted(merged)
    assert merged.schema.equals(read_part(tmp_path, same[0]).schema)


def test_rows_in_input_order_are_written_in_that_order_and_times_are_delta_coded(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    w = PartWriter(tmp_path, "records", 3, "r", sort_by=("line",))
    for k in range(5):
        table, day, device = _chunk(rng, 400, 20_000 * NS_PER_DAY + k * 10**9)
        w.add(table, day, device)
    w.close()
    for rel in w.written:
        f = pq.ParquetFile(tmp_path / rel)
        lines = read_part(tmp_path, rel).column("line").to_numpy()
        assert (np.diff(lines) > 0).all()
        cols = {f.metadata.row_group(0).column(i).path_in_schema: f.metadata.row_group(0).column(i) for i in range(4)}
        assert "DELTA_BINARY_PACKED" in cols["time"].encodings
        assert "DELTA_BINARY_PACKED" in cols["line"].encodings
        assert any("DICTIONARY" in e for e in cols["value"].encodings)


def _labelled(codes: list[int], labels: list[str], first_line: int) -> pa.Table:
    n = len(codes)
    return pa.table(
        {
            "time": pa.array(np.full(n, 20_000 * NS_PER_DAY, np.int64).view("datetime64[ns]")),
            "label": pa.DictionaryArray.from_arrays(pa.array(codes, pa.int32()), pa.array(labels)),
            "line": pa.array(np.arange(first_line, first_line + n)),
        }
    )


@pytest.mark.parametrize("second_file", [False, True])
def test_growing_and_foreign_dictionaries_keep_every_value(tmp_path: Path, second_file: bool) -> None:
    # The encoder's dictionaries grow chunk by chunk (a prefix each time); another file's do not.
    chunks = [
        _labelled([0, 1, 0], ["Radsensor", "Diagnose"], 1),
        _labelled([2, 0], ["Radsensor", "Diagnose", "Status"], 4),
        _labelled([1, 1], ["Radsensor", "Diagnose"], 6),
        _labelled([0, 1], ["Zähler", "Radsensor"] if second_file else ["Radsensor", "Diagnose"], 8),
    ]
    w = PartWriter(tmp_path, "records", 3, "r")
    expected: list[str] = []
    for t in chunks:
        expected += [str(v) for v in t.column("label").to_pylist()]
        w.add(t, np.full(t.num_rows, 20_000), np.full(t.num_rows, 5000))
    w.close()
    assert len(w.written) == 1
    got = read_part(tmp_path, w.written[0])
    assert got.column("label").to_pylist() == expected
    assert got.column("line").to_pylist() == list(range(1, 10))


def test_a_partition_idle_for_some_write_outs_is_closed_and_a_late_row_starts_a_second_part(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(parts, "BUFFER_BYTES", 1)  # a write-out after every table
    monkeypatch.setattr(parts, "IDLE_WRITE_OUTS", 2)
    w = PartWriter(tmp_path, "records", 3, "r")
    day1 = [_labelled([0], ["Radsensor"], line) for line in (1, 2)]
    day2 = [_labelled([0], ["Radsensor"], line) for line in (3, 4, 5)]
    for t in day1:
        w.add(t, np.full(1, 20_000), np.full(1, 5000))
    assert len(w._writers) == 1
    for t in day2:
        w.add(t, np.full(1, 20_001), np.full(1, 5000))
    assert list(w._writers) == [(20_001, 5000)]  # day 1's file is closed
    w.add(_labelled([0], ["Radsensor"], 6), np.full(1, 20_000), np.full(1, 5000))  # a late record of day 1
    w.close()
    day1_parts = [rel for rel in w.written if "day=2024-10-04" in rel]
    assert len(day1_parts) == 2
    assert sorted(x for rel in day1_parts for x in read_part(tmp_path, rel).column("line").to_pylist()) == [1, 2, 6]


def test_statistics_are_written_for_filtered_columns_only(tmp_path: Path) -> None:
    heads = pa.DictionaryArray.from_arrays(pa.array([0, 1], pa.int32()), pa.array(["WS1", "WS2"]))
    t = (
        _labelled([0, 1], ["Radsensor", "Diagnose"], 1)
        .append_column("data", pa.array(["0001", "0002"]))
        .append_column("counting_head", heads)
    )
    rel = parts.write_part(tmp_path, "p.parquet", t)
    rg = pq.ParquetFile(tmp_path / rel).metadata.row_group(0)
    cols = {rg.column(i).path_in_schema: rg.column(i) for i in range(rg.num_columns)}
    assert cols["time"].is_stats_set and cols["line"].is_stats_set
    assert cols["counting_head"].is_stats_set  # a query for a head skips the other boards' parts
    assert (cols["counting_head"].statistics.min, cols["counting_head"].statistics.max) == ("WS1", "WS2")
    assert not cols["data"].is_stats_set  # in NO_STATISTICS
    assert not cols["label"].is_stats_set  # every row group of a board's part holds every label


def test_write_batch_rows_change_no_byte_of_a_part(tmp_path: Path) -> None:
    """The writer's step size is CPU only: pages are cut by their own limits, so the file is the same."""
    rng = np.random.default_rng(5)
    n = 300_000  # more rows than a page holds (20,000) and than one step of either size
    labels = pa.array(["Radsensor", "Diagnose", "Summe"])
    t = pa.table(
        {
            "time": pa.array(np.cumsum(rng.integers(0, 10**6, n)).view("datetime64[ns]")),
            "label": pa.DictionaryArray.from_arrays(pa.array(rng.integers(0, 3, n, dtype=np.int32)), labels),
            "value": pa.array(rng.integers(0, 50, n)),
            "line": pa.array(np.arange(1, n + 1)),
        }
    )
    ours = parts.write_part(tmp_path, "ours.parquet", t)
    default = tmp_path / "default.parquet"
    with pq.ParquetWriter(default, t.schema, compression=parts.COMPRESSION, **parts.encodings(t.schema)) as w:
        w.write_table(t, row_group_size=parts.ROW_GROUP_ROWS)
    assert parts.WRITE_BATCH_ROWS != 1024  # Arrow's default, written above
    assert (tmp_path / ours).read_bytes() == default.read_bytes()
    assert pq.read_table(tmp_path / ours).equals(t)


@pytest.mark.parametrize("seed", range(6))
def test_partition_order_is_the_stable_sort_of_the_keys(seed: int) -> None:
    """The radix path over (day, device) ranks gives np.argsort's stable permutation, and so does the fallback
    when the pairs do not fit 16 bits (devices far apart, many days)."""
    rng = np.random.default_rng(seed)
    n = 50_000
    devices = rng.choice([5000, 5001, 5039, 7, 0] if seed % 2 else [3, 2**31 + 5, 90_000], n)
    days = 20_000 + rng.integers(0, 3 if seed < 4 else 900, n)
    key = days.astype(np.int64) * (1 << 32) + devices.astype(np.int64)
    assert (parts._stable_order(key) == np.argsort(key, kind="stable")).all()


def test_the_buffer_size_changes_only_the_row_groups_of_parts_in_input_order(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The buffer bounds an ingest's memory: a smaller one cuts the same rows, in the same order, into more row
    groups (records keep their input order: no ``sort_by``)."""

    def write(name: str, buffer_bytes: int) -> tuple[Path, list[str]]:
        monkeypatch.setattr(parts, "BUFFER_BYTES", buffer_bytes)
        rng = np.random.default_rng(11)
        root = tmp_path / name
        w = PartWriter(root, "records", 3, "r")
        start = 20_000 * NS_PER_DAY - 5 * 10**8  # the first chunk straddles two days
        for k in range(6):
            w.add(*_chunk(rng, 400, start + k * 10**9))
        w.close()
        return root, sorted(w.written)

    def row_groups(root: Path, rels: list[str]) -> int:
        return sum(pq.ParquetFile(root / rel).metadata.num_row_groups for rel in rels)

    big, big_rels = write("big", 64 << 20)
    small, small_rels = write("small", 5_000)
    assert big_rels and small_rels == big_rels
    assert row_groups(small, small_rels) > row_groups(big, big_rels)
    for rel in big_rels:
        a, b = read_part(big, rel), read_part(small, rel)
        assert a.num_rows > 0 and b.schema.equals(a.schema) and b.equals(a), rel
