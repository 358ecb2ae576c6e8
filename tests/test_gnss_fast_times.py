"""The device CSV's fast path without pandas: its ISO 8601 times against pandas' parser, its Arrow reads,
the name dictionary frozen after the read, and a big read that does not load pandas."""

from __future__ import annotations

import random
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest

from parsers.dictionary import StringDictionary
from parsers.gnss.csv_fast import _mask, _np, _string_array, iso_times_ns


def _pandas_times(texts: list[str], ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the fast path did before: pandas' ISO 8601 parser, NaT left to the per-row reader."""
    import pandas as pd

    filled = pc.if_else(pa.array(ok), pa.array(texts), pa.scalar("1970-01-01T00:00:00Z")).to_pandas()
    times = pd.to_datetime(filled, format="ISO8601", utc=True, errors="coerce")
    good = ok & times.notna().to_numpy()
    ns = np.asarray(times.dt.tz_convert(None).dt.as_unit("ns").to_numpy(), dtype="datetime64[ns]").view(np.int64)
    return ns, good


def _random_time(rng: random.Random) -> str:
    # Fields in and out of range (month 0/13, day 0/30 February/32, hour 24, second 60, offsets of 24 h or
    # 60 min, lower-case z), every fraction length the fast pattern takes, both separators.
    year = rng.choice([1678, 1969, 1970, 2000, 2024, 2026, 2261])
    month, day = rng.randrange(0, 14), rng.randrange(0, 33)
    hour, minute, second = rng.randrange(0, 26), rng.choice([0, 30, 59, 60]), rng.choice([0, 1, 59, 60])
    digits = rng.randint(0, 6)
    fraction = "." + "".join(rng.choice("0123456789") for _ in range(digits)) if digits else ""
    zone = rng.choice(["", "Z", "z", "+00:00", "-00:00", "+05:30", "-23:59", "+24:00", "+05:60", "+14:00", "-12:00"])
    sep = rng.choice("T ")
    return f"{year:04d}-{month:02d}-{day:02d}{sep}{hour:02d}:{minute:02d}:{second:02d}{fraction}{zone}"


@pytest.mark.parametrize("seed", range(6))
def test_iso_times_match_pandas(seed: int) -> None:
    rng = random.Random(seed)
    texts = [_random_time(rng) for _ in range(4000)]
    ok = np.array([rng.random() < 0.95 for _ in texts])
    want_ns, want_ok = _pandas_times(texts, ok.copy())
    got_ns, got_ok = iso_times_ns(pa.array(texts), ok.copy())
    differ = [t for t, a, b in zip(texts, want_ok, got_ok, strict=True) if a != b]
    assert not differ, differ[:5]
    assert 0 < got_ok.sum() < len(texts)  # both kinds present
    assert (want_ns[want_ok] == got_ns[got_ok]).all()


def test_iso_times_known_values() -> None:
    texts = ["2026-03-02T10:00:00.5-23:59", "2026-02-29T10:00:00Z", "1970-01-01 00:00:01.000001"]
    ns, ok = iso_times_ns(pa.array(texts), np.ones(3, bool))
    assert ok.tolist() == [True, False, True]
    assert ns[0] == np.datetime64("2026-03-03T09:59:00.5", "ns").astype(np.int64)
    assert ns[2] == 1_000_001_000


def test_arrow_reads_off_buffers() -> None:
    rng = np.random.default_rng(3)
    mask = rng.random(1000) < 0.5
    sliced = _mask(mask)[7:900]  # an offset not on a byte
    assert (_np(sliced) == mask[7:900]).all()
    numbers = pa.array(rng.integers(-5, 5, 100).astype(np.int32))[3:]
    assert (_np(numbers) == numbers.to_numpy()).all()
    lines = [b"a,b", b"", b"ccc"]
    assert _string_array(lines).to_pylist() == ["a,b", "", "ccc"]


def test_frozen_dictionary_reads_and_refuses_new_strings() -> None:
    names = StringDictionary()
    codes = names.codes([f"D{i}" for i in range(5000)] + ["D1"])
    names.freeze()
    assert names.take(codes) == [f"D{i}" for i in range(5000)] + ["D1"]
    assert names.value(3) == "D3" and len(names) == 5000
    with pytest.raises(RuntimeError):
        names.code("D1")


def test_big_device_csv_read_without_pandas(tmp_path: Path) -> None:
    path = tmp_path / "devices.csv"
    rows = [f"2026-01-19T00:{i // 60 % 60:02d}:{i % 60:02d}.{i % 7}Z,D{i},head,20.6,105.9,0.5" for i in range(3000)]
    path.write_text("time,device,role,lat,lon,speed\n" + "\n".join(rows) + "\n")
    script = textwrap.dedent(
        f"""
        import sys
        from parsers.gnss_files import parse_gnss_columns
        fixes, report = parse_gnss_columns([{str(path)!r}])
        assert len(fixes) == 3000, len(fixes)
        print("pandas" in sys.modules)
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip() == "False"
