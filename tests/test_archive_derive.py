"""Derived passages and axles per (device, day) partition equal analyze's on the whole log, whatever the split.

Simulator logs run over midnight (several heads, passages crossing 00:00);
the partitions are derived one by one and in runs of consecutive days, and
compared with ``analyze`` of the whole file.  More examples with
``TRACKSIDE_ARCHIVE_EXAMPLES=50``.
"""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.analysis.timefmt import NS
from console.archive.history import speed_settings
from console.archive.ingest import run_ingest
from console.archive.partition import (
    NS_PER_DAY,
    Carried,
    PartitionKey,
    axles_table,
    carried_state,
    combine,
    derive_partition,
    derive_run,
    partitions,
    passages_table,
)
from console.archive.store import read_current
from console.layout import load_layout
from console.sim.station import SimConfig, StationSim
from console.sim.writers import write_diagnostic
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


def _sorted(df: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    return df.sort_values(by, kind="stable").reset_index(drop=True)


def _assert_equal_to_analyze(log: Path, got: dict[str, pd.DataFrame], s: object) -> None:
    job = whole_job([log], s, keep_releases=True)  # type: ignore[arg-type]
    by_p = ["device_id", "counting_head", "start_ns"]
    by_a = ["device_id", "counting_head", "time_ns", "direction"]
    pd.testing.assert_frame_equal(
        _sorted(got["passages"], by_p), _sorted(passages_table(job.analysis), by_p), check_dtype=False
    )
    pd.testing.assert_frame_equal(
        _sorted(got["axles"], by_a), _sorted(axles_table(job.analysis), by_a), check_dtype=False
    )
    wr = job.analysis.wheel_records
    assert len(got["wheel"]) == len(wr)
    # Per head, the wheel records in the batch's order (the section engine's input).
    names = {i: h for i, h in enumerate(job.analysis.heads)}
    for i, (dev, name) in names.items():
        mine = got["wheel"][(got["wheel"]["device_id"] == dev) & (got["wheel"]["counting_head"] == name)]
        theirs = wr[wr["head"] == i]
        assert mine["time_ns"].tolist() == theirs["time_ns"].tolist()
        assert mine["channel"].tolist() == theirs["channel"].tolist()
        assert mine["value"].tolist() == theirs["value"].tolist()


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    seed=st.integers(1, 1000),
    before_s=st.integers(30, 900),
    nights=st.integers(1, 2),
    run_days=st.integers(1, 3),
)
def test_partitions_equal_analyze_over_midnight(
    tmp_path_factory: pytest.TempPathFactory, seed: int, before_s: int, nights: int, run_days: int
) -> None:
    tmp = tmp_path_factory.mktemp("part")
    log = tmp / "sim.log"
    simulate_over_midnight(log, seed, before_s, minutes=25, days=nights)
    run_ingest([log], tmp / "arc", layout="example")
    m = read_current(tmp / "arc")
    s = speed_settings(m)
    keys = partitions(m)
    assert {k.day for k in keys} >= {dt.date(2026, 3, 3)}  # the log runs over midnight
    carried = carried_state(keys)
    # One partition at a time (the Dask unit)...
    one_by_one = combine([derive_partition(tmp / "arc", m, k, carried[k], s) for k in keys])
    _assert_equal_to_analyze(log, one_by_one, s)
    # ... and runs of `run_days` consecutive days (the local engine's batches): the same rows.
    runs = []
    for dev in sorted({k.device_id for k in keys}):
        days = sorted(k.day for k in keys if k.device_id == dev)
        for i in range(0, len(days), run_days):
            chunk = days[i : i + run_days]
            first, last = PartitionKey(dev, chunk[0]), PartitionKey(dev, chunk[-1])
            runs.append(
                derive_run(
                    tmp / "arc",
                    m,
                    dev,
                    chunk,
                    Carried(carried[first].day_before, carried[last].days_after),
                    s,
                )
            )
    in_runs = combine(runs)
    for name in ("passages", "axles", "wheel"):
        pd.testing.assert_frame_equal(in_runs[name], one_by_one[name], obj=name)


def test_passage_longer_than_a_day_is_one_passage(tmp_path: Path) -> None:
    """A head writing every 5 s for 40 hours: one passage from the first day to the third, derived by the first."""
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
    run_ingest([log], tmp_path / "arc")
    m = read_current(tmp_path / "arc")
    s = speed_settings(m)
    keys = partitions(m)
    assert [k.day.isoformat() for k in keys] == ["2026-03-02", "2026-03-03", "2026-03-04"]
    carried = carried_state(keys)
    rows = [derive_partition(tmp_path / "arc", m, k, carried[k], s) for k in keys]
    assert [len(r.passages) for r in rows] == [1, 0, 0]
    assert rows[0].last_end_day == {"4081/2026-03-02": "2026-03-04"}
    got = combine(rows)
    assert int(got["passages"]["end_ns"].iloc[0]) == int(times[-1])
    assert int(got["passages"]["records"].iloc[0]) == len(lines)
    assert (int(times[-1]) // NS_PER_DAY) - (start // NS_PER_DAY) == 2
    _assert_equal_to_analyze(log, got, s)
