"""The report's GNSS unit table: flat per-device columns give the same rows, in natural order."""

from __future__ import annotations

import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from console.inputs.recognise import natural_key
from console.sinks.report.gnss_units import _natural_order

_NAME = st.text(alphabet=st.sampled_from("aAbZ09-_ 7ÿ.ß"), max_size=8)


@settings(max_examples=300, deadline=None)
@given(st.lists(_NAME, max_size=40, unique=True))
def test_natural_order_is_natural_key_order(names: list[str]) -> None:
    index = pd.Index(sorted(names), dtype=object)
    want = sorted(range(len(index)), key=lambda i: natural_key(index[i]))
    assert _natural_order(index).tolist() == want


def test_units_as_rows_of_many_devices() -> None:
    from console.sinks.report.document import _gnss_units
    from console.sinks.report.model import ReportData

    t = pd.to_datetime(["2026-01-01T00:00:00Z", "2026-01-01T00:00:01Z", "2026-01-01T00:00:02Z", "NaT"], utc=True)
    fixes = pd.DataFrame(
        {
            "device": ["D10", "D9", "D10", "D2"],
            "time": t,
            "role": ["head", "", "eot", ""],
            "source": ["nmea", "csv", "csv", "csv"],
            "valid": [True, False, True, False],
        }
    )
    data = ReportData.__new__(ReportData)
    data.fixes = fixes
    rows = list(_gnss_units(data))
    assert [r["device"] for r in rows] == ["D2", "D9", "D10"]
    d10 = rows[2]
    assert d10["role"] == "eot/head" and d10["sources"] == ["csv", "nmea"] and d10["fixes"] == 2
    assert (
        d10["valid"] == 2
        and d10["first"].startswith("2026-01-01T00:00:00")
        and d10["last"].startswith("2026-01-01T00:00:02")
    )
    assert rows[0]["first"] is None and rows[0]["role"] is None and rows[1]["valid"] == 0
