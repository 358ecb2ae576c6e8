"""Derived tables equal batch analysis: a log split at random points and ingested piece by piece
gives what one ingest gives, and what `analyze` / `report` compute on the whole file.

The hypothesis profile here runs EXAMPLES examples (a few seconds each); more with
``TRACKSIDE_ARCHIVE_EXAMPLES=50``.
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.archive.history import cross_head_tables, report_data
from console.archive.ingest import run_ingest
from console.archive.query import run_query
from console.archive.reader import ArchivedRecords
from console.archive.store import read_current
from console.drivers.batch import ReadOptions, read_diag
from console.engine.pipeline import PipelineSettings
from console.sinks.report.collect import collect
from tests.conftest import SAMPLES
from tests.reads import whole_job


def tables_from(data: object) -> dict[str, pd.DataFrame]:
    """The derived tables of one ReportData: its job's passages and axles, and the cross-head tables."""
    import numpy as np

    job = data.job  # type: ignore[attr-defined]
    out: dict[str, pd.DataFrame] = {}
    if job is not None:
        p = job.analysis.passages.copy()
        p["start"] = pd.to_datetime(p["start_ns"], unit="ns")
        out["passages"] = p
        ax = job.analysis.axles.copy()
        heads = job.analysis.heads
        ax["device_id"] = np.array([h[0] for h in heads], np.int64)[ax["head"].to_numpy()]
        ax["counting_head"] = np.array([h[1] for h in heads], object)[ax["head"].to_numpy()]
        ax["time"] = pd.to_datetime(ax["time_ns"], unit="ns")
        out["axles"] = ax.drop(columns=["head"])
    out.update(cross_head_tables(data))  # type: ignore[arg-type]
    return out


EXAMPLES = int(os.environ.get("TRACKSIDE_ARCHIVE_EXAMPLES", 4))
STATION = SAMPLES / "example_station.log"
DATA = STATION.read_bytes()
SORT = {
    "passages": "counting_head, start_ns",
    "axles": "counting_head, time_ns, direction",
    "section_states": "time_ns, section, state",
    "count_ledger": "time_ns, section, head",
    "health_findings": "rule, counting_head, channel, message",
}


def _stored(archive: Path, table: str) -> pd.DataFrame:
    names, rows = run_query(archive, f"SELECT * FROM {table} ORDER BY {SORT[table]}")
    # seq orders the section history's rows that share an instant: it numbers rows per ingest.
    return pd.DataFrame(rows, columns=names).drop(columns=["seq"], errors="ignore")


def _batch_tables() -> dict[str, pd.DataFrame]:
    """Passages and axles as ``analyze`` computes them, the cross-head tables as ``report`` does.

    (The report reads a log streaming since 3bcc3b8 and keeps no axle table: its job's analysis is
    not the whole batch analysis, so passages and axles come from ``analyze_files``.)
    """
    data = collect([STATION], "example", whole=True)  # the section history as tables, not spooled
    assert data.job is not None
    data.job = whole_job([STATION], data.job.analysis.settings, keep_releases=True)
    return tables_from(data)


BATCH = _batch_tables()


def _assert_same(a: dict[str, pd.DataFrame], b: dict[str, pd.DataFrame]) -> None:
    assert sorted(a) == sorted(b)
    for name in a:
        pd.testing.assert_frame_equal(
            a[name].reset_index(drop=True), b[name].reset_index(drop=True), check_dtype=False, obj=name
        )


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cuts=st.lists(st.integers(1, len(DATA) - 1), min_size=1, max_size=3, unique=True))
def test_piece_by_piece_equals_one_ingest_and_batch_analysis(tmp_path_factory: object, cuts: list[int]) -> None:
    tmp = tmp_path_factory.mktemp("eq")  # type: ignore[attr-defined]
    log = tmp / "station.log"
    pieces = tmp / "pieces"
    whole = tmp / "whole"
    log.write_bytes(b"")
    start = 0
    for cut in [*sorted(cuts), len(DATA)]:
        with log.open("ab") as f:
            f.write(DATA[start:cut])  # cuts fall anywhere, mid-line included
        start = cut
        run_ingest([log], pieces, layout="example")
    whole_log = tmp / "whole" / "station.log"
    whole_log.parent.mkdir()
    whole_log.write_bytes(DATA)
    run_ingest([whole_log], whole / "arc", layout="example")

    # Stored derived tables: pieces == one ingest.
    for table in SORT:
        pd.testing.assert_frame_equal(_stored(pieces, table), _stored(whole / "arc", table), obj=table)
    # The archive's analysis == the report's and analyze's on the file.
    _assert_same(tables_from(report_data(pieces)), BATCH)
    m = read_current(pieces)
    job = read_diag(ArchivedRecords(pieces, m), PipelineSettings(), opts=ReadOptions(hold_passages=True))
    batch_job = whole_job([STATION], job.analysis.settings, keep_releases=True)
    assert job.analysis.passages_json_text() == batch_job.analysis.passages_json_text()
    assert job.analysis.unpaired_detections == batch_job.analysis.unpaired_detections
    assert [d.to_dict() for d in job.analysis.devices] == [d.to_dict() for d in batch_job.analysis.devices]
    assert job.report.records == batch_job.report.records == len(DATA.splitlines())
