"""The numpy passages encoder writes exactly what pandas' to_json writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from console.analysis import passages_json as pj
from console.analysis.diagnostics import SpeedSettings, iso_strings, passages_json_text
from tests.reads import whole_job

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"


def _tokens(matrix: np.ndarray) -> list[str]:
    sep = np.full((len(matrix), 1), ord(","), np.uint8)
    flat = np.concatenate([matrix, sep], axis=1).ravel()
    return flat[flat != 0].tobytes().decode("ascii")[:-1].split(",")


@pytest.mark.parametrize("decimals", [None, 3, 6])
def test_floats_match_pandas(decimals: int | None) -> None:
    rng = np.random.default_rng(decimals or 0)
    v = 10.0 ** rng.uniform(-14, 15.9, 50_000) * rng.choice([-1.0, 1.0], 50_000)
    if decimals is not None:
        v = np.round(v, decimals)
    v[::97] = np.nan
    v[::89] = 0.0
    v[::83] = -0.0
    v[:6] = [0.5, 0.05, 0.95, 0.99999999995, 1e16 - 2, 17.0]
    tokens = pj._floats(v)
    assert tokens is not None
    assert _tokens(tokens) == pd.Series(v).to_json(orient="values", double_precision=10)[1:-1].split(",")


def test_exponent_floats_are_left_to_pandas() -> None:
    assert pj._floats(np.array([1.0, 1e17])) is None
    assert pj._floats(np.array([1e-16])) is None
    assert pj._floats(np.array([np.inf])) is None


def test_ints_and_times_match() -> None:
    rng = np.random.default_rng(1)
    ints = rng.integers(-(2**62), 2**62, 10_000)
    ints[:3] = [0, -1, 9]
    tokens = pj._ints(ints)
    assert tokens is not None
    assert _tokens(tokens) == pd.Series(ints).to_json(orient="values")[1:-1].split(",")
    ns = rng.integers(-(2 * 10**18), 9 * 10**18, 10_000).astype(float)
    ns[::7] = np.round(ns[::7] / 1e9) * 1e9
    ns[::11] = np.nan
    iso = pj._iso(ns)
    assert iso is not None
    assert _tokens(iso) == ["null" if s is None else f'"{s}"' for s in iso_strings(ns)]


def test_text_needing_escapes_is_left_to_pandas() -> None:
    assert pj._texts(np.array([0]), ['W"S']) is None
    assert pj._texts(np.array([0]), ["WS/1"]) is None
    assert pj._texts(np.array([0]), ["WS\u00e4"]) is None


@pytest.mark.parametrize("log", sorted(p.name for p in SAMPLES.glob("*.log")))
def test_passages_same_as_pandas(log: str) -> None:
    analysis = whole_job([SAMPLES / log], SpeedSettings()).analysis
    expected = passages_json_text(analysis.passages)
    if analysis.passage_columns is None:
        assert expected == "[]"
        return
    assert pj.encode_passages(analysis.passage_columns, analysis.heads) == expected


def test_small_batches_same_as_one(monkeypatch: pytest.MonkeyPatch) -> None:
    analysis = whole_job([SAMPLES / "example_station.log"], SpeedSettings()).analysis
    assert analysis.passage_columns is not None
    whole = pj.encode_passages(analysis.passage_columns, analysis.heads)
    monkeypatch.setattr(pj, "_BATCH_ROWS", 7)
    monkeypatch.setattr(pj, "_BATCH_CELLS", 20)
    assert pj.encode_passages(analysis.passage_columns, analysis.heads) == whole
