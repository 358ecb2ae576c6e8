"""Past days' part files closed by the time watermark: the stored rows are those of an ingest that keeps them open."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from console.archive import parts
from console.archive.ingest import run_ingest
from console.archive.parts import PartWriter, read_part
from console.archive.query import run_query
from console.archive.store import read_current
from parsers.units import NS_PER_DAY
from tests.conftest import SAMPLES
from tests.test_archive_parts import _labelled

STATION = SAMPLES / "example_station.log"
TABLES = ("records", "rejected", "passages", "axles", "section_states", "count_ledger", "health_findings")


def _log_over_days(path: Path, late: bool) -> None:
    """The example station's day copied onto three days in a row; ``late``: each day's last fifth arrives after
    the next day's first half (a board whose records come in late), the days interleaved in the file."""
    lines = STATION.read_bytes().splitlines(keepends=True)
    days = [[ln.replace(b"Date:2026-03-02", f"Date:2026-03-0{d}".encode()) for ln in lines] for d in (2, 3, 4)]
    if not late:
        path.write_bytes(b"".join(b"".join(d) for d in days))
        return
    cut, half = len(lines) * 4 // 5, len(lines) // 2
    out = days[0][:cut]
    for prev, day in itertools.pairwise(days):
        out += day[:half] + prev[cut:] + day[half:cut]
    out += days[-1][cut:]
    path.write_bytes(b"".join(out))


def _stored(archive: Path) -> dict[str, pd.DataFrame]:
    out = {}
    for table in TABLES:
        names, rows = run_query(archive, f"SELECT * FROM {table}")
        df = pd.DataFrame(rows, columns=names).drop(columns=["seq"], errors="ignore")
        for c in df.columns:  # list columns (axle speeds) as tuples: sortable
            if len(df) and isinstance(df[c].iloc[0], list):
                df[c] = df[c].map(tuple)
        out[table] = df.sort_values(list(df.columns), ignore_index=True) if len(df) else df
    return out


def _parts(archive: Path, table: str) -> list[str]:
    return list(read_current(archive).parts(table))


@pytest.mark.parametrize("late", [False, True])
def test_closing_past_days_stores_the_same_rows_as_keeping_them_open(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, late: bool
) -> None:
    log = tmp_path / "days.log"
    _log_over_days(log, late)
    monkeypatch.setattr(parts, "DAY_CLOSE_MARGIN_NS", 1 << 62)  # never closed by the watermark: as before
    assert run_ingest([log], tmp_path / "open").published
    if late:
        monkeypatch.setattr(parts, "DAY_CLOSE_MARGIN_NS", 0)  # closed as soon as the stream is past the day
    else:
        monkeypatch.undo()  # the margin the ingest uses
    assert run_ingest([log], tmp_path / "closed").published
    kept, closed = _stored(tmp_path / "open"), _stored(tmp_path / "closed")
    assert len(kept["passages"]) > 0 and len(kept["axles"]) > 0
    assert kept["passages"]["day"].nunique() == 3
    for table in TABLES:
        pd.testing.assert_frame_equal(kept[table], closed[table], obj=table)
    if late:
        # A late passage of a closed day started a further part of it; the reader takes them all.
        folders = [str(Path(rel).parent) for rel in _parts(tmp_path / "closed", "passages")]
        assert len(folders) > len(set(folders))
    # In time order, with the ingest's margin, a part can still be added: a head's last passage of a day is
    # closed by its next record, here the next day's first, hours of log later.


def test_advance_writes_a_days_buffered_rows_then_closes_its_files_and_a_late_row_starts_a_second_part(
    tmp_path: Path,
) -> None:
    w = PartWriter(tmp_path, "passages", 3, "p")  # BUFFER_BYTES: nothing written out before advance
    day = 20_000
    w.add(_labelled([0], ["Radsensor"], 1), np.full(1, day), np.full(1, 5000))
    w.add(_labelled([0], ["Radsensor"], 2), np.full(1, day + 1), np.full(1, 5000))
    w.advance((day + 1) * NS_PER_DAY)  # only just past day's end: within the margin, nothing closed
    w._wait()
    assert w.written == []
    assert not w.closes_day((day + 1) * NS_PER_DAY + parts.DAY_CLOSE_MARGIN_NS - 1)
    assert w.closes_day((day + 1) * NS_PER_DAY + parts.DAY_CLOSE_MARGIN_NS)
    w.advance((day + 1) * NS_PER_DAY + parts.DAY_CLOSE_MARGIN_NS)
    assert not w.closes_day((day + 1) * NS_PER_DAY + parts.DAY_CLOSE_MARGIN_NS)  # that day is closed already
    w._wait()
    assert list(w._writers) == [(day + 1, 5000)]  # day's file written and closed, the next day's open
    w.add(_labelled([0], ["Radsensor"], 3), np.full(1, day), np.full(1, 5000))  # a late row of the closed day
    w.add(_labelled([0], ["Radsensor"], 4), np.full(1, day + 1), np.full(1, 5000))
    w.close()
    by_folder: dict[str, list[int]] = {}
    for rel in w.written:
        by_folder.setdefault(str(Path(rel).parent), []).extend(read_part(tmp_path, rel).column("line").to_pylist())
    assert len([rel for rel in w.written if "day=2024-10-04" in rel]) == 2
    assert sorted(by_folder.values()) == [[1, 3], [2, 4]]
    assert len(w.written) == 3  # the open day kept one part


def test_a_writer_not_split_by_day_ignores_the_watermark(tmp_path: Path) -> None:
    w = PartWriter(tmp_path, "rejected", 3, "l", by_device=False, by_day=False)
    w.add(_labelled([0], ["Radsensor"], 1))
    assert not w.closes_day(10**18)
    w.advance(10**18)
    w.add(_labelled([0], ["Radsensor"], 2))
    assert len(w.close()) == 1
