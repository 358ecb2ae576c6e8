"""The compiled reduction of records to activity runs (console/analysis/passages/compiled_runs.c) and the numpy
one give the same columns.

Both run over the same records and register tables: the head key per record, every run column (counts, first
and last times overall and per system) and the positions of the wheel-sensor records must be equal, dtypes
included.  The inputs: random tables and records (times before 1970 and on whole seconds, heads interleaved,
channels other than 1 and 2, values other than 0 and 1), and whole reads through the command either way.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages import buckets, stream
from parsers.diag.records import DiagChunk
from tests.compiled_parts import needs_compiled
from tests.conftest import SAMPLES

pytestmark = needs_compiled(buckets.compiled_runs, "console.analysis.passages.compiled_runs")


@dataclass
class Tables:
    head: np.ndarray
    channel: np.ndarray
    is_wheel: np.ndarray


@st.composite
def chunks(draw: st.DrawFn) -> tuple[Tables, dict[str, np.ndarray], bool]:
    n_registers = draw(st.integers(1, 12))
    tables = Tables(
        head=np.array(
            draw(st.lists(st.integers(0, 2**31 - 1) | st.integers(0, 4), min_size=n_registers, max_size=n_registers)),
            np.int32,
        ),
        channel=np.array(draw(st.lists(st.integers(-1, 3), min_size=n_registers, max_size=n_registers)), np.int8),
        is_wheel=np.array(draw(st.lists(st.booleans(), min_size=n_registers, max_size=n_registers)), bool),
    )
    n = draw(st.integers(0, 60))
    # Steps of a few ms to a few s from a start anywhere, before 1970 too: runs of one second and breaks.
    start_ns = draw(st.integers(-(10**18), 10**18))
    steps = draw(st.lists(st.integers(-2 * 10**9, 3 * 10**9), min_size=n, max_size=n))
    whole = draw(st.booleans())
    time_ns = start_ns + np.cumsum(np.array(steps, np.int64))
    if whole:  # a whole-second board's stamps
        time_ns = time_ns // 10**9 * 10**9
    records = {
        "register_id": np.array(draw(st.lists(st.integers(0, n_registers - 1), min_size=n, max_size=n)), np.int32),
        "time_ns": time_ns.astype(np.int64),
        "subsecond": np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), bool),
        "value": np.array(draw(st.lists(st.integers(-1, 2), min_size=n, max_size=n)), np.int64),
    }
    return tables, records, draw(st.booleans())


def _chunk(register_id: np.ndarray, time_ns: np.ndarray, subsecond: np.ndarray, value: np.ndarray) -> DiagChunk:
    n = len(register_id)
    zeros = np.zeros(n, np.int32)
    return DiagChunk(0, register_id, time_ns, subsecond, value, zeros, zeros.astype(np.int8), np.arange(n))


def _alike(got: tuple, want: tuple) -> None:
    (g_head, g_runs, g_wheel), (w_head, w_runs, w_wheel) = got, want
    assert g_head.dtype == w_head.dtype == np.int64
    assert np.array_equal(g_head, w_head)
    assert sorted(g_runs) == sorted(w_runs) == sorted(buckets.BUCKET_COLUMNS)
    for name in buckets.BUCKET_COLUMNS:
        assert g_runs[name].dtype == w_runs[name].dtype == np.int64, name
        assert np.array_equal(g_runs[name], w_runs[name]), name
    assert g_wheel.dtype == w_wheel.dtype == np.int64
    assert np.array_equal(g_wheel, w_wheel)


@settings(max_examples=400, deadline=None)
@given(case=chunks())
def test_random_records_reduce_alike(case: tuple[Tables, dict[str, np.ndarray], bool]) -> None:
    tables, rec, keep_releases = case
    args = (_chunk(rec["register_id"], rec["time_ns"], rec["subsecond"], rec["value"]), tables, keep_releases)
    _alike(buckets._record_runs_compiled(*args), buckets._record_runs_numpy(*args))


def test_realistic_chunk_reduces_alike() -> None:
    """Many records of one second in a row, several boards interleaved, both systems: the usual chunk."""
    rng = np.random.default_rng(7)
    n = 50_000
    tables = Tables(
        head=rng.integers(0, 80, 400).astype(np.int32),
        channel=rng.integers(1, 3, 400).astype(np.int8),
        is_wheel=rng.random(400) < 0.3,
    )
    time_ns = 1_772_409_600 * 10**9 + np.sort(rng.integers(0, 600 * 10**9, n))
    chunk = _chunk(
        rng.integers(0, 400, n).astype(np.int32), time_ns, rng.random(n) < 0.9, rng.integers(0, 2, n).astype(np.int64)
    )
    for keep_releases in (False, True):
        got = buckets._record_runs_compiled(chunk, tables, keep_releases)
        _alike(got, buckets._record_runs_numpy(chunk, tables, keep_releases))


def test_a_record_naming_no_register_is_refused() -> None:
    tables = Tables(np.zeros(2, np.int32), np.ones(2, np.int8), np.ones(2, bool))
    one = np.zeros(1, np.int64)
    with pytest.raises(IndexError, match="names no register"):
        buckets._record_runs_compiled(_chunk(np.array([2], np.int32), one, np.ones(1, bool), one), tables, False)


def test_pure_switch_chooses_the_numpy_path() -> None:
    probe = "from console.analysis.passages import buckets; print(buckets.compiled_record_runs())"
    env = {k: v for k, v in os.environ.items() if k != "TRACKSIDE_PURE"}
    outs = [
        subprocess.run([sys.executable, "-c", probe], env=e, capture_output=True, text=True, check=True).stdout
        for e in (env, {**env, "TRACKSIDE_PURE": "1"})
    ]
    assert [o.strip() for o in outs] == ["True", "False"]


def test_speeds_and_sections_alike_through_the_command(tmp_path: Path) -> None:
    """The releases kept (sections) and not (speeds): whole commands either way, byte for byte."""
    log = tmp_path / "real.log"
    generate(6000, log, boards=4, resolution="mixed", seed=11, corrupt_every=80, block_s=90)
    trackside = Path(sys.executable).with_name("trackside")
    env = {k: v for k, v in os.environ.items() if k != "TRACKSIDE_PURE"}
    station = SAMPLES / "example_station.log"
    for command in (["speeds", "--json", str(log)], ["sections", "--json", "--layout", "example", str(station)]):
        outs = [
            subprocess.run([str(trackside), *command], env=e, capture_output=True, timeout=120, check=False)
            for e in (env, {**env, "TRACKSIDE_PURE": "1"})
        ]
        assert outs[0].returncode == outs[1].returncode == 0, outs[0].stderr
        assert outs[0].stdout == outs[1].stdout, command
        assert len(outs[0].stdout) > 100, command


@st.composite
def head_records(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, int, int]:
    n_heads = draw(st.integers(1, 6))
    n = draw(st.integers(1, 80))
    heads = np.array(draw(st.lists(st.integers(0, n_heads - 1), min_size=n, max_size=n)), np.int64)
    # Steps of exactly the gap too: a pause is longer than the gap, not as long.
    step = st.integers(0, 30 * 10**9) | st.sampled_from([10**9, 10 * 10**9])
    steps = draw(st.lists(step, min_size=n, max_size=n))
    time_ns = draw(st.integers(-(10**18), 10**18)) + np.cumsum(np.array(steps, np.int64))
    if draw(st.booleans()):  # boards out of step: some head's times go back (the numpy sort then)
        i, j = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
        time_ns[[i, j]] = time_ns[[j, i]]
    gap_ns = draw(st.sampled_from([10**9, 10 * 10**9]))
    return heads, time_ns, gap_ns, n_heads


def _by_head(spans: tuple[np.ndarray, ...]) -> list[np.ndarray]:
    order = np.argsort(spans[0])
    return [c[order] for c in spans]


@settings(max_examples=400, deadline=None)
@given(case=head_records())
def test_head_spans_alike(case: tuple[np.ndarray, np.ndarray, int, int]) -> None:
    heads, time_ns, gap_ns, n_heads = case
    slot = np.full(n_heads + 3, -1, np.int32)
    got = _by_head(stream._head_spans_compiled(heads, time_ns, gap_ns, slot))
    want = _by_head(stream._head_spans_numpy(heads, time_ns, gap_ns, slot.copy()))
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype == np.int64
        assert np.array_equal(g, w)
    assert (slot == -1).all()  # the scratch is left as it was found


def test_head_spans_refuse_a_head_beyond_the_scratch() -> None:
    one = np.zeros(1, np.int64)
    with pytest.raises(IndexError, match="beyond the slots"):
        stream._head_spans_compiled(np.array([4]), one, 10**9, np.full(4, -1, np.int32))


@st.composite
def run_parts(draw: st.DrawFn) -> list[dict[str, np.ndarray]]:
    """Runs as chunks leave them: several parts, one (head, second) repeated within and across parts."""
    wide = draw(st.booleans())  # seconds or heads beyond the one-key sort: lexsort then
    parts = []
    for _ in range(draw(st.integers(1, 4))):
        n = draw(st.integers(0, 25))
        col = {
            "head": st.integers(0, 2**40 if wide else 3),
            "second": st.integers(-(2**40), 2**40) if wide else st.integers(1_772_409_600, 1_772_409_603),
            "records": st.integers(0, 50),
            "t_first_ns": st.integers(-(2**62), 2**62),
            "t_last_ns": st.integers(-(2**62), 2**62),
        }
        part = {
            c: np.array(draw(st.lists(col.get(c, col["records"]), min_size=n, max_size=n)), np.int64)
            for c in ("head", "second", "records", "records_sys1", "records_sys2", "records_whole_second")
        }
        for c in buckets.BUCKET_COLUMNS[6:]:
            key = "t_first_ns" if "first" in c else "t_last_ns"
            part[c] = np.array(draw(st.lists(col[key], min_size=n, max_size=n)), np.int64)
        parts.append(part)
    return parts


@settings(max_examples=400, deadline=None)
@given(parts=run_parts())
def test_runs_merge_alike(parts: list[dict[str, np.ndarray]]) -> None:
    runs = np.stack([np.concatenate([p[c] for p in parts]) for c in buckets.BUCKET_COLUMNS])
    assert np.array_equal(buckets._by_head_and_second(runs[0], runs[1]), np.lexsort((runs[1], runs[0])))
    got, want = buckets._merge_runs_compiled(runs), buckets._merge_runs_numpy(runs)
    for name in buckets.BUCKET_COLUMNS:
        assert got[name].dtype == want[name].dtype == np.int64, name
        assert np.array_equal(got[name], want[name]), name
    keys = list(zip(want["head"].tolist(), want["second"].tolist(), strict=True))
    assert keys == sorted(set(keys))  # one bucket per head and second, in order


@settings(max_examples=300, deadline=None)
@given(
    n=st.integers(0, 6),
    items=st.lists(st.tuples(st.integers(0, 5), st.integers(-(2**63), 2**63 - 1), st.integers(0, 3)), max_size=40),
    wanted=st.integers(1, 2),
)
def test_group_extremes_alike(n: int, items: list[tuple[int, int, int]], wanted: int) -> None:
    items = [i for i in items if i[0] < n]
    group, values, channel = (np.array([i[k] for i in items], np.int64) for k in range(3))
    got = buckets._group_extremes_compiled(n, group, values, channel, wanted)
    want = buckets._group_extremes_numpy(n, group, values, channel, wanted)
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype == np.int64
        assert np.array_equal(g, w)


@settings(max_examples=300, deadline=None)
@given(rows=st.lists(st.binary(min_size=7, max_size=7), max_size=20), zeros=st.integers(0, 6))
def test_rows_squeeze_alike(rows: list[bytes], zeros: int) -> None:
    """Rows padded with 0 bytes anywhere (a zero byte every ``zeros``), squeezed to their texts."""
    a = np.frombuffer(b"".join(rows), np.uint8).reshape(len(rows), 7).copy() if rows else np.zeros((0, 7), np.uint8)
    if zeros:
        a[:, ::zeros] = 0
    got, want = buckets._squeeze_rows_compiled(a), buckets._squeeze_rows_numpy(a)
    assert got[0] == want[0]
    assert got[1].dtype == want[1].dtype == np.int64
    assert np.array_equal(got[1], want[1])


@settings(max_examples=300, deadline=None)
@given(
    keys=st.lists(st.tuples(st.integers(0, 6), st.integers(-5, 5)), max_size=40),
    probes=st.lists(st.tuples(st.integers(0, 7), st.integers(-7 * 10**9, 7 * 10**9)), max_size=60),
    twice=st.booleans(),
)
def test_compiled_and_numpy_bucket_lookups_agree(
    keys: list[tuple[int, int]], probes: list[tuple[int, int]], twice: bool
) -> None:
    """Each (head, time) to the first bucket row of its head and second (floored: times before 1970 too), or -1;
    a key listed twice gives its first row either way."""
    rows = sorted(set(keys)) if not twice else sorted(keys)
    cols = {
        "head": np.array([h for h, _ in rows], np.int64),
        "second": np.array([s for _, s in rows], np.int64),
    }
    head = np.array([h for h, _ in probes], np.int64)
    time_ns = np.array([t for _, t in probes], np.int64)
    # Probes on the keys' own seconds too, so that many are found.
    head = np.r_[head, cols["head"]]
    time_ns = np.r_[time_ns, cols["second"] * 1_000_000_000 + 999_999_999]
    compiled = buckets._bucket_index_compiled(cols, head, time_ns)
    numpy = buckets._bucket_index_numpy(cols, head, time_ns)
    assert compiled.dtype == numpy.dtype
    np.testing.assert_array_equal(compiled, numpy)
