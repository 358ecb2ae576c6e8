"""The numpy passages encoder writes exactly what pandas' to_json writes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from console.analysis.passages import json_text as pj
from console.analysis.passages.frame_json import iso_strings, passages_json_text
from console.analysis.passages.speed_settings import SpeedSettings
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


@pytest.mark.parametrize("keep_leading", [False, True])
def test_digits_are_the_decimal_text(keep_leading: bool) -> None:
    """Digits four at a time (looked up) right-aligned in any width: what str() writes, zero-padded or not."""
    rng = np.random.default_rng(7)
    for width in range(1, 21):
        top = 10**width if width < 20 else 2**64
        u = rng.integers(0, top, 2_000, dtype=np.uint64)
        u[:4] = [0, 1, 10 ** (width - 1), top - 1]
        u[4:200] = rng.integers(0, min(100, top), 196, dtype=np.uint64)
        rows = pj._digits(u, width, keep_leading=keep_leading)
        assert rows.shape == (len(u), width)
        texts = [r[r != 0].tobytes().decode("ascii") for r in rows]
        assert texts == [str(int(x)).zfill(width) if keep_leading else str(int(x)) for x in u]
        # Right-aligned: the 0 bytes (unwritten leading zeros) all come first.
        assert all(
            r[width - len(t) :].all() and not r[: width - len(t)].any() for r, t in zip(rows, texts, strict=True)
        )
    assert pj._digits(np.array([5, 12345678901], np.uint64)).shape == (2, 11)  # width: the largest's


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


def test_objects_are_the_array_items(monkeypatch: pytest.MonkeyPatch) -> None:
    analysis = whole_job([SAMPLES / "example_station.log"], SpeedSettings()).analysis
    cols = analysis.passage_columns
    assert cols is not None
    array = pj.encode_passages(cols, analysis.heads)
    for rows, cells in ((8192, 1 << 18), (7, 20)):  # one batch, and many small ones
        monkeypatch.setattr(pj, "_BATCH_ROWS", rows)
        monkeypatch.setattr(pj, "_BATCH_CELLS", cells)
        encoded = pj.encode_objects(cols, analysis.heads)
        assert encoded is not None
        text, lengths = encoded
        assert len(lengths) == len(cols["head"]) and int(lengths.sum()) == len(text)
        ends = np.cumsum(lengths)
        objects = [text[e - n : e].decode("ascii") for e, n in zip(ends.tolist(), lengths.tolist(), strict=True)]
        assert "[" + ",".join(objects) + "]" == array
        # Each followed by a separator (the spool's commas): the same objects, one byte longer each.
        with_commas = pj.encode_objects(cols, analysis.heads, after=",")
        assert with_commas is not None
        assert with_commas[0] == b"".join(o.encode("ascii") + b"," for o in objects)
        np.testing.assert_array_equal(with_commas[1], lengths + 1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_spool_encodes_held_batches_as_each_passage_alone(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Batches handed in any sizes are held and encoded a few at a time; one head's name needs escaping, so
    the batches holding it take pandas' encoder: the document is the same as each passage encoded alone."""
    from console.analysis.passages.stream import by_head_and_start, take_passages
    from console.sinks.tables import passage_spool as ps

    analysis = whole_job([SAMPLES / "example_station.log"], SpeedSettings()).analysis
    cols = analysis.passage_columns
    assert cols is not None
    heads = list(analysis.heads)
    heads[0] = (heads[0][0], 'W"S/1')  # needs escapes: not covered by the byte encoder
    rng = np.random.default_rng(seed)
    monkeypatch.setattr(ps, "_ENCODE_ROWS", int(rng.integers(1, 200)))
    n = len(cols["head"])
    # The stream's order is any (the document's is sorted); the escaped head's passages come last, so the
    # batches held before them are encoded by the byte encoder.
    first = cols["head"] == 0
    rows = np.concatenate([rng.permutation(np.flatnonzero(~first)), rng.permutation(np.flatnonzero(first))])
    cuts = np.sort(rng.choice(np.arange(1, n), size=60, replace=False))
    spool = ps.PassageSpool(columns=[("axles", "<i8")])
    for part in np.split(rows, cuts):
        spool.passages(take_passages(cols, part), heads)
    assert spool.count == n
    objects = ps.passage_texts(take_passages(cols, by_head_and_start(cols)), heads)
    assert list(spool.texts()) == objects  # each alone, its comma in the spool left out
    expected = "[" + ",".join(objects) + "]"
    got = "".join(spool.json_parts().texts())
    same = got == expected  # not compared by pytest's diff: two long texts
    at = next((i for i, (a, b) in enumerate(zip(got, expected, strict=False)) if a != b), min(len(got), len(expected)))
    assert same, f"first difference at {at}"
    assert sorted(spool.columns(["axles"])["axles"].tolist()) == sorted(cols["axles"].tolist())
    spool.close()


@pytest.mark.parametrize("decimals", [None, 3, 6])
def test_python_floats_are_what_json_reads_back(decimals: int | None) -> None:
    """The report writes a passage's floats as Python writes what it read of pandas' text: ``1e-06``, not
    ``0.000001``; the text as pandas wrote it where that is Python's shortest form."""
    import json

    rng = np.random.default_rng(10 + (decimals or 0))
    v = 10.0 ** rng.uniform(-10, 15.9, 50_000) * rng.choice([-1.0, 1.0], 50_000)
    if decimals is not None:
        v = np.round(v, decimals)
    v[::97] = np.nan
    v[::89] = 0.0
    v[::83] = -0.0
    v[:9] = [1e-06, 0.0001, 0.00009999999999, 1e-05, 0.001, 1.0, 0.5, 12345678.901, 1e15 + 0.5]
    tokens = pj._python_floats(v)
    assert tokens is not None
    pandas_text = pd.Series(v).to_json(orient="values", double_precision=10)
    assert _tokens(tokens) == [json.dumps(x) for x in json.loads(pandas_text)]


@pytest.mark.parametrize("log", sorted(p.name for p in SAMPLES.glob("*.log")))
@pytest.mark.parametrize("depth", [1, 3])
def test_indented_objects_are_the_report_json(log: str, depth: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """The passages laid out as ``json.dumps(indent=1)`` lays out what ``json.loads`` reads of the pandas
    text, ``depth`` levels deep: from the table the archive reads, in one batch and in many."""
    import json

    from console.analysis.passages.passage_frame import frame_columns
    from console.sinks.report.jsonwrite import indented

    p = whole_job([SAMPLES / log], SpeedSettings()).analysis.passages
    if p.empty:
        return
    expected = indented(json.loads(passages_json_text(p)), depth)
    found = frame_columns(p)
    assert found is not None
    for rows, cells in ((8192, 1 << 18), (7, 20)):
        monkeypatch.setattr(pj, "_BATCH_ROWS", rows)
        monkeypatch.setattr(pj, "_BATCH_CELLS", cells)
        blobs = pj.indented_objects(*found, depth)
        assert blobs is not None
        got = "[" + b"".join(blobs).decode("ascii") + "\n" + " " * depth + "]"
        assert got == expected


def test_frame_columns_refuse_what_has_no_code() -> None:
    from console.analysis.passages.passage_frame import frame_columns

    p = whole_job([SAMPLES / "example_station.log"], SpeedSettings()).analysis.passages
    assert frame_columns(p) is not None
    odd = p.copy()
    odd.loc[odd.index[0], "kind"] = "tram"
    assert frame_columns(odd) is None
    odd = p.copy()
    odd["direction"] = odd["direction"].astype(object)
    odd.loc[odd.index[0], "direction"] = "sideways"
    assert frame_columns(odd) is None


def test_a_document_with_the_spool_s_bytes_is_the_same_text_whatever_the_output() -> None:
    """The spool hands its runs of passages as bytes: written to a text stream with a byte layer (stdout), text
    and bytes come out in the document's order, as written to one without (the text buffered before a run of
    bytes goes first), and the JSON reads back to the passages each encoded alone."""
    import io
    import json

    from console.jsonout import write
    from console.sinks.tables.passage_spool import PassageSpool, passage_texts

    analysis = whole_job([SAMPLES / "example_station.log"], SpeedSettings()).analysis
    cols = analysis.passage_columns
    assert cols is not None
    heads = list(analysis.heads)
    texts = []
    for out in (io.TextIOWrapper(io.BytesIO(), encoding="ascii", write_through=False), io.StringIO()):
        spool = PassageSpool()
        spool.passages(cols, heads)
        write({"schema": "x", "passages": spool.json_parts(), "after": [1, 2]}, out)
        out.flush()
        texts.append(out.buffer.getvalue().decode("ascii") if isinstance(out, io.TextIOWrapper) else out.getvalue())
    same = texts[0] == texts[1]  # not compared by pytest's diff: two long texts
    assert same, "the outputs differ"
    doc = json.loads(texts[0])
    assert list(doc) == ["schema", "passages", "after"] and doc["after"] == [1, 2]
    assert [json.dumps(p, separators=(",", ":")) for p in doc["passages"]] == [
        json.dumps(json.loads(t), separators=(",", ":")) for t in passage_texts(cols, heads)
    ]
