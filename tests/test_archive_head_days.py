"""The inventory's figures per day, device and head derived at ingest (console.archive.head_days): they equal
what the archived records give, whatever the ingests the files came in, and a report's inventory read from them
equals the one aggregated over the records (whole days, partial days, one head, one device)."""

from __future__ import annotations

import datetime as dt
import random
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from console.analysis.inventory import IDENTITY_LABELS
from console.archive.head_days import HEAD_DAYS, IDENTITY_DAYS
from console.archive.history_diag import _inventory
from console.archive.ingest import run_ingest
from console.archive.reader import Window
from console.archive.store import read_current
from console.archive.views import connect
from tests.conftest import SAMPLES
from tests.test_archive_derive import simulate_over_midnight

HEAD_COLUMNS = ["day", "device_id", "counting_head", "device", "type", "gs", "diag_ids", "channels", "records"]
HEAD_COLUMNS += ["first_time", "last_time"]
IDENTITY_COLUMNS = ["day", "device_id", "diag_id", "counting_head", "channel", "address", "label_canonical"]
IDENTITY_COLUMNS += ["value", "data_kind", "data"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two nights of a simulated station (over midnight), and the Osong excerpts with identity registers."""
    d = tmp_path_factory.mktemp("logs")
    sim = d / "nights.log"
    simulate_over_midnight(sim, seed=11, before_s=240, minutes=9, days=2)
    osong = d / "osong.log"
    osong.write_bytes(
        (SAMPLES / "osong_ws4_0932_detection.log").read_bytes()
        + (SAMPLES / "osong_ws4_1032_detection.log").read_bytes()
    )
    return [sim, osong]


def _stored(root: Path, table: str) -> pd.DataFrame:
    """The table's rows as the archive holds them (the day from each part's path)."""
    m = read_current(root)
    frames = []
    for rel in m.parts(table):
        df = pd.read_parquet(root / rel)
        df.insert(0, "day", rel.split("day=")[1][:10])
        frames.append(df)
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def _records(root: Path) -> pd.DataFrame:
    con, _ = connect(root)
    try:
        return con.sql("SELECT * FROM records WHERE time IS NOT NULL").df()
    finally:
        con.close()


def _want_heads(records: pd.DataFrame) -> pd.DataFrame:
    """Per (day, device, head), computed here from the records with pandas."""
    rows = []
    records = records.assign(pos=records["file_seq"].astype("int64") * 2**32 + records["line"].astype("int64"))
    for (day, device_id, head), g in records.groupby(
        [records["time"].dt.strftime("%Y-%m-%d"), "device_id", "counting_head"], dropna=False
    ):
        first = g.loc[g["pos"].idxmin()]
        rows.append(
            {
                "day": day,
                "device_id": int(device_id),
                "counting_head": head,
                "device": first["device"],
                "type": first["type"],
                "gs": first["gs"],
                "diag_ids": sorted(int(x) for x in set(g["diag_id"])),
                "channels": sorted(int(x) for x in set(g["channel"])),
                "records": len(g),
                "first_time": g["time"].min(),
                "last_time": g["time"].max(),
            }
        )
    return _ordered(pd.DataFrame(rows), HEAD_COLUMNS)


def _want_identity(records: pd.DataFrame) -> pd.DataFrame:
    ident = records[records["label_canonical"].isin(IDENTITY_LABELS)]
    ident = ident.assign(day=ident["time"].dt.strftime("%Y-%m-%d"))
    latest = ident.sort_values(["time", "file_seq", "line"], kind="stable").groupby(
        ["day", "device_id", "diag_id", "counting_head", "channel", "address", "label", "label_canonical"],
        dropna=False,
    )
    return _ordered(latest.tail(1).reset_index(drop=True), IDENTITY_COLUMNS)


def _ordered(df: pd.DataFrame, columns: list[str]) -> pd.DataFrame:
    df = df[columns].copy()
    for c in ("diag_ids", "channels"):
        if c in df:
            df[c] = [tuple(sorted(int(x) for x in v)) for v in df[c]]
    for c in ("device_id", "diag_id", "channel", "address", "value", "records"):
        if c in df:
            df[c] = df[c].astype("int64")
    for c in ("first_time", "last_time"):
        if c in df:
            df[c] = pd.to_datetime(df[c]).astype("datetime64[ns]")
    return df.sort_values(columns[:7], kind="stable").reset_index(drop=True)


def ingest_split(logs: list[Path], root: Path, how: str) -> None:
    """Ingest ``logs`` ``whole``, ``file_by_file``, or ``grown-N``: each file cut at a random line (seed N),
    ingested, then grown to its whole and ingested again."""
    if how == "whole":
        run_ingest(logs, root)
    elif how == "file_by_file":
        for log in logs:
            run_ingest([log], root)
    else:
        rng = random.Random(int(how.removeprefix("grown-")))
        grown = []
        for log in logs:
            lines = log.read_bytes().splitlines(keepends=True)
            cut = rng.randrange(1, len(lines))
            path = root.parent / f"grown-{log.name}"
            path.write_bytes(b"".join(lines[:cut]))
            grown.append((path, b"".join(lines)))
        run_ingest([p for p, _ in grown], root)
        for path, whole in grown:
            path.write_bytes(whole)
        run_ingest([p for p, _ in grown], root)


@pytest.mark.parametrize("how", ["whole", "file_by_file", "grown-1", "grown-2"])
def test_stored_rows_are_the_records_figures_whatever_the_ingests(logs: list[Path], tmp_path: Path, how: str) -> None:
    root = tmp_path / "arc"
    ingest_split(logs, root, how)
    records = _records(root)
    heads = _ordered(_stored(root, HEAD_DAYS), HEAD_COLUMNS)
    want = _want_heads(records)
    assert len(want["day"].unique()) == 4  # two nights over midnight (three days), and the Osong day
    pd.testing.assert_frame_equal(heads, want, check_dtype=False)
    ident = _ordered(_stored(root, IDENTITY_DAYS), IDENTITY_COLUMNS)
    want_ident = _want_identity(records)
    assert set(want_ident["label_canonical"]) == set(IDENTITY_LABELS)  # the Osong excerpts have them all
    pd.testing.assert_frame_equal(ident, want_ident, check_dtype=False)
    # One part per day and table: a day's part is made again, not added to.
    m = read_current(root)
    for table in (HEAD_DAYS, IDENTITY_DAYS):
        days = [rel.split("day=")[1][:10] for rel in m.parts(table)]
        assert len(days) == len(set(days))


def _inventories(con: Any, root: Path, window: Window) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    m = read_current(root)
    stored = [d.to_dict() for d in _inventory(con, window, root, m)]
    scanned = [d.to_dict() for d in _inventory(con, window)]
    return stored, scanned


def test_report_inventory_from_stored_rows_equals_the_records(logs: list[Path], tmp_path: Path) -> None:
    root = tmp_path / "arc"
    ingest_split(logs, root, "file_by_file")
    records = _records(root)
    days = sorted(records["time"].dt.normalize().unique())
    day0 = pd.Timestamp(days[1]).to_pydatetime()  # the simulated nights' first day (days[0]: the Osong excerpts')
    one = dt.timedelta(days=1)
    osong = records[records["device_id"] == 4083]
    t_osong = pd.Timestamp(osong["time"].min()).to_pydatetime()
    windows = [
        Window(day0, day0 + one),  # one whole day
        Window(day0, day0 + 3 * one),  # whole days only
        Window(day0 + dt.timedelta(hours=23, minutes=58), day0 + one + dt.timedelta(minutes=3)),  # no whole day
        Window(day0 + dt.timedelta(hours=23, minutes=58), day0 + 2 * one + dt.timedelta(minutes=3)),  # edges + day
        Window(day0, day0 + 3 * one, head="WS4"),
        Window(day0, day0 + 3 * one, device_id=4083),
        Window(t_osong.replace(hour=0, minute=0, second=0), t_osong + dt.timedelta(minutes=30)),
        Window(dt.datetime(2031, 1, 1), dt.datetime(2031, 1, 2)),  # nothing in it
    ]
    con, _ = connect(root)
    try:
        for w in windows:
            stored, scanned = _inventories(con, root, w)
            assert stored == scanned, w
        # Identity registers came through (the Osong board's designation and serial, as the paper's excerpt).
        osong_day = t_osong.replace(hour=0, minute=0, second=0, microsecond=0)
        (board,), _ = _inventories(con, root, Window(osong_day, osong_day + one, device_id=4083))
    finally:
        con.close()
    assert (board["designation"], board["serial_number"]) == ("TMC", "4803")


def test_archive_without_stored_rows_reads_the_records(logs: list[Path], tmp_path: Path) -> None:
    """An archive derived before the rows existed (no parts listed): the inventory is the records' own."""
    root = tmp_path / "arc"
    ingest_split(logs, root, "whole")
    m = read_current(root)
    m.tables[HEAD_DAYS] = []
    m.tables[IDENTITY_DAYS] = []
    w = Window(dt.datetime(2015, 1, 1), dt.datetime(2027, 1, 1))
    con, _ = connect(root)
    try:
        assert [d.to_dict() for d in _inventory(con, w, root, m)] == [d.to_dict() for d in _inventory(con, w)]
        assert _inventory(con, w, root, m)
    finally:
        con.close()
