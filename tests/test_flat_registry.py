"""The flat registry's lookups give what a dict would (issue "Memory from many devices").

Register spans and strings are looked up by 128-bit digest in sorted runs
(:mod:`parsers.dictionary`) instead of a ``dict`` keyed by the bytes.  These
properties compare every lookup, over random spans repeated and new across
many calls (chunks), with a plain ``dict`` numbering in order of first sight,
which is what the registry did before.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from parsers import dictionary
from parsers.diag.fields import FieldError, parse_register_span
from parsers.diag.registry import DiagRegistry
from parsers.dictionary import DigestIndex, StringDictionary

# Few distinct names, so that calls repeat each other's spans as a log's chunks do.
_names = st.sampled_from(["WS1", "WS2", "WS10", "Zähler", "H0000007", "x", " WS1 ", "Ω"])
_span = st.builds(
    lambda dev, head, ch, adr, label: (
        f"Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:{adr:03d}\t"
        f"Label:{label}"
    ).encode(),
    st.integers(4000, 4005),
    _names,
    st.integers(0, 17),  # 16, 17: invalid channels
    st.integers(0, 3),
    st.sampled_from(["Radsensor", "Summenzä", "Temperatur", ""]),
)
# Now and then a span that is not a register at all.
_any_span = st.one_of(_span, _span, _span, st.binary(max_size=40))


@settings(max_examples=150, deadline=None)
@given(
    chunks=st.lists(st.lists(_any_span, max_size=30, unique=True), max_size=8),
    front_max=st.sampled_from([1, 4, 10**6]),
)
def test_register_ids_across_chunks_equal_a_dict_in_first_seen_order(chunks: list[list[bytes]], front_max: int) -> None:
    # A tiny front cache makes every lookup go through the digest index (the many-heads case).
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dictionary, "FRONT_CACHE_MAX", front_max)
        mp.setattr("parsers.dictionary.FRONT_CACHE_MAX", front_max)
        # Read again without the invalid spans: every chunk then names only registers met before (a long
        # log's usual chunk), which the registry answers without a loop.
        _check_register_ids(chunks + [[s for s in spans if _parses(s)] for spans in chunks])


def _parses(span: bytes) -> bool:
    try:
        parse_register_span(span)
    except (FieldError, ValueError):
        return False
    return True


def _check_register_ids(chunks: list[list[bytes]]) -> None:
    reg = DiagRegistry()
    want: dict[bytes, int] = {}
    keys = []
    for spans in chunks:
        ids, errors = reg.register_ids(spans)
        for i, span in enumerate(spans):
            try:
                key = parse_register_span(span)
            except (FieldError, ValueError):
                assert i in errors and ids[i] == -1
                continue
            if span not in want:
                want[span] = len(want)
                keys.append(key)
            assert i not in errors
            assert ids[i] == want[span]
    assert reg.n_registers == len(want)
    # The columns hold each register as parsed: rebuilt RegisterKeys equal the parser's.
    assert list(reg.registers) == keys
    a = reg.arrays()
    assert a["device_id"].tolist() == [k.device_id for k in keys]
    assert reg.heads.take(a["counting_head"]) == [k.counting_head for k in keys]


# Value spans ``Data:…\tDate:…``: few distinct, valid and not (bad data, bad date, wrong shape).
_value_span = st.builds(
    lambda data, day: f"Data:{data}\tDate:{day}".encode(),
    st.sampled_from(["18", "0", "1", "Ω", "", "12x"]),
    st.sampled_from(["2015-10-31", "2015-11-01", "2015-13-01", "x"]),
)
_any_value_span = st.one_of(_value_span, _value_span, _value_span, st.binary(max_size=30))


@settings(max_examples=150, deadline=None)
@given(
    chunks=st.lists(st.lists(_any_value_span, max_size=20, unique=True), max_size=8),
    cache_max=st.sampled_from([1, 3, 10**6]),
)
def test_values_across_chunks_equal_each_span_decoded_alone(chunks: list[list[bytes]], cache_max: int) -> None:
    """Value spans read chunk after chunk, many met before (from the decoded-span cache): the same rows,
    errors and data codes (texts numbered in order of first reading) as decoding each span on its own.  A
    tiny cache is cleared between and within chunks."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("parsers.diag.registry._VALUE_CACHE_MAX", cache_max)
        reg = DiagRegistry()
        codes: dict[str, int] = {}
        for spans in chunks:
            cols, errors = reg.values(spans)
            assert cols.shape == (4, len(spans)) and cols.dtype == np.int64
            for i, span in enumerate(spans):
                parts = span.split(b"\t")
                if len(parts) != 2:
                    assert isinstance(errors[i], FieldError) and cols[:, i].tolist() == [0, 0, 0, 0]
                    continue
                data = DiagRegistry._parse_data(parts[0])
                day = DiagRegistry._parse_day(parts[1])
                if isinstance(data, FieldError):
                    assert errors[i].reason == data.reason and cols[:, i].tolist() == [0, 0, 0, 0]
                    continue
                code = codes.setdefault(data[0], len(codes))  # read, so interned, even beside a bad date
                if isinstance(day, FieldError):
                    assert errors[i].reason == day.reason and cols[:, i].tolist() == [0, 0, 0, 0]
                    continue
                assert i not in errors
                assert cols[:, i].tolist() == [code, data[1], data[2], day]
        assert reg.data.values == list(codes)


@settings(max_examples=150, deadline=None)
@given(
    batches=st.lists(st.lists(st.text(max_size=6), max_size=25), max_size=8),
    front_max=st.sampled_from([1, 3, 10**6]),
)
def test_string_dictionary_codes_equal_a_dict_in_first_seen_order(batches: list[list[str]], front_max: int) -> None:
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dictionary, "FRONT_CACHE_MAX", front_max)
        _check_codes(batches)


def _check_codes(batches: list[list[str]]) -> None:
    d = StringDictionary()
    want: dict[str, int] = {}
    for batch in batches:
        got = d.codes(batch).tolist()
        assert got == [want.setdefault(v, len(want)) for v in batch]
        if batch:
            assert d.code(batch[0]) == want[batch[0]]
    assert d.values == list(want)
    assert d.take(np.arange(len(want))[::-1]) == list(want)[::-1]
    assert len(d) == len(want)


def test_string_dictionary_keeps_lone_surrogates() -> None:
    d = StringDictionary()
    odd = "file\udcff"  # a byte of a file name that is not UTF-8 (surrogateescape)
    assert d.codes(["a", odd, "a"]).tolist() == [0, 1, 0]
    assert d.value(1) == odd and d.values == ["a", odd]


def test_digest_index_tells_apart_digests_sharing_their_high_half() -> None:
    """Two digests with the same high 64 bits (rare: about one pair in 10^7 among a million) stay distinct."""
    idx = DigestIndex()
    hi = np.array([5, 5, 5, 9], np.uint64)
    lo = np.array([1, 2, 3, 1], np.uint64)
    idx.add(hi[:2], lo[:2], np.array([10, 11]))
    idx.add(hi[2:], lo[2:], np.array([12, 13]))
    assert idx.get(hi, lo).tolist() == [10, 11, 12, 13]
    assert idx.get(np.array([5, 9, 7], np.uint64), np.array([4, 2, 1], np.uint64)).tolist() == [-1, -1, -1]


def test_digest_index_runs_stay_few_as_entries_grow() -> None:
    """Runs merge as they grow: O(log n) runs, each lookup a searchsorted per run."""
    idx = DigestIndex()
    rng = np.random.default_rng(7)
    for start in range(0, 20_000, 100):
        hi = rng.integers(0, 2**63, 100, dtype=np.uint64)
        idx.add(hi, hi, np.arange(start, start + 100))
    assert len(idx) == 20_000
    assert len(idx._runs) <= 2 * int(np.log2(20_000 / 100)) + 2


def test_unknown_labels_count_per_label_in_register_order() -> None:
    reg = DiagRegistry()
    spans = [
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:1\tAdr:1\tLabel:Temperatur",
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:1\tAdr:2\tLabel:Radsensor",
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:2\tAdr:1\tLabel:Temperatur",
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:1\tAdr:3\tLabel:Anders",
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:1\tAdr:4\tLabel:",
        b"Diag_id:1\tID:1\tDevice:IM\tType:1\tGS:G\tTrackinfo:WS1\tch:1\tAdr:5\tLabel:Nie",
    ]
    ids, errors = reg.register_ids(spans)
    assert not errors
    reg.count_records(np.repeat(ids, [2, 5, 1, 3, 4, 0]))
    # "Nie" has no record, the empty label is no label: neither is listed.
    assert list(reg.unknown_labels().items()) == [("Temperatur", 3), ("Anders", 3)]
    assert reg.canonical_in({"wheel_sensor"}).tolist() == [False, True, False, False, False, False]
