"""The GNSS fix table and device table with the device names held flat (issue "Memory from many devices").

Device names are interned in a flat dictionary while rows are collected, the
fix table is built in time order column by column (no second table to sort),
and the device table's figures are grouped over the rows of the devices shown
only.  These tests hold each to what the table-wide pandas operations give.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.safe_text import inert
from console.sinks.tables.gnss_tables import DEVICES_SHOWN, _Clock, _num, _table, devices_table
from parsers.gnss_files import parse_gnss

_MPS_TO_KMH = 3.6
_row = st.tuples(
    st.integers(0, 40),  # device
    st.one_of(st.integers(0, 3599), st.none()),  # second of the hour; None: no time (a rejected row)
    st.sampled_from(["head", "eot", ""]),
    st.one_of(st.floats(0, 50, allow_nan=False).map(lambda v: f"{v:.2f}"), st.just("")),
    st.booleans(),  # with a position (a valid fix) or without
)


def _csv(tmp_path: Path, rows: list[tuple[int, int | None, str, str, bool]]) -> Path:
    lines = ["time,device,role,lat,lon,speed"]
    for dev, sec, role, speed, pos in rows:
        time = "" if sec is None else f"2026-01-19T10:{sec // 60:02d}:{sec % 60:02d}Z"
        lat, lon = ("20.6", "105.9") if pos else ("", "")
        lines.append(f"{time},U{dev},{role},{lat},{lon},{speed}")
    path = tmp_path / "devices.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _whole_table_devices(fixes: pd.DataFrame, limit: int) -> Any:
    """The device table as it was computed before: every figure grouped over the whole table."""
    clock = _Clock(fixes["time"])
    t = _table("GNSS devices" + (f" ({clock.note})" if clock.note else ""))
    if fixes.empty:
        return t
    by = fixes.groupby("device", observed=True, sort=True)
    count = by.size()
    shown = count.index[:limit]
    valid = fixes["valid"].astype(bool)
    n_valid = valid.groupby(fixes["device"], observed=True, sort=True).sum()
    first, last = by["time"].min(), by["time"].max()
    speed = fixes["speed_mps"].where(valid).groupby(fixes["device"], observed=True, sort=True).mean()
    rows = []
    for device in shown:
        roles = sorted(set(fixes["role"][fixes["device"] == device].astype(str)) - {""})
        rows.append(
            [
                str(inert(device)),
                "/".join(roles) or "–",
                f"{int(count[device]):,}",
                f"{int(n_valid[device]):,}",
                str(clock.text(first[device], seconds=True)),
                str(clock.text(last[device], seconds=True)),
                str(_num(speed[device], "{:.1f}", _MPS_TO_KMH)),
            ]
        )
    return rows, len(count)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(_row, min_size=1, max_size=80), limit=st.sampled_from([1, 3, DEVICES_SHOWN]))
def test_device_table_over_the_shown_devices_equals_grouping_the_whole_table(
    tmp_path: Path, rows: list[tuple[int, int | None, str, str, bool]], limit: int
) -> None:
    fixes = parse_gnss([_csv(tmp_path, rows)])[0]
    table = devices_table(fixes, limit=limit)
    if fixes.empty:
        assert table.row_count == 0
        return
    want, n_devices = _whole_table_devices(fixes, limit)
    got = [[str(c) for c in col.cells] for col in table.columns]
    assert [list(r) for r in zip(*got, strict=True)] == want
    assert (f"first {limit:,} of {n_devices:,} devices" in str(table.caption)) == (n_devices > limit)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rows=st.lists(_row, max_size=80))
def test_fix_table_in_time_order_is_the_stable_sort_of_the_rows_read(
    tmp_path: Path, rows: list[tuple[int, int | None, str, str, bool]]
) -> None:
    from parsers.gnss_files import parse_device_stream

    path = _csv(tmp_path, rows)
    fixes = parse_gnss([path])[0]
    in_file_order = parse_device_stream([path])[0]
    want = in_file_order.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
    pd.testing.assert_frame_equal(fixes, want)
    # Devices: categories in order of first appearance in the file, not in time.
    first_seen = list(dict.fromkeys(in_file_order["device"].astype(str)))
    assert fixes["device"].cat.categories.tolist() == first_seen
    assert isinstance(fixes.index, pd.RangeIndex)
