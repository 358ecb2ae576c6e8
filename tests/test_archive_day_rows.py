"""The head_days rows an ingest gathers as it stores the records (console.archive.day_rows), merged with the
day's stored rows: the same table, type for type, as the DuckDB aggregate over all of the day's records gives,
whatever the split of the files between ingests; and days the merge cannot make exactly are made from the
records as before."""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from console.archive import head_days
from console.archive.head_days import HEAD_DAYS, IDENTITY_DAYS, days_of_parts
from console.archive.ingest import run_ingest
from console.archive.store import read_current
from tests.conftest import SAMPLES
from tests.test_archive_derive import simulate_over_midnight
from tests.test_archive_head_days import ingest_split


@pytest.fixture(scope="module")
def nights(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two nights over midnight, in two files (one per night), plus whole-second and sub-second boards."""
    d = tmp_path_factory.mktemp("nights")
    a, b = d / "night-a.log", d / "night-b.log"
    simulate_over_midnight(a, seed=21, before_s=200, minutes=7, days=1)
    simulate_over_midnight(b, seed=5, before_s=150, minutes=6, days=2)
    sub = d / "ws4.log"
    sub.write_bytes((SAMPLES / "ws4_subsecond.log").read_bytes())
    return [a, b, sub]


def _from_records(root: Path) -> dict[str, dict[str, pa.Table]]:
    """Each day's rows made from all of that day's records (the aggregate the merge replaces), by table."""
    m = read_current(root)
    out: dict[str, dict[str, pa.Table]] = {}
    by_day: dict[str, list[str]] = {}
    for rel in m.parts("records"):
        for day in days_of_parts([rel]):
            by_day.setdefault(day, []).append(rel)
    for day, rels in by_day.items():
        for table, rel in head_days._day_parts(root, 999_999, day, rels):
            out.setdefault(table, {})[day] = pq.read_table(root / rel)
            (root / rel).unlink()
    return out


def _stored(root: Path, table: str = HEAD_DAYS) -> dict[str, pa.Table]:
    m = read_current(root)
    return {days_of_parts([rel]).pop(): pq.read_table(root / rel) for rel in m.parts(table)}


@pytest.mark.parametrize("how", ["whole", "file_by_file", "grown-1", "grown-2"])
def test_merged_rows_equal_the_records_aggregate(
    nights: list[Path], tmp_path: Path, how: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    made_from_records: list[str] = []
    real = head_days._day_parts

    def counted(root: Path, generation: int, day: str, records: list[str]) -> list[tuple[str, str]]:
        made_from_records.append(day)
        return real(root, generation, day, records)

    monkeypatch.setattr(head_days, "_day_parts", counted)
    root = tmp_path / "arc"
    ingest_split(nights, root, how)
    assert not made_from_records  # no identity registers here: every day merged, none read back
    monkeypatch.setattr(head_days, "_day_parts", real)
    stored = _stored(root)
    want = _from_records(root)[HEAD_DAYS]
    assert len(want) >= 3  # the nights' days, and the sub-second board's
    assert sorted(stored) == sorted(want)
    for day, table in want.items():
        assert stored[day].schema.equals(table.schema, check_metadata=True), day
        assert stored[day].equals(table), day


def test_identity_registers_merged_over_ingests(
    nights: list[Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The Osong excerpts (every identity register, the same registers in both) in two ingests, beside the
    nights: the identity rows keep the later excerpt's values, as the records' aggregate does."""
    root = tmp_path / "arc"
    real = head_days._day_parts
    monkeypatch.setattr(head_days, "_day_parts", None)  # not called: every day merged
    run_ingest([nights[0], SAMPLES / "osong_ws4_0932_detection.log"], root)
    run_ingest([SAMPLES / "osong_ws4_1032_detection.log", nights[1]], root)
    monkeypatch.setattr(head_days, "_day_parts", real)
    stored = _stored(root, IDENTITY_DAYS)
    made = _from_records(root)
    want = made[IDENTITY_DAYS]
    stored_heads = _stored(root)
    for day, t in made[HEAD_DAYS].items():
        assert stored_heads[day].equals(t), day
    assert want and sorted(stored) == sorted(want)
    for day, table in want.items():
        assert stored[day].schema.equals(table.schema, check_metadata=True), day
        assert stored[day].equals(table), day
