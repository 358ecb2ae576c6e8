"""parsers.diag.read: every line parsed or rejected with file, line and reason."""

from __future__ import annotations

import gzip
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from parsers.diag.read import read_diag
from parsers.diag.records import RECORD_COLUMNS
from tests.conftest import record


def _write(tmp_path: Path, data: bytes, name: str = "log.txt") -> Path:
    p = tmp_path / name
    p.write_bytes(data)
    return p


def _lines(*lines: str, sep: str = "\n", encoding: str = "utf-8") -> bytes:
    return (sep.join(lines) + sep).encode(encoding)


def test_record_columns_and_types(samples: Path) -> None:
    df, report = read_diag([samples / "osong_ws4_0932_detection.log"])
    assert list(df.columns) == list(RECORD_COLUMNS)
    assert len(df) == 34 and report.records == 34 and report.rejected == 0
    row = df[df["address"] == 20].iloc[0]
    assert (row["label"], row["label_canonical"], row["data"], row["value"], row["data_kind"]) == (
        "CRC-Code",
        "crc_code",
        "0xD8",
        0xD8,
        "hex",
    )
    char = df[df["address"] == 2].iloc[0]
    assert (char["data"], char["value"], char["data_kind"]) == ("'T'", ord("T"), "char")
    assert df["time"].iloc[0] == pd.Timestamp("2015-10-31 09:32:24")
    for col in ("device", "counting_head", "label", "label_canonical", "data", "file"):
        assert isinstance(df[col].dtype, pd.CategoricalDtype), col
    assert df["line"].tolist() == list(range(1, 35))
    assert df["counting_head"].unique().tolist() == ["WS4"]


def test_empty_labels_have_no_canonical_name(samples: Path) -> None:
    df, _ = read_diag([samples / "osong_ws4_0932_detection.log"])
    unlabeled = df[df["address"] == 19]
    assert unlabeled["label"].iloc[0] == "" and pd.isna(unlabeled["label_canonical"].iloc[0])


def test_fractional_seconds_are_kept(tmp_path: Path) -> None:
    p = _write(tmp_path, _lines(record(time="09:32:24.125"), record(time="09:32:24.5"), record(time="09:32:24")))
    df, _ = read_diag([p])
    assert df["time"].tolist() == [
        pd.Timestamp("2015-10-31 09:32:24.125"),
        pd.Timestamp("2015-10-31 09:32:24.5"),
        pd.Timestamp("2015-10-31 09:32:24"),
    ]
    assert df["subsecond"].tolist() == [True, True, False]


def test_blank_lines_are_counted_not_rejected(tmp_path: Path) -> None:
    p = _write(tmp_path, _lines("", record(), "   ", "\t", record(), ""))
    df, rep = read_diag([p])
    assert (rep.lines_read, rep.records, rep.blank, rep.rejected) == (6, 2, 4, 0)
    assert df["line"].tolist() == [2, 5]


def test_crlf_line_ends(tmp_path: Path) -> None:
    p = _write(tmp_path, _lines(record(), record(time="09:32:25"), sep="\r\n"))
    df, rep = read_diag([p])
    assert rep.records == 2 and rep.rejected == 0
    assert df["time"].iloc[1] == pd.Timestamp("2015-10-31 09:32:25")


def test_utf8_bom_is_skipped(tmp_path: Path) -> None:
    p = _write(tmp_path, b"\xef\xbb\xbf" + _lines(record(), record()))
    df, rep = read_diag([p])
    assert rep.records == 2 and rep.files[0].encoding == "utf-8-sig"
    assert df["diag_id"].iloc[0] == 2


def test_utf16_export_is_transcoded(tmp_path: Path) -> None:
    p = _write(tmp_path, _lines(record(), record(label="Zähler 1-Fl"), sep="\r\n", encoding="utf-16"))
    df, rep = read_diag([p])
    assert rep.records == 2 and rep.files[0].encoding == "utf-16"
    assert df["label_canonical"].tolist() == ["sum_counter", "counter_1_edge"]


def test_latin1_and_mojibake_labels_map_to_one_name(tmp_path: Path) -> None:
    latin1 = record(label="Summenzä").encode("cp1252")
    mojibake = record(label="Summenzä".encode().decode("cp1252")).encode()  # "SummenzÃ¤"
    p = _write(tmp_path, latin1 + b"\n" + mojibake + b"\n" + record().encode() + b"\n")
    df, rep = read_diag([p])
    assert rep.rejected == 0
    assert df["label_canonical"].tolist() == ["sum_counter"] * 3
    assert df["label"].tolist() == ["Summenzä", "SummenzÃ¤", "Summenzä"]


def test_truncated_last_line_without_newline(tmp_path: Path) -> None:
    good = _write(tmp_path, (record() + "\n" + record(time="09:32:25")).encode(), "good.log")
    _, rep = read_diag([good])
    assert rep.records == 2 and rep.files[0].ends_without_newline
    cut = _write(tmp_path, (record() + "\n" + record()[:60]).encode(), "cut.log")
    _, rep = read_diag([cut])
    assert (rep.records, rep.rejected) == (1, 1)
    (r,) = rep.rejections
    assert r.line == 2 and r.reason.startswith("truncated last line")


def test_binary_junk_is_rejected_with_line_numbers(tmp_path: Path) -> None:
    junk = bytes(range(256)) * 4
    p = _write(tmp_path, record().encode() + b"\n" + junk + b"\n" + record().encode() + b"\n")
    df, rep = read_diag([p])
    assert rep.records == 2
    assert rep.lines_read == rep.records + rep.blank + rep.rejected
    assert rep.rejected >= 1
    assert df["line"].iloc[0] == 1 and df["line"].iloc[1] == rep.lines_read
    for r in rep.rejections:
        assert "\x1b" not in r.text and "\x00" not in r.text  # shown escaped


@pytest.mark.parametrize(
    ("line", "category", "needle"),
    [
        (record(date="2015-02-30"), "Date", "impossible date '2015-02-30'"),
        (record(date="2015-13-01"), "Date", "impossible date"),
        (record(date="31/10/2015"), "Date", "expected YYYY-MM-DD"),
        # Outside what int64 ns (pandas) timestamps hold: rejected, not an OverflowError.
        (record(date="0001-01-01"), "Date", "date out of range '0001-01-01'"),
        (record(date="9999-12-31"), "Date", "date out of range"),
        (record(date="1677-09-21"), "Date", "date out of range"),
        (record(date="2262-04-11"), "Date", "date out of range"),
        (record(date="01.01.0001"), "Date", "date out of range"),
        (record(time="25:00:00"), "Time", "impossible time '25:00:00'"),
        (record(time="09:61:00"), "Time", "impossible time"),
        (record(time="9:32"), "Time", "expected HH:MM:SS"),
        (record(ch="x"), "ch", "expected a channel number"),
        (record(ch=""), "ch", "expected a channel number"),
        (record(data="abc"), "Data", "expected a number"),
        (record(adr="0A0"), "Adr", "numeric register address"),
        (record().replace("Trackinfo:", "Track:"), "fields", "expected 'Trackinfo:"),
        ("not a record at all", "fields", "expected 12 tab-separated"),
        (record(label="Sum\x1b[31m"), "Label", "control characters"),
    ],
)
def test_bad_field_is_rejected_with_reason(tmp_path: Path, line: str, category: str, needle: str) -> None:
    p = _write(tmp_path, _lines(record(), line, record()))
    df, rep = read_diag([p])
    assert (rep.records, rep.rejected) == (2, 1)
    (r,) = rep.rejections
    assert (r.file, r.line) == (str(p), 2)
    assert needle in r.reason
    assert rep.rejected_by_reason[category] == 1
    assert df["line"].tolist() == [1, 3]


def test_one_line_dated_out_of_range_among_a_thousand_is_rejected_alone(tmp_path: Path) -> None:
    # Hostile input: a single bit flip in a year (2015 -> 6111 is 0x07DF -> 0x17DF) among good records.
    good = [record(time=f"09:{i // 60:02d}:{i % 60:02d}") for i in range(1000)]
    lines = [*good[:500], record(date="6111-10-31"), *good[500:]]
    df, rep = read_diag([_write(tmp_path, _lines(*lines))])
    assert (rep.records, rep.rejected) == (1000, 1)
    assert rep.rejections[0].line == 501 and "date out of range" in rep.rejections[0].reason
    assert df["time"].min() == pd.Timestamp("2015-10-31 09:00:00")


def test_dates_at_the_edges_of_the_timestamp_range_are_kept(tmp_path: Path) -> None:
    lines = [record(date="1677-09-22", time="00:00:00"), record(date="2262-04-10", time="23:59:59.999999999")]
    df, rep = read_diag([_write(tmp_path, _lines(*lines))])
    assert rep.rejected == 0
    assert df["time"].tolist() == [pd.Timestamp("1677-09-22"), pd.Timestamp("2262-04-10 23:59:59.999999999")]


def test_one_megabyte_line_is_rejected_and_shown_short(tmp_path: Path) -> None:
    huge = "Diag_id:" + "9" * (1 << 20)
    p = _write(tmp_path, _lines(record(), huge, record()))
    _, rep = read_diag([p])
    assert (rep.records, rep.rejected) == (2, 1)
    assert len(rep.rejections[0].text) < 200


def test_line_longer_than_the_limit_is_skipped_in_bounded_memory(tmp_path: Path) -> None:
    huge = b"x" * (3 << 20)
    p = _write(tmp_path, record().encode() + b"\n" + huge + b"\n" + record().encode() + b"\n")
    _, rep = read_diag([p], chunk_bytes=1 << 16, max_line_bytes=1 << 20)
    assert (rep.lines_read, rep.records, rep.rejected) == (3, 2, 1)
    r = rep.rejections[0]
    assert r.line == 2 and "longer than" in r.reason


def test_empty_file_has_zero_records(tmp_path: Path) -> None:
    df, rep = read_diag([_write(tmp_path, b"")])
    assert len(df) == 0 and rep.lines_read == 0 and rep.records == 0


def test_gzip_input_by_magic_bytes(tmp_path: Path) -> None:
    p = _write(tmp_path, gzip.compress(_lines(record(), record(time="09:32:25"))), "export.dat")
    _df, rep = read_diag([p])
    assert rep.records == 2 and rep.files[0].compressed


def test_truncated_gzip_keeps_the_lines_before_the_cut_and_rejects_the_rest(tmp_path: Path) -> None:
    data = gzip.compress(_lines(*[record()] * 1000))
    p = _write(tmp_path, data[: len(data) // 2], "cut.gz")
    df, rep = read_diag([p])  # parsers.sources: the complete lines, then one "corrupt" rejection
    rep.check()
    assert 0 < rep.records < 1000 and len(df) == rep.records
    (rej,) = rep.rejections
    assert (
        rej.line == rep.records + 1
        and rej.reason.startswith("corrupt gzip (truncated")
        and (f"after {rep.records} lines" in rej.reason)
    )


def test_many_files_keep_their_names_and_lines(tmp_path: Path) -> None:
    a = _write(tmp_path, _lines(record(), record()), "a.log")
    b = _write(tmp_path, _lines("junk", record()), "b.log")
    df, rep = read_diag([a, b])
    assert df["file"].astype(str).tolist() == [str(a), str(a), str(b)]
    assert df["line"].tolist() == [1, 2, 2]
    assert [(f.lines_read, f.records, f.rejected) for f in rep.files] == [(2, 2, 0), (2, 1, 1)]


def test_german_dates_are_accepted(tmp_path: Path) -> None:
    df, _ = read_diag([_write(tmp_path, _lines(record(date="31.10.2015")))])
    assert df["time"].iloc[0] == pd.Timestamp("2015-10-31 09:32:24")


def test_unknown_labels_are_kept_verbatim_and_counted(tmp_path: Path) -> None:
    p = _write(tmp_path, _lines(record(label="Temperatur"), record(label="Temperatur"), record(label="[bold]x")))
    df, rep = read_diag([p])
    assert df["label_canonical"].astype(str).tolist() == ["Temperatur", "Temperatur", "[bold]x"]
    assert rep.unknown_labels == {"Temperatur": 2, "[bold]x": 1}


def test_chunk_boundaries_do_not_change_the_result(samples: Path) -> None:
    path = samples / "ws4_subsecond.log"
    whole, _ = read_diag([path])
    tiny, rep = read_diag([path], chunk_bytes=97)  # lines straddle every chunk
    pd.testing.assert_frame_equal(whole, tiny)
    assert rep.records == 100


_pieces = st.sampled_from(
    [
        record(),
        record(time="09:32:24.250", label="Radsensor", adr="026", data="1"),
        record(label="ZÃ¤hler 1-Fl"),
        record(date="2015-02-29"),
        record(ch="z"),
        "",
        "   ",
        "\x00\x01garbage\t\t",
        "Diag_id:1\tID:2",
    ]
)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    lines=st.lists(_pieces, max_size=40),
    crlf=st.booleans(),
    final_newline=st.booleans(),
    chunk=st.integers(64, 4096),
)
def test_totals_always_add_up(tmp_path: Path, lines: list[str], crlf: bool, final_newline: bool, chunk: int) -> None:
    sep = "\r\n" if crlf else "\n"
    text = sep.join(lines) + (sep if final_newline and lines else "")
    p = tmp_path / "prop.log"
    p.write_bytes(text.encode("utf-8"))
    df, rep = read_diag([p], chunk_bytes=chunk)
    rep.check()
    valid = sum(1 for x in lines if x.startswith("Diag_id:00002"))
    bad_date_or_ch = sum(1 for x in lines if "2015-02-29" in x or "ch:z" in x)
    assert rep.records == valid - bad_date_or_ch == len(df)
    expected_lines = len(lines) if lines and (final_newline or lines[-1] != "" or len(lines) > 1) else 0
    if lines and not final_newline and lines[-1] == "":
        expected_lines = len(lines) - 1
    assert rep.lines_read == expected_lines
