"""The reader's vectorized time parse (whole lines at once) agrees with the per-line rules of parse_time."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from parsers.diag.fields import FieldError, parse_time
from parsers.diag.read import read_diag
from tests.conftest import record

_DIGITS = "0123456789"
# Mostly digits, sometimes a byte that is next to one ("/" and ":" border 0-9), or junk.
_FRACTION_CHAR = st.sampled_from(_DIGITS * 6 + "/:a. x")


@st.composite
def _times(draw: st.DrawFn) -> str:
    hms = f"{draw(st.integers(0, 29)):02d}:{draw(st.integers(0, 65)):02d}:{draw(st.integers(0, 65)):02d}"
    n = draw(st.integers(0, 11))  # 1-9 digits are valid; 10 and 11 are not
    if not n:
        return hms
    sep = draw(st.sampled_from("...,:"))
    return hms + sep + "".join(draw(st.lists(_FRACTION_CHAR, min_size=n, max_size=n)))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(times=st.lists(_times(), min_size=1, max_size=60))
def test_fast_time_parse_is_parse_time(tmp_path: Path, times: list[str]) -> None:
    p = tmp_path / "log.txt"
    p.write_text("".join(record(time=t) + "\n" for t in times), encoding="utf-8")
    df, report = read_diag([p])
    expected: list[tuple[int, int, bool]] = []
    for line, t in enumerate(times, start=1):
        try:
            tod_ns, subsecond = parse_time(f"Time:{t}".encode())
        except FieldError:
            continue
        expected.append((line, tod_ns, subsecond))
    day = pd.Timestamp("2015-10-31")
    got = [
        (int(line), int((time - day).value), bool(sub))
        for line, time, sub in zip(df["line"], df["time"], df["subsecond"], strict=True)
    ]
    assert got == expected
    assert report.rejected == len(times) - len(expected)
