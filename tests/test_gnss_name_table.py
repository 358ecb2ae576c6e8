"""The fix table's device names left flat until read (:class:`parsers.gnss.fix_table.NameTable`).

``trackside gnss`` on a file of a million devices held a million Python strings for the device
column beside the fixes; the names now become strings a block at a time as they are written.
These tests hold the lazy table to the list it stands for, and the JSON written from it to the
JSON written from a plain list, over random device sets, batch splits and block sizes.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import console.sinks.tables.gnss_tables as gnss_tables
from console.jsonout import dumps
from parsers.dictionary import StringDictionary
from parsers.gnss.fix_table import FixColumns, NameTable
from parsers.gnss_files import parse_gnss_columns
from parsers.report import ParseReport

_names = st.lists(st.text(min_size=1, max_size=6), min_size=0, max_size=60, unique=True)


@given(_names, st.data())
def test_name_table_reads_as_the_list_it_stands_for(names: list[str], data: st.DataObject) -> None:
    d = StringDictionary()
    d.codes(names)
    order = data.draw(st.permutations(range(len(names)))) if names else []
    expected = [names[i] for i in order]
    table = NameTable(d, np.array(order, np.int64))
    assert len(table) == len(expected)
    assert list(table) == expected
    assert table == expected and expected == table
    assert [table[i] for i in range(len(table))] == expected
    assert table[1:4] == expected[1:4]
    codes = np.array(data.draw(st.lists(st.integers(0, max(len(names) - 1, 0)), max_size=30)) if names else [])
    assert table.take(codes.astype(np.int64)) == [expected[c] for c in codes.tolist()]


def _plain(cols: FixColumns) -> FixColumns:
    """The same columns with the names as plain lists (as before the lazy table)."""
    fields: dict[str, Any] = {k: list(v) if k.endswith("_names") else v for k, v in vars(cols).items()}
    return FixColumns(**fields)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    devices=st.lists(st.integers(0, 300), min_size=1, max_size=400),
    block=st.sampled_from([1, 7, 64, 10_000]),
)
def test_gnss_json_from_the_lazy_names_equals_the_json_from_a_list(
    tmp_path: Path, devices: list[int], block: int
) -> None:
    lines = ["time,device,role,lat,lon,speed"]
    for i, dev in enumerate(devices):
        lines.append(f"2026-01-19T10:{(i // 60) % 60:02d}:{i % 60:02d}Z,Ü{dev},head,20.6,105.9,{i % 30}.5")
    path = tmp_path / "d.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    cols, report = parse_gnss_columns([path])
    assert isinstance(cols.device_names, NameTable)
    saved = gnss_tables.FIX_BLOCK
    gnss_tables.FIX_BLOCK = block
    try:
        lazy = dumps(gnss_tables.gnss_json_parts(cols, report))
        plain = dumps(gnss_tables.gnss_json_parts(_plain(cols), report))
    finally:
        gnss_tables.FIX_BLOCK = saved
    assert lazy == plain
    assert [f["device"] for f in json.loads(lazy)["fixes"]] == [f"Ü{d}" for d in devices]
    assert isinstance(report, ParseReport)


def test_many_devices_use_the_arrow_path_of_the_names(tmp_path: Path) -> None:
    """Past 4096 names in a block the dictionary hands the strings over through Arrow: same strings."""
    n = 9000
    lines = ["time,device,role,lat,lon,speed"]
    lines += [f"2026-01-19T10:00:{i % 60:02d}Z,D{i:05d},eot,20.6,105.9,1.5" for i in range(n)]
    path = tmp_path / "many.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    cols, report = parse_gnss_columns([path])
    names = cols.device_names
    assert isinstance(names, NameTable) and len(names) == n
    fixes = json.loads(dumps(gnss_tables.gnss_json_parts(cols, report)))["fixes"]
    # Time order is stable: the rows of one second keep their line order.
    expected = sorted(range(n), key=lambda i: i % 60)
    assert [f["device"] for f in fixes] == [f"D{i:05d}" for i in expected]
    assert cols.frame()["device"].cat.categories.tolist() == list(names)
