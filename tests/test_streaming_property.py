"""Streaming analysis equals a whole-file read, at any chunk size (issue 12).

`stream_files` closes passages per counting head while it reads a log in
chunks; `analyze_files` reduces the whole log first.  Over realistic
multi-board logs (benchmarks/gen_realistic_diag.py: boards stamping
microseconds, milliseconds or whole seconds, interleaved at random, damaged
lines) and simulated runs, for chunk sizes down to a single record, both give
the same passages (with speeds), axles, device inventory, unpaired count and
parse report.  Without ``--include-status`` the status-only passages are
counted per head, and the counts add up to the passages listed with it.

CI runs a few examples; ``TRACKSIDE_LONG=1`` runs many more.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.status import STATUS_KIND
from console.layout import load_layout
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_diagnostic
from tests.reads import DiagJob, stream_job, whole_job

LONG = bool(os.environ.get("TRACKSIDE_LONG"))
EXAMPLES = 200 if LONG else 6
# Each chunk costs about a millisecond of fixed work: tiny chunks get small logs in CI.
TINY_RECORDS = (300, 3000) if LONG else (200, 600)
RECORDS = (1000, 20_000) if LONG else (1500, 4000)
SIM_RUN_S = 4 * 3600 if LONG else 1200

CASE = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
IDLE_GAPS = st.sampled_from([2.0, 10.0, 30.0])


def _axle_rows(job: DiagJob) -> list[tuple[object, ...]]:
    """The axles as rows in one canonical order (a stream emits them batch by batch)."""
    cols = job.analysis.axle_columns
    order = np.lexsort((cols["t_sys2_ns"], cols["t_sys1_ns"], cols["time_ns"], cols["head"]))
    return list(zip(*(np.asarray(cols[c])[order].tolist() for c in sorted(cols)), strict=True))


def assert_same_as_whole(whole: DiagJob, streamed: DiagJob) -> None:
    a, b = whole.analysis, streamed.analysis
    assert b.heads == a.heads
    assert b.passages_json_text() == a.passages_json_text()
    # NaN speeds (a whole-second passage has none) compare equal as text.
    assert repr(_axle_rows(streamed)) == repr(_axle_rows(whole))
    assert [d.to_dict() for d in b.devices] == [d.to_dict() for d in a.devices]
    assert b.unpaired_detections == a.unpaired_detections
    assert streamed.report.to_dict() == whole.report.to_dict()


def assert_status_adds_up(with_status: DiagJob, summarised: DiagJob) -> None:
    """Passages without --include-status, plus the status ones counted per head, are those with it."""
    full, kept = with_status.analysis.passage_columns, summarised.analysis.passage_columns
    assert summarised.status is not None and with_status.status is None
    n_full = len(full["head"]) if full is not None else 0
    n_kept = len(kept["head"]) if kept is not None else 0
    assert n_kept + int(summarised.status.passages.sum()) == n_full
    if full is None:
        return
    status = full["kind"] == STATUS_KIND
    per_head = np.bincount(full["head"][status], minlength=len(with_status.analysis.heads))
    counted = np.zeros(len(per_head), np.int64)
    counted[: len(summarised.status.passages)] = summarised.status.passages
    assert counted.tolist() == per_head.tolist()
    assert int(summarised.status.records.sum()) == int(full["records"][status].sum())
    if kept is not None:
        assert not (kept["kind"] == STATUS_KIND).any()
        assert kept["start_ns"].tolist() == full["start_ns"][~status].tolist()


def check_log(path: Path, chunk_bytes: int, idle_gap_s: float) -> DiagJob:
    s = SpeedSettings(idle_gap_s=idle_gap_s)
    whole = whole_job([path], s)
    streamed = stream_job([path], s, chunk_bytes=chunk_bytes)
    assert streamed.late_records == 0  # exports in time order: nothing came after its passage closed
    assert_same_as_whole(whole, streamed)
    assert_status_adds_up(streamed, stream_job([path], s, chunk_bytes=chunk_bytes, include_status=False))
    return whole


def _realistic(tmp_path: Path, records: int, boards: int, seed: int, interleave: int) -> tuple[Path, dict]:
    path = tmp_path / "real.log"
    # Short blocks of simulated time (small logs) and one damaged line in 50.
    truth = generate(records, path, boards=boards, seed=seed, interleave_seed=interleave, corrupt_every=50, block_s=60)
    return path, truth


@CASE
@given(
    records=st.integers(*TINY_RECORDS),
    boards=st.integers(2, 6),
    seed=st.integers(1, 10_000),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(64, 2000),
    idle_gap_s=IDLE_GAPS,
)
def test_realistic_log_in_chunks_of_a_few_records_equals_a_whole_read(
    tmp_path: Path, records: int, boards: int, seed: int, interleave: int, chunk_bytes: int, idle_gap_s: float
) -> None:
    path, truth = _realistic(tmp_path, records, boards, seed, interleave)
    whole = check_log(path, chunk_bytes, idle_gap_s)
    assert whole.report.records == truth["records"]
    assert whole.report.rejected == truth["corrupt_lines"]


@CASE
@given(
    records=st.integers(*RECORDS),
    boards=st.integers(2, 12),
    seed=st.integers(1, 10_000),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(2000, 200_000),
    idle_gap_s=IDLE_GAPS,
)
def test_realistic_log_in_any_chunks_equals_a_whole_read(
    tmp_path: Path, records: int, boards: int, seed: int, interleave: int, chunk_bytes: int, idle_gap_s: float
) -> None:
    path, truth = _realistic(tmp_path, records, boards, seed, interleave)
    whole = check_log(path, chunk_bytes, idle_gap_s)
    assert whole.report.records == truth["records"]
    assert whole.report.rejected == truth["corrupt_lines"]


@pytest.fixture(scope="module")
def sim_run() -> StationSim:
    sim = StationSim(load_layout("example"), SimConfig(seed=7, trains_per_hour=12))
    sim.run(SIM_RUN_S)
    return sim


@CASE
@given(
    resolution=st.sampled_from(["us", "ms", "s", "mixed"]),
    interleave=st.integers(0, 2**31),
    chunk_bytes=st.integers(64, 100_000),
    idle_gap_s=IDLE_GAPS,
)
def test_simulated_run_in_any_chunks_equals_a_whole_read(
    tmp_path: Path, sim_run: StationSim, resolution: str, interleave: int, chunk_bytes: int, idle_gap_s: float
) -> None:
    heads = [h.id for h in sim_run.layout.heads]
    res: str | dict[str, str] = (
        {h: ("us", "ms", "s")[i % 3] for i, h in enumerate(heads)} if resolution == "mixed" else resolution
    )
    path = tmp_path / "sim.log"
    write_diagnostic(sim_run, path, resolution=res, interleave_seed=interleave)
    whole = check_log(path, chunk_bytes, idle_gap_s)
    trains = [p for p in whole.analysis.passages_json() if p["kind"] == "train"]
    assert sum(p["axles"] for p in trains) == len(sim_run.truth_axles)


def test_a_log_out_of_time_order_is_counted_as_late(tmp_path: Path) -> None:
    """Two halves of an export swapped: records come after their head's passage closed."""
    path, _ = _realistic(tmp_path, 3000, 3, 1, 0)
    lines = path.read_bytes().splitlines(keepends=True)
    swapped = tmp_path / "swapped.log"
    swapped.write_bytes(b"".join(lines[len(lines) // 2 :] + lines[: len(lines) // 2]))
    assert stream_job([path], SpeedSettings(), chunk_bytes=20_000).late_records == 0
    late = stream_job([swapped], SpeedSettings(), chunk_bytes=20_000)
    assert late.late_records > 0
    # Read whole, as the commands then do, it is the whole read.
    whole = stream_job([swapped], SpeedSettings(), chunk_bytes=20_000, whole=True)
    assert whole.analysis.passages_json_text() == whole_job([swapped], SpeedSettings()).analysis.passages_json_text()
