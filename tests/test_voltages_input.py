"""Voltage tables (parsers/voltages.py) as the world writes them, and what the report shows of them.

Regression tests for the "hostile input" issue: UTF-16 exports with and
without a BOM, CR-only line ends, a NUL or a stray CR inside a row (the csv
module's "new-line character seen in unquoted field" used to end the run),
numbers no receiver gives, and file names and cells that must be shown
escaped.
"""

from __future__ import annotations

import gzip
import itertools
import os
import unicodedata
from pathlib import Path

import pytest

from parsers.report import ParseReport, escape_name, escape_text
from parsers.voltages import read_voltages

SAMPLE = Path(__file__).resolve().parents[1] / "sample_logs" / "am_thuong_2021-06-06_voltages.csv"
TEXT = SAMPLE.read_bytes().decode("utf-8")
# Seed 000 (Zhang et al.), Table 2: the twelve in-phase voltages, mV.
IN_PHASE_MV = [346.0, 250.0, 180.0, 284.0, 230.0, 188.0, 233.0, 120.0, 216.0, 230.0, 313.0, 293.0]


def _cp1258(text: str) -> bytes:
    """As Vietnamese Windows writes it: a precomposed base where CP1258 has one, then combining tone marks."""
    out = bytearray()
    for ch in text:
        decomposed = unicodedata.normalize("NFD", ch)
        base, marks = decomposed[0], list(decomposed[1:])
        for order in itertools.permutations(marks):
            for k in range(len(order), -1, -1):
                try:
                    out += (unicodedata.normalize("NFC", base + "".join(order[:k])) + "".join(order[k:])).encode(
                        "cp1258"
                    )
                    break
                except UnicodeEncodeError:
                    continue
            else:
                continue
            break
        else:
            raise AssertionError(f"{ch!r} has no CP1258 form")
    return bytes(out)


@pytest.mark.parametrize(
    "encode",
    [
        lambda t: b"\xff\xfe" + t.replace("\n", "\r\n").encode("utf-16-le"),
        lambda t: t.encode("utf-16-le"),
        lambda t: t.encode("utf-16-be"),
        lambda t: t.replace("\n", "\r").encode("utf-8"),
        lambda t: gzip.compress(t.encode("utf-16")),
        lambda t: _cp1258(t),
    ],
    ids=["utf16-bom-crlf", "utf16le-no-bom", "utf16be-no-bom", "cr-only", "gzip-utf16", "cp1258"],
)
def test_the_sample_table_reads_the_same_in_every_documented_encoding(tmp_path: Path, encode) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "v.csv"
    path.write_bytes(encode(TEXT))
    table, report = read_voltages([path])
    report.check()
    assert (report.records, report.rejected) == (12, 0)
    assert table["in_phase_mv"].tolist() == IN_PHASE_MV


def _one_bad_row(tmp_path: Path, row: bytes) -> ParseReport:
    lines = TEXT.encode().split(b"\n")
    lines.insert(3, row)
    path = tmp_path / "v.csv"
    path.write_bytes(b"\n".join(lines))
    table, report = read_voltages([path])
    report.check()
    assert len(table) == 12 and report.records == 12  # the others all kept
    return report


@pytest.mark.parametrize(
    ("row", "reason"),
    [
        (b"13,2\x0046,-152,398", "a NUL byte at column 5"),
        (b'13,"246\r,-152,398', "a stray CR (a broken line end) at column 8"),
        (b"13,246,-152\r398", "a stray CR"),
        (b"13,\x1b[31m246,-152,398", "control character \\x1b"),
    ],
)
def test_a_nul_or_stray_cr_rejects_that_row_alone(tmp_path: Path, row: bytes, reason: str) -> None:
    report = _one_bad_row(tmp_path, row)
    (rej,) = report.rejections
    assert rej.line == 4 and reason in rej.reason and "\x1b" not in rej.text and "\r" not in rej.text


@pytest.mark.parametrize(
    "number",
    [str(2**64), "9" * 5000, "1e308", "nan", "inf", "-inf", "٣٤٦", "0x1F", "346.", "1_000"],
)
def test_numbers_no_receiver_gives_are_rejected_not_read(tmp_path: Path, number: str) -> None:
    report = _one_bad_row(tmp_path, f"13,{number},-152,398".encode())
    (rej,) = report.rejections
    assert rej.line == 4 and rej.reason.startswith("in_phase_mv:") and len(rej.reason) < 300


def test_minus_zero_is_a_number(tmp_path: Path) -> None:
    path = tmp_path / "v.csv"
    path.write_text("sensor,in_phase_mv,anti_phase_mv\n1,346,-0\n")
    table, report = read_voltages([path])
    assert report.records == 1 and table["anti_phase_mv"].tolist() == [0.0]


def test_a_hostile_header_cell_is_shown_escaped_in_the_reason(tmp_path: Path) -> None:
    path = tmp_path / "v.csv"
    path.write_bytes("sensor,\u202eevil[bold],anti\n1,\x1b]8;;http://x\x07,2\n".encode())
    _table, report = read_voltages([path])
    header, row = report.rejections
    assert "unknown column '\\u202eevil[bold]'" in header.reason and "\u202e" not in header.reason
    assert row.reason == "control character \\x1b at column 3" and row.text == "1,\\x1b]8;;http://x\\x07,2"


def test_a_file_name_that_is_not_utf8_is_analysed_and_shown_as_ls_does(tmp_path: Path) -> None:
    name = os.fsdecode(os.fsencode(tmp_path) + b"/volt\xff\xe2\x80\xae.csv")  # 0xFF, then U+202E (RLO)
    Path(name).write_bytes(SAMPLE.read_bytes())
    table, report = read_voltages([name])
    assert report.records == 12 and table["file"].iloc[0].endswith("/volt\\xff\\u202e.csv")
    shown = report.to_dict()["files"][0]["file"]
    assert shown.endswith("/volt\\xff\\u202e.csv")
    shown.encode("utf-8")  # printable: no lone surrogate left


def test_escape_text_shows_controls_bidi_and_bad_bytes_as_escapes() -> None:
    assert escape_text(b"a\tb\x1b[0m\xff\xe2\x80\x8f") == "a\\tb\\x1b[0m\\xff\\u200f"
    assert escape_text("\u2066x\u2069\u061c\ud800") == "\\u2066x\\u2069\\u061c\\ud800"
    assert escape_name("a\nb\udcff") == "a\\nb\\xff"
