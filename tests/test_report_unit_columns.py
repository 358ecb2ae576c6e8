"""The report's GNSS unit table from the fix columns (no pandas frame, names left flat) equals the one
from the fix table: the names sorted from their UTF-8 bytes in Python's string order (non-ASCII, astral
and lone-surrogate names, names equal under the natural key), and every row the same."""

from __future__ import annotations

import random
from pathlib import Path

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from console.sinks.report.document import _gnss_units
from console.sinks.report.gnss_units import gnss_units_of_columns
from console.sinks.report.model import ReportData
from console.sinks.report.unit_codes import sorted_name_codes
from parsers.dictionary import StringDictionary
from parsers.gnss.fix_table import NameTable
from parsers.gnss_files import parse_gnss, parse_gnss_columns

_NAME = st.text(
    alphabet=st.sampled_from(["a", "B", "0", "1", "9", "ä", "ß", "\U0001f600", "\udcff", "\ue000", "-"]), max_size=6
)


@settings(max_examples=300, deadline=None)
@given(st.lists(_NAME, min_size=1, max_size=30, unique=True), st.data())
def test_sorted_name_codes_as_factorize(names: list[str], data: st.DataObject) -> None:
    table = StringDictionary()
    table.codes(["unused-before", *names])
    # The table's codes → dictionary codes, shuffled; some names get no row.
    at = np.array(data.draw(st.permutations(range(1, len(names) + 1))), np.int64)
    names_here = NameTable(table, at)
    codes = np.array(data.draw(st.lists(st.integers(0, len(names) - 1), min_size=1, max_size=60)), np.int32)
    code, sorted_names = sorted_name_codes(codes, names_here)
    strings = [names_here[int(c)] for c in codes]
    ref_code, ref_names = pd.factorize(pd.Series(strings, dtype=object), sort=True)
    assert isinstance(sorted_names, NameTable)
    assert list(sorted_names) == [str(n) for n in ref_names]
    assert code.tolist() == np.asarray(ref_code).tolist()
    plain_code, plain_names = sorted_name_codes(codes, list(names_here))  # a plain list: the string sort
    assert plain_code.tolist() == code.tolist() and list(plain_names) == list(sorted_names)


def _csv(path: Path, seed: int) -> Path:
    rng = random.Random(seed)
    names = ["D1", "D01", "d1", "D10", "D9", "Zug-ä", "Zug-a", "\U0001f600-head", "T 2", "T2", "x", "X0"]
    lines = ["time,device,role,lat,lon,speed"]
    for k in range(400):
        device = rng.choice(names) if k % 3 else f"U{rng.randrange(60)}"
        time = "" if rng.random() < 0.05 else f"2026-01-19T00:{k // 60 % 60:02d}:{k % 60:02d}Z"
        role = rng.choice(["head", "eot", ""])
        speed = "" if rng.random() < 0.2 else f"{rng.uniform(0, 30):.1f}"
        lines.append(f"{time},{device},{role},{20.6 + k * 1e-5:.7f},{105.9 + k * 1e-5:.7f},{speed}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _rows(fixes: pd.DataFrame | None, units: object) -> list[dict[str, object]]:
    data = ReportData.__new__(ReportData)
    data.fixes, data.gnss_units = fixes, units  # type: ignore[assignment]
    return list(_gnss_units(data))


def test_units_from_columns_as_from_the_table(tmp_path: Path) -> None:
    paths = [_csv(tmp_path / "a.csv", 1), _csv(tmp_path / "b.csv", 2)]
    table = parse_gnss(paths)[0]
    c = parse_gnss_columns(paths)[0]
    assert isinstance(c.device_names, NameTable)
    units = gnss_units_of_columns(c.device_codes, c.device_names, c.valid, c.time_ns, c.role, c.source)
    want = _rows(table, None)
    assert len(want) > 60 and {"D1", "D01", "\U0001f600-head"} <= {r["device"] for r in want}
    assert _rows(None, units) == want


def test_units_of_no_fixes() -> None:
    empty = np.zeros(0, np.int32)
    none = np.zeros(0, np.int8)
    units = gnss_units_of_columns(empty, [], none.astype(bool), np.zeros(0, np.int64), none, none)
    assert _rows(None, units) == []
