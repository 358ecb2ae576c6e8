"""The compiled encoder of passages (console/analysis/passages/compiled_json.c) and the numpy one
(json_text.py, the reference) give the same bytes and lengths, or both None.

Inputs: random passage columns (NaN, zero, negatives, floats huge and tiny and at ties of the tenth decimal,
ints near the limits, empty and long per-axle lists, every text code, head names needing escapes), a
realistic log's passages, and whole commands with TRACKSIDE_PURE=1 and without.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages import json_text as pj
from console.analysis.passages.speed_settings import SpeedSettings
from tests.conftest import SAMPLES
from tests.reads import whole_job

pytestmark = [
    pytest.mark.skipif(
        pj.compiled_json is None,
        reason="console.analysis.passages.compiled_json is not built (no C compiler at install): only the numpy path",
    ),
    # Floats near the float64 limit are drawn on purpose: rounding them to 3 decimals overflows (to inf, which
    # neither encoder covers), as it would in the command.
    pytest.mark.filterwarnings("ignore:overflow encountered in multiply:RuntimeWarning"),
]

_I64 = np.iinfo(np.int64)
_floats = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-1e6, 1e6),
    st.sampled_from(
        [
            0.0,
            -0.0,
            0.5,
            -2.5,
            1e-15,
            5e-11,
            -5e-11,
            2.5e-10,
            7.00000000005,
            1e16 - 1,
            1e16,
            123.00000000005,
            0.00000000015,
            9.99999999995,
        ]
    ),
    st.integers(-(10**12), 10**12).map(lambda k: k / 2e10),  # ties at the tenth decimal and around them
)
_ints = st.one_of(st.integers(-1000, 1000), st.integers(_I64.min, _I64.max), st.sampled_from([_I64.min, _I64.max]))
_ns = st.one_of(st.integers(-(2**62), 2**62), st.integers(1_700_000_000 * 10**9, 1_800_000_000 * 10**9))


@st.composite
def passages(draw: st.DrawFn) -> tuple[dict[str, np.ndarray], dict[int, tuple[int, str]]]:
    n = draw(st.integers(1, 12))

    def col(strategy: st.SearchStrategy[object], dtype: object) -> np.ndarray:
        return np.array(draw(st.lists(strategy, min_size=n, max_size=n)), dtype)

    def times() -> np.ndarray:
        if draw(st.booleans()):
            return col(_ns, np.int64)
        return col(st.one_of(st.just(float("nan")), _ns.map(float)), np.float64)

    names = draw(st.lists(st.sampled_from(["WS1", "A b", 'q"', "s/1", "\u00e4", ""]), min_size=1, max_size=4))
    heads = {k: (draw(_ints), name) for k, name in enumerate(names)}
    counts = draw(st.lists(st.integers(0, 30), min_size=n, max_size=n))
    stop = np.cumsum(counts) + draw(st.integers(0, 3))
    start = stop - np.array(counts)
    speeds = np.array(draw(st.lists(_floats, min_size=int(stop.max()), max_size=int(stop.max()))), np.float64)
    cols = {
        "head": col(st.integers(0, len(names) - 1), np.int64),
        "start_ns": times(),
        "end_ns": times(),
        "duration_s": col(_floats, np.float64),
        "records": col(_ints, np.int64),
        "axles": col(_ints, np.int64),
        "detections_sys1": col(st.integers(0, 3) | _ints, np.int64),
        "detections_sys2": col(st.integers(0, 3) | _ints, np.int64),
        "direction": col(st.integers(0, 3), np.int8),
        "detection_second_ns": times(),
        "records_in_detection_second": col(st.just(float("nan")) | st.integers(0, 2**40).map(float), np.float64),
        "speed_kmh_per_second_method": col(_floats, np.float64),
        "speed_kmh_whole_train": col(_floats, np.float64),
        "speed_kmh_whole_train_min": col(_floats, np.float64),
        "speed_kmh_whole_train_max": col(_floats, np.float64),
        "whole_train_basis": col(st.integers(0, 2), np.int8),
        "whole_train_duration_s": col(_floats, np.float64),
        "axle_speeds_kmh": speeds,
        "axle_speeds_start": start,
        "axle_speeds_stop": stop,
        "speed_kmh_per_axle_mean": col(_floats, np.float64),
        "subsecond": col(st.booleans(), bool),
        "time_resolution_s": col(_floats, np.float64),
        "kind": col(st.integers(0, 2), np.int8),
    }
    return cols, heads


def _alike(cols: dict[str, np.ndarray], heads: dict[int, tuple[int, str]]) -> None:
    got = pj._encode_objects_compiled(cols, heads)
    want = pj._encode_objects_numpy(cols, heads)
    if want is None:
        assert got is None
        return
    assert got is not None
    assert got[0] == want[0]
    assert got[1].dtype == want[1].dtype and got[1].tolist() == want[1].tolist()


@settings(max_examples=400, deadline=None)
@given(passages())
def test_random_passages_encode_alike(case: tuple[dict[str, np.ndarray], dict[int, tuple[int, str]]]) -> None:
    _alike(*case)


@settings(max_examples=200, deadline=None)
@given(passages())
def test_covered_random_passages_encode_alike(
    case: tuple[dict[str, np.ndarray], dict[int, tuple[int, str]]],
) -> None:
    """The same with values the numpy path covers (finite, not in exponent form, names needing no escape), so
    that the bytes are compared and not only the Nones."""
    cols, heads = case
    for k, v in cols.items():
        if v.dtype == np.float64 and not k.endswith("_ns") and k != "records_in_detection_second":
            a = np.abs(np.nan_to_num(v, posinf=1.0, neginf=1.0))
            cols[k] = np.where((a > 1e15) | ((a != 0) & (a < 1e-12)), 1.5, np.nan_to_num(v, posinf=1.0, neginf=-1))
    for k in ("records", "axles", "detections_sys1", "detections_sys2"):
        cols[k] = np.maximum(cols[k], _I64.min + 1)
    heads = {
        k: (max(d, _I64.min + 1), "WS1" if set(name) - set(" WSAb1") or not name else name)
        for k, (d, name) in heads.items()
    }
    assert pj._encode_objects_numpy(cols, heads) is not None
    _alike(cols, heads)


def test_realistic_passages_encode_alike(tmp_path: Path) -> None:
    log = tmp_path / "r.log"
    generate(60_000, log, seed=3)
    for path in (log, SAMPLES / "example_station.log"):
        analysis = whole_job([path], SpeedSettings()).analysis
        assert analysis.passage_columns is not None
        got = pj._encode_objects_compiled(analysis.passage_columns, analysis.heads)
        assert got is not None
        _alike(analysis.passage_columns, analysis.heads)


@pytest.mark.parametrize("command", [["analyze", "--json"], ["speeds", "--json"]])
def test_commands_alike_pure_and_compiled(command: list[str], tmp_path: Path) -> None:
    log = tmp_path / "r.log"
    generate(40_000, log, seed=5)
    outs = []
    for pure in ("1", ""):
        env = {**os.environ, "TRACKSIDE_PURE": pure}
        if not pure:
            env.pop("TRACKSIDE_PURE")
        run = subprocess.run(
            [str(Path(sys.executable).with_name("trackside")), *command, str(log)],
            env=env,
            capture_output=True,
            check=True,
        )
        outs.append(run.stdout)
    assert outs[0] == outs[1] and len(outs[0]) > 1000
