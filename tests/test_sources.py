"""parsers.sources: one reader for every input, whatever it is and however it is damaged.

Files, gzip (truncated, junk after the end, corrupt), UTF-16 with and
without a BOM, CR-only line ends, FIFOs, standard input and process
substitution.  The property test at the end runs every combination of
encoding, line end and compression on random text.
"""

from __future__ import annotations

import gzip
import io
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from parsers import sources
from parsers.sources import (
    InputError,
    OverlongLine,
    ReadFailure,
    iter_chunks,
    open_input,
    release_streams,
    utf16_without_bom,
)

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_logs" / "osong_ws4_0932_passage.log"


@pytest.fixture(autouse=True)
def _fresh_streams() -> Iterator[None]:
    yield
    release_streams()


def read_lines(path: Path | str, chunk_bytes: int = 1 << 16) -> tuple[list[bytes | str], sources.SourceInfo]:
    """Every line (CR of CRLF dropped, as the parsers do); a ReadFailure as its message."""
    stream, raw, info = open_input(path)
    out: list[bytes | str] = []
    try:
        for item in iter_chunks(stream, info, chunk_bytes=chunk_bytes, name=str(path)):
            if isinstance(item, ReadFailure):
                out.append(item.message(len(out)))
            elif isinstance(item, OverlongLine):
                out.append(f"overlong {item.length}")
            else:
                data = bytes(item.data)
                pieces = data.split(b"\n")
                if data.endswith(b"\n"):
                    pieces.pop()
                out.extend(p.removesuffix(b"\r") for p in pieces)
    finally:
        stream.close()
        raw.close()
    return out, info


BODY = b"".join(b"Diag_id:%05d\tTrackinfo:WS4\tData:%d\n" % (i, i % 7) for i in range(20_000))
LINES = BODY.split(b"\n")[:-1]


# ------------------------------------------------------------------ gzip


def test_gzip_reads_like_the_plain_file_by_its_magic_bytes_not_its_name(tmp_path: Path) -> None:
    (tmp_path / "a.txt").write_bytes(gzip.compress(BODY))
    lines, info = read_lines(tmp_path / "a.txt")
    assert lines == LINES and info.compressed


def test_concatenated_gzip_members_and_zero_padding_are_one_stream(tmp_path: Path) -> None:
    (tmp_path / "a.gz").write_bytes(gzip.compress(BODY) + gzip.compress(BODY) + b"\0" * 512)
    lines, _ = read_lines(tmp_path / "a.gz")
    assert lines == LINES + LINES


def test_truncated_gzip_keeps_every_complete_line_before_the_cut(tmp_path: Path) -> None:
    data = gzip.compress(BODY)
    (tmp_path / "cut.gz").write_bytes(data[: len(data) // 2])
    lines, _ = read_lines(tmp_path / "cut.gz")
    *good, failure = lines
    assert good == LINES[: len(good)] and len(good) > len(LINES) // 3
    assert failure == (
        f"corrupt gzip (truncated: the data ends before the end of the compressed stream) after {len(good)} lines; "
        "the rest of the input is not read"
    )


def test_junk_after_the_gzip_data_is_one_failure_after_all_the_lines(tmp_path: Path) -> None:
    (tmp_path / "junk.gz").write_bytes(gzip.compress(BODY) + b"PK\x03\x04 not gzip")
    lines, _ = read_lines(tmp_path / "junk.gz")
    assert lines[:-1] == LINES
    assert lines[-1] == f"corrupt gzip (junk after the end of the compressed data) after {len(LINES)} lines; " + (
        "the rest of the input is not read"
    )


def test_a_gzip_header_with_nothing_readable_fails_after_0_lines(tmp_path: Path) -> None:
    (tmp_path / "bad.gz").write_bytes(b"\x1f\x8b\x08junk")
    lines, _ = read_lines(tmp_path / "bad.gz")
    assert len(lines) == 1 and isinstance(lines[0], str) and "corrupt gzip" in lines[0] and "after 0 lines" in lines[0]


@pytest.mark.parametrize("where", [0.1, 0.5, 0.9])
def test_a_bit_flip_in_gzip_data_is_reported_never_raised(tmp_path: Path, where: float) -> None:
    data = bytearray(gzip.compress(BODY))
    data[int(len(data) * where)] ^= 0x10
    (tmp_path / "flip.gz").write_bytes(bytes(data))
    lines, _ = read_lines(tmp_path / "flip.gz")
    assert isinstance(lines[-1], str) and lines[-1].startswith("corrupt gzip (")


def test_a_gzip_bomb_is_read_in_bounded_pieces(tmp_path: Path) -> None:
    # 64 MiB of one line's worth of zeros compress to ~64 KiB: the line is cut off, not held whole.
    (tmp_path / "bomb.gz").write_bytes(gzip.compress(b"0" * (64 << 20) + b"\nend\n", 9))
    lines, _ = read_lines(tmp_path / "bomb.gz", chunk_bytes=1 << 20)
    assert lines == [f"overlong {64 << 20}", b"end"]


# ------------------------------------------------------------ encodings


@pytest.mark.parametrize(
    ("encoding", "bom", "name"),
    [
        ("utf-16-le", b"\xff\xfe", "utf-16"),
        ("utf-16-be", b"\xfe\xff", "utf-16"),
        ("utf-16-le", b"", "utf-16-le"),
        ("utf-16-be", b"", "utf-16-be"),
        ("utf-8", b"\xef\xbb\xbf", "utf-8-sig"),
        ("utf-8", b"", "utf-8"),
    ],
)
def test_utf16_with_or_without_bom_and_utf8_read_as_the_same_utf8_lines(
    tmp_path: Path, encoding: str, bom: bytes, name: str
) -> None:
    text = "Diag_id:00002\tLabel:Zähler 1-Fl\tData:'T'\r\nVị trí cảm biến,−152\r\n"
    (tmp_path / "t.csv").write_bytes(bom + text.encode(encoding))
    lines, info = read_lines(tmp_path / "t.csv")
    assert lines == [line.encode() for line in text.split("\r\n")[:-1]]
    assert info.encoding == name


def test_utf16_detection_needs_the_nul_pattern_not_any_nul() -> None:
    assert utf16_without_bom("Diag_id:1\n".encode("utf-16-le")) == "utf-16-le"
    assert utf16_without_bom("Diag_id:1\n".encode("utf-16-be")) == "utf-16-be"
    assert utf16_without_bom(b"Diag_id:1\x00\tData:2\n") is None  # a stray NUL in a UTF-8 line
    assert utf16_without_bom(b"\x00" * 64) is None
    assert utf16_without_bom(b"LOGG\x90\x00\x00\x00") is None


def test_cr_only_line_ends_are_line_ends(tmp_path: Path) -> None:
    (tmp_path / "mac.csv").write_bytes(b"a,1\rb,2\r\rc,3")
    lines, info = read_lines(tmp_path / "mac.csv")
    assert lines == [b"a,1", b"b,2", b"", b"c,3"] and info.line_ends == "cr" and info.ends_without_newline


def test_a_nul_or_stray_cr_inside_a_field_stays_inside_its_own_line(tmp_path: Path) -> None:
    (tmp_path / "t.csv").write_bytes(b"a,1\nb,\x002\nc,3\rx\nd,4\n")
    lines, info = read_lines(tmp_path / "t.csv")
    assert lines == [b"a,1", b"b,\x002", b"c,3\rx", b"d,4"] and info.line_ends == "lf"


# -------------------------------------------------------------- streams


def _fifo_with(tmp_path: Path, data: bytes) -> tuple[Path, threading.Thread]:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)

    def write() -> None:
        with open(fifo, "wb") as f:
            f.write(data)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    return fifo, writer


def test_a_fifo_is_read_as_a_stream_and_a_second_open_starts_again_at_byte_0(tmp_path: Path) -> None:
    fifo, writer = _fifo_with(tmp_path, gzip.compress(BODY))
    stream, raw, info = open_input(fifo)  # a parser's peek at the head ...
    assert stream.read(13) == b"Diag_id:00000" and info.stream and info.compressed
    stream.close()
    raw.close()
    lines, _ = read_lines(fifo)  # ... then its full read
    writer.join(5)
    assert lines == LINES


def test_a_stream_read_past_the_replay_limit_cannot_be_read_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sources, "REPLAY_LIMIT_BYTES", 1 << 16)
    fifo, writer = _fifo_with(tmp_path, BODY)
    assert read_lines(fifo)[0] == LINES
    writer.join(5)
    lines, _ = read_lines(fifo)
    assert len(lines) == 1 and "a stream can be read only once" in str(lines[0])


def test_dash_is_standard_input(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(gzip.compress(BODY))))
    lines, info = read_lines("-")
    assert lines == LINES and info.stream


def test_a_missing_file_and_a_directory_are_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        open_input(tmp_path / "nope.log")
    with pytest.raises(InputError, match="is a directory"):
        open_input(tmp_path)


def test_a_file_name_that_is_not_utf8_is_read(tmp_path: Path) -> None:
    name = os.fsdecode(os.fsencode(tmp_path) + b"/log\xff.txt")
    Path(name).write_bytes(BODY)
    assert read_lines(name)[0] == LINES


def test_process_substitution_through_the_cli_is_read_as_a_stream(tmp_path: Path) -> None:
    (tmp_path / "p.log.gz").write_bytes(gzip.compress(SAMPLE.read_bytes()))
    run = subprocess.run(
        [
            "bash",
            "-c",
            f"'{Path(sys.executable).with_name('trackside')}' analyze --json <(zcat {tmp_path / 'p.log.gz'})",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert '"records":' in run.stdout and "not seekable" not in run.stderr


# ------------------------------------------------------------- property

# Latin-1 text: BOM-less UTF-16 is told by its NUL bytes, which text mostly outside Latin-1 does not have
# (the example test above has Vietnamese in a mostly ASCII line, as real exports do).
_TEXT = st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=0xFF, blacklist_characters="\x7f"), max_size=60)


@settings(max_examples=60, deadline=None)
@given(
    lines=st.lists(_TEXT, max_size=30),
    encoding=st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-16-be"]),
    line_end=st.sampled_from(["\n", "\r\n", "\r"]),
    compressed=st.booleans(),
    chunk_bytes=st.sampled_from([7, 64, 1 << 16]),
)
def test_any_encoding_line_end_and_compression_give_back_the_same_lines(
    tmp_path_factory: pytest.TempPathFactory,
    lines: list[str],
    encoding: str,
    line_end: str,
    compressed: bool,
    chunk_bytes: int,
) -> None:
    if line_end == "\r" and encoding.startswith("utf-16-") and lines and not lines[0]:
        lines = ["x", *lines]  # a BOM-less UTF-16 head needs text to be told from binary
    data = "".join(line + line_end for line in lines).encode(encoding)
    path = tmp_path_factory.mktemp("enc") / "t.txt"
    path.write_bytes(gzip.compress(data) if compressed else data)
    got, info = read_lines(path, chunk_bytes=chunk_bytes)
    assert got == [line.encode() for line in lines]
    assert info.compressed == compressed


@pytest.mark.parametrize("cut", [12, 20, 40, 80])
def test_a_gzip_cut_inside_the_head_gives_the_lines_before_and_the_failure(tmp_path: Path, cut: int) -> None:
    # The head is read to recognise the encoding: a failure there is held back for the reader, not raised.
    # (Found by the fuzz suite: the held-back error's traceback kept the head buffer exported: BufferError.)
    data = gzip.compress(BODY, compresslevel=1)
    (tmp_path / "cut.gz").write_bytes(data[:cut])
    lines, info = read_lines(tmp_path / "cut.gz")
    assert info.compressed and isinstance(lines[-1], str) and lines[-1].startswith("corrupt gzip (")
    assert lines[:-1] == LINES[: len(lines) - 1]
