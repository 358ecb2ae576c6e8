"""Arrow columns built from buffers equal pa.array's, and an ingest's read leaves pandas unimported."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from console.archive import arrow_np
from tests.conftest import SAMPLES

DTYPES = [
    "int8",
    "int16",
    "int32",
    "int64",
    "uint8",
    "uint32",
    "uint64",
    "float32",
    "float64",
    "bool",
    "datetime64[ns]",
]


def _values(arr: pa.Array) -> list[object]:
    return ["NaN" if isinstance(v, float) and v != v else v for v in arr.to_pylist()]


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("seed", range(4))
def test_arrays_equal_pa_array(dtype: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 50))
    a = (rng.integers(0, 100, n) * (1 if dtype != "bool" else 0) + rng.integers(0, 2, n)).astype(dtype)
    if dtype.startswith("float"):
        a[rng.random(n) < 0.3] = np.nan
    a = a[:: int(rng.integers(1, 3))]  # a strided view too
    mask = rng.random(len(a)) < 0.2
    for nan_is_null in (False, True):
        want = pa.array(a, from_pandas=nan_is_null)
        got = arrow_np.array(a, nan_is_null=nan_is_null)
        assert got.type == want.type and _values(got) == _values(want) and got.null_count == want.null_count
    want = pa.array(a, mask=mask)
    got = arrow_np.array(a, mask=mask)
    assert _values(got) == _values(want) and got.null_count == want.null_count
    if a.dtype.kind in "iu" and a.dtype != np.uint64:
        assert arrow_np.array(a, pa.int32()).equals(pa.array(a, pa.int32()))
        assert arrow_np.array(a.astype(np.int32), pa.date32()).equals(pa.array(a.astype(np.int32), pa.date32()))
    if dtype != "bool" and not dtype.startswith("float"):
        assert np.array_equal(arrow_np.to_numpy(pa.array(a)), pa.array(a).to_numpy())
        chunked = pa.chunked_array([pa.array(a), pa.array(a).slice(1)], pa.array(a).type)
        assert np.array_equal(arrow_np.to_numpy(chunked), chunked.to_numpy())


def test_an_integer_out_of_range_fails_as_pa_array_does() -> None:
    with pytest.raises(pa.ArrowInvalid):
        arrow_np.array(np.array([1, 1 << 40]), pa.int32())


@pytest.mark.parametrize("type", [None, pa.string(), pa.large_string()])
def test_strings_equal_pa_array(type: pa.DataType | None) -> None:
    values = [None, "sys1_to_sys2", "", "Zählkopf ä", None, "x" * 300]
    assert arrow_np.strings(values, type).equals(pa.array(values, type or pa.string()))
    assert arrow_np.strings([], type).equals(pa.array([], type or pa.string()))


@pytest.mark.parametrize("type", [None, pa.binary(), pa.large_binary()])
def test_binaries_equal_pa_array(type: pa.DataType | None) -> None:
    values = [None, b"\x00\xff pickled", b"", "Zählkopf".encode(), None, b"x" * 300]
    got = arrow_np.binaries(values, type)
    got.validate(full=True)
    assert got.equals(pa.array(values, type or pa.binary()))
    assert arrow_np.binaries([], type).equals(pa.array([], type or pa.binary()))


def test_an_ingests_read_does_not_import_pandas(tmp_path: Path) -> None:
    # pandas (+46 MB) would sit under the read's peak: only the derivation's end imports it (or the health
    # events' table, where a log has any: this one has none).
    code = textwrap.dedent(
        f"""
        import sys
        from pathlib import Path
        import console.archive.ingest as ingest
        import console.archive.ingest_summary as ingest_summary
        lap = ingest_summary.PhaseClock.lap
        seen = {{}}
        def watch(self, name):
            lap(self, name)
            seen.setdefault(name, "pandas" in sys.modules)
        ingest_summary.PhaseClock.lap = watch
        summary = ingest.run_ingest([Path({str(SAMPLES / "ws4_subsecond.log")!r})], Path({str(tmp_path / "arc")!r}))
        assert summary.records > 0, summary.records
        print(seen["read"])
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.split() == ["False"], out.stderr


@pytest.mark.parametrize("value_type", [pa.float64(), pa.int32()])
def test_list_values_are_flatten_s_for_slices_nulls_and_chunks(value_type: pa.DataType) -> None:
    rng = np.random.default_rng(5)
    lists: list[list[float | None] | None] = []
    for _ in range(300):
        k = int(rng.integers(0, 5))
        lists.append([float(x) if value_type == pa.float64() else int(x) for x in rng.integers(0, 99, k)])
    whole = pa.array(lists, pa.list_(value_type))
    with_nulls = pa.array([None if i % 7 == 0 else v for i, v in enumerate(lists)], pa.list_(value_type))
    cases = [
        whole,
        whole.slice(13, 200),  # ``values`` would still hold the lists outside the slice
        with_nulls,
        with_nulls.slice(5, 50),
        pa.chunked_array([whole.slice(0, 100), whole.slice(100, 0), whole.slice(150, 150)]),
        pa.chunked_array([], pa.list_(value_type)),
    ]
    for arr in cases:
        want = (arr.combine_chunks() if isinstance(arr, pa.ChunkedArray) else arr).flatten().to_numpy()
        got = arrow_np.list_values(arr)
        assert got.dtype == want.dtype and np.array_equal(got, want)
