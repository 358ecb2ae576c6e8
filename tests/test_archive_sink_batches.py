"""The archive's passages and axles, made into tables a batch of the pipeline's calls at a time, are the rows a
table per call gave: every partition's rows, in order (only the write-outs, the row groups, fall elsewhere)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from benchmarks.gen_realistic_diag import generate
from console.archive import derive_sink
from console.archive.derive_sink import concat_passages, passages_table
from console.archive.ingest import run_ingest
from console.archive.store import read_current
from parsers.diag import read as diag_read

HEADS = [(7001, "A1"), (7001, "A2"), (7002, "B1")]


def _calls(rng: np.random.Generator, n_calls: int) -> list[dict[str, Any]]:
    """Passage columns of several calls, each with its own flat axle speeds (slices not in passage order)."""
    out = []
    for _ in range(n_calls):
        n = int(rng.integers(0, 6))
        lengths = rng.integers(0, 4, n)
        flat = rng.uniform(5, 120, int(lengths.sum()) + 3)  # a few speeds no passage of the call holds
        base = np.cumsum(np.r_[0, lengths])[:-1] + 3
        starts = rng.permutation(base)
        cols: dict[str, Any] = {c: rng.uniform(0, 9, n) for c in derive_sink.PASSAGE_COLUMNS[2:]}
        for c in ("direction", "whole_train_basis", "kind"):
            cols[c] = rng.integers(0, 2, n).astype(np.int8)
        for c in ("detection_second_ns", "records_in_detection_second"):  # integers stored, NaN: none
            cols[c] = np.where(rng.random(n) < 0.5, np.nan, rng.integers(0, 10**9, n).astype(np.float64))
        cols["head"] = rng.integers(0, len(HEADS), n).astype(np.int64)
        cols["start_ns"] = np.sort(rng.integers(0, 10**15, n)).astype(np.int64)
        cols["axle_speeds_start"] = starts.astype(np.int64)
        # Each passage's slice is as long as the passage at its start says (the slices are shuffled).
        by_start = dict(zip(base.tolist(), lengths.tolist(), strict=True))
        cols["axle_speeds_stop"] = np.array([s + by_start[s] for s in starts.tolist()], np.int64)
        cols["axle_speeds_kmh"] = flat
        out.append(cols)
    return out


@pytest.mark.parametrize("seed", range(5))
def test_joined_calls_make_the_tables_of_each_call(seed: int) -> None:
    calls = _calls(np.random.default_rng(seed), 6)
    one_by_one = pa.concat_tables([passages_table(c, HEADS)[1] for c in calls])
    dev_each = np.concatenate([passages_table(c, HEADS)[0] for c in calls])
    device_id, joined = passages_table(concat_passages(calls), HEADS)
    assert joined.equals(one_by_one)
    assert device_id.tolist() == dev_each.tolist()
    # Each passage's speeds are the slice its own call held.
    speeds = joined.column("axle_speeds_kmh").to_pylist()
    want = [
        c["axle_speeds_kmh"][a:b].tolist()
        for c in calls
        for a, b in zip(c["axle_speeds_start"], c["axle_speeds_stop"], strict=True)
    ]
    assert speeds == want


def _rows(root: Path, table: str) -> dict[str, pa.Table]:
    """Per partition folder, the rows of its parts in the manifest's order."""
    manifest = read_current(root)
    by: dict[str, list[str]] = {}
    for rel in manifest.parts(table):
        by.setdefault(os.path.dirname(rel), []).append(rel)
    return {
        folder: pa.concat_tables([pq.read_table(root / rel, partitioning=None) for rel in rels]).combine_chunks()
        for folder, rels in by.items()
    }


@pytest.fixture(scope="module")
def log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("batches") / "r.log"
    generate(30_000, path, boards=6, seed=11)
    return path


def test_an_ingest_stores_the_rows_of_a_table_per_call(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, log: Path
) -> None:
    class SmallChunks(diag_read.DiagReader):
        def __init__(self, *args: Any, **kwargs: Any) -> None:
            super().__init__(*args, chunk_bytes=48 << 10, **kwargs)

    monkeypatch.setattr(diag_read, "DiagReader", SmallChunks)
    calls: list[int] = []
    passages = derive_sink.ArchiveSink.passages

    def counted(self: Any, cols: Any, heads: Any) -> None:
        calls.append(len(cols["head"]))
        passages(self, cols, heads)

    monkeypatch.setattr(derive_sink.ArchiveSink, "passages", counted)
    stored = {}
    for batch_rows in (0, 60, derive_sink.PASSAGE_BATCH_ROWS):  # a table per call (as before), some, one
        monkeypatch.setattr(derive_sink, "PASSAGE_BATCH_ROWS", batch_rows)
        root = tmp_path / f"arc{batch_rows}"
        run_ingest([log], root)
        stored[batch_rows] = {t: _rows(root, t) for t in ("passages", "axles")}
    assert len(calls) >= 3 * 10, "the pipeline handed its passages on in many calls"
    first = stored[0]
    assert sum(t.num_rows for t in first["axles"].values()) > 100
    for other in list(stored.values())[1:]:
        for table in ("passages", "axles"):
            assert sorted(other[table]) == sorted(first[table])
            for folder, rows in first[table].items():
                assert other[table][folder].equals(rows), (table, folder)
