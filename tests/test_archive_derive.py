"""Derived passages and axles equal analyze's on the whole log, however the log was split into ingests.

Simulator logs run over midnight (several heads, passages crossing 00:00);
the log is cut at random points (midnight among them) and each piece
ingested on its own: every later ingest resumes from the pipeline state the
one before saved.  The stored passages and axles are compared with
``analyze`` of the whole file.  More examples with
``TRACKSIDE_ARCHIVE_EXAMPLES=50``.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.archive.ingest import run_ingest
from console.archive.query import run_query
from console.layout import load_layout
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_diagnostic
from parsers.units import NS, NS_PER_DAY
from tests.reads import whole_job

EXAMPLES = int(os.environ.get("TRACKSIDE_ARCHIVE_EXAMPLES", 3))
MIDNIGHT_S = int(dt.datetime(2026, 3, 2, tzinfo=dt.UTC).timestamp()) + 86_400  # 2026-03-03 00:00 UTC


def simulate_over_midnight(path: Path, seed: int, before_s: int, minutes: int, days: int = 1) -> None:
    """A diagnostic log of ``minutes`` starting ``before_s`` before midnight, on ``days`` consecutive nights."""
    lines: list[str] = []
    for night in range(days):
        start = (MIDNIGHT_S + night * 86_400 - before_s) * NS
        sim = StationSim(
            load_layout("example"), SimConfig(seed=seed + night, trains_per_hour=40, first_train_s=30, start_ns=start)
        )
        sim.run(minutes * 60)
        part = path.with_suffix(f".{night}")
        write_diagnostic(sim, part)
        lines += part.read_text(encoding="utf-8").splitlines()
        part.unlink()
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


PASSAGE_COLUMNS = ["device_id", "counting_head", "start_ns", "end_ns", "records", "axles", "kind"]
AXLE_COLUMNS = ["device_id", "counting_head", "time_ns", "t_sys1_ns", "t_sys2_ns", "direction"]


def _stored(archive: Path, table: str, columns: list[str]) -> pd.DataFrame:
    names, rows = run_query(archive, f"SELECT {', '.join(columns)} FROM {table} ORDER BY {', '.join(columns[:3])}")
    return pd.DataFrame(rows, columns=names)


def _analyzed(log: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    job = whole_job([log])
    p = job.analysis.passages[PASSAGE_COLUMNS].sort_values(PASSAGE_COLUMNS[:3]).reset_index(drop=True)
    ax = job.analysis.axles
    heads = job.analysis.heads
    ax = ax.assign(device_id=[heads[h][0] for h in ax["head"]], counting_head=[heads[h][1] for h in ax["head"]])[
        AXLE_COLUMNS
    ]
    return p, ax.sort_values(AXLE_COLUMNS[:3]).reset_index(drop=True)


def _ingest_in_pieces(log: Path, archive: Path, cuts: list[int]) -> int:
    """The log written to a growing file piece by piece, an ingest after each; the number of ingests."""
    data = log.read_bytes()
    grown = log.with_name("grown.log")
    grown.write_bytes(b"")
    start = 0
    n = 0
    for cut in [*sorted(set(cuts)), len(data)]:
        with grown.open("ab") as f:
            f.write(data[start:cut])
        start = cut
        run_ingest([grown], archive, layout="example")
        n += 1
    return n


def _assert_equal_to_analyze(log: Path, archive: Path) -> None:
    passages, axles = _analyzed(log)
    pd.testing.assert_frame_equal(_stored(archive, "passages", PASSAGE_COLUMNS), passages, check_dtype=False)
    if len(axles):
        pd.testing.assert_frame_equal(_stored(archive, "axles", AXLE_COLUMNS), axles, check_dtype=False)
    else:
        assert run_query(archive, "SELECT count(*) FROM axles")[1] == [(0,)]


def _midnight_offset(log: Path) -> int:
    """The byte offset of the first line stamped on 2026-03-03 (the cut at midnight)."""
    data = log.read_bytes()
    at = data.find(b"Date:2026-03-03")
    return data.rfind(b"\n", 0, at) + 1 if at > 0 else len(data) // 2


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    seed=st.integers(1, 1000),
    before_s=st.integers(30, 900),
    nights=st.integers(1, 2),
    fractions=st.lists(st.floats(0.01, 0.99), max_size=3),
)
def test_ingests_split_anywhere_equal_analyze_over_midnight(
    tmp_path_factory: object, seed: int, before_s: int, nights: int, fractions: list[float]
) -> None:
    tmp = tmp_path_factory.mktemp("part")  # type: ignore[attr-defined]
    log = tmp / "sim.log"
    simulate_over_midnight(log, seed, before_s, minutes=25, days=nights)
    size = log.stat().st_size
    cuts = [_midnight_offset(log), *(int(f * size) for f in fractions)]
    _ingest_in_pieces(log, tmp / "arc", cuts)
    days = {r[0] for r in run_query(tmp / "arc", "SELECT DISTINCT day FROM passages")[1]}
    assert dt.date(2026, 3, 2) in days or dt.date(2026, 3, 3) in days
    _assert_equal_to_analyze(log, tmp / "arc")


def test_passage_longer_than_a_day_is_one_passage(tmp_path: Path) -> None:
    """A head writing every 5 s for 40 hours, ingested a day at a time: one passage, on its first day."""
    start = (MIDNIGHT_S - 3600) * NS
    times = start + 5 * NS * pd.RangeIndex(40 * 720).to_numpy()
    stamp = pd.to_datetime(times, unit="ns")
    lines = [
        f"Diag_id:00002\tID:4081\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:WS1\tch:1\tAdr:000\tLabel:Diagnose I"
        f"\tData:2\tDate:{t.strftime('%Y-%m-%d')}\tTime:{t.strftime('%H:%M:%S.%f')}"
        for t in stamp
    ]
    log = tmp_path / "long.log"
    log.write_text("\n".join(lines) + "\n", encoding="utf-8")
    text = log.read_bytes()
    cuts = [text.find(b"Date:2026-03-03"), text.find(b"Date:2026-03-04")]
    assert _ingest_in_pieces(log, tmp_path / "arc", [text.rfind(b"\n", 0, c) + 1 for c in cuts]) == 3
    _names, rows = run_query(tmp_path / "arc", "SELECT day, start_ns, end_ns, records FROM passages")
    assert rows == [(dt.date(2026, 3, 2), int(times[0]), int(times[-1]), len(lines))]
    assert (int(times[-1]) // NS_PER_DAY) - (start // NS_PER_DAY) == 2
    _assert_equal_to_analyze(log, tmp_path / "arc")
