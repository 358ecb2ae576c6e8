"""Intelligent-sensor frames (text) → the frame table.

Seed 002's sensor sends its processor two bytes: byte 1 is the working
status, byte 2 the axle count while the section is occupied or the check
byte 0xA5 while it is clear (bits and check-byte rule in
:mod:`parsers.frames.table` and ``docs/frames.md``).  This module reads text
files, one frame a line: ``2021-06-06T10:15:02.125 AC07 4A05`` (or
``4A 05``).  Lines are matched and the bits decoded a chunk at a time with
vectorized string and numpy operations; only rejected lines are looked at
one by one, to say why.

Recorded CAN traffic (candump, ASC, BLF, PEAK TRC) is read by
:mod:`parsers.frames.can`.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from parsers.frames.table import (
    FrameColumns,
    finish_table,
    suspect_mask,
)
from parsers.report import FileReport, ParseReport, escape_text
from parsers.sources import Chunk, OverlongLine, ReadFailure, iter_chunks, open_input

__all__ = ["MAX_LINE_CHARS", "frame_line_problem", "parse_frames", "read_frame_lines"]

MAX_LINE_CHARS = 256  # a frame line is about 35 characters; longer is not one
_MAX_LINE_BYTES = 64 << 10  # lines beyond this are never held whole in memory
_SENSOR_MAX = 32
_TIME_MIN = pd.Timestamp("1900-01-01", tz="UTC")
_TIME_MAX = pd.Timestamp("2200-01-01", tz="UTC")

_TIME_PATTERN = r"\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}(?:\.\d{1,9})?(?:Z|[+-]\d{2}:?\d{2})?"
_SENSOR_PATTERN = r"[^\s\x00-\x1f\x7f-\x9f]{1,32}"
_LINE_RE = (
    rf"^\s*(?P<time>{_TIME_PATTERN})\s+(?P<sensor>{_SENSOR_PATTERN})"
    r"\s+(?P<b1>[0-9A-Fa-f]{2})\s*(?P<b2>[0-9A-Fa-f]{2})\s*$"
)
_TIME_FULL = re.compile(_TIME_PATTERN)
_SENSOR_FULL = re.compile(_SENSOR_PATTERN)
_HEX = re.compile(r"[0-9A-Fa-f]+")
_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")

# ASCII → hex digit value (255: not a hex digit; the line regex excludes those).
_HEX_LUT = np.full(256, 255, np.uint8)
for _i, _c in enumerate(b"0123456789abcdef"):
    _HEX_LUT[_c] = _i
    _HEX_LUT[ord(chr(_c).upper())] = _i


def frame_line_problem(text: str) -> tuple[str, str] | None:
    """Why one text line is not a valid frame line: (category, reason), or None.

    The per-line statement of the rules the vectorized pass applies; it is
    run only on lines that pass failed, to name the reason.
    """
    if len(text) > MAX_LINE_CHARS:
        return "too long", f"line of {len(text)} characters; a frame line is under {MAX_LINE_CHARS}"
    if "\x00" in text or len(_CONTROL.findall(text)) > 2:
        return "binary", "binary data, not a frame line"
    fields = text.split()
    if not fields or text.lstrip().startswith("#"):
        return None
    if len(fields) not in (3, 4):
        return (
            "fields",
            f"expected '<time> <sensor> <frame>' (3 fields, 4 with a space in the frame), found {len(fields)}",
        )
    stamp, sensor, *frame = fields
    if not _TIME_FULL.fullmatch(stamp):
        return "time", f"time: expected ISO 8601 like 2021-06-06T10:15:02.125, found '{escape_text(stamp, 40)}'"
    try:
        ts = pd.Timestamp(stamp)
    except (ValueError, OverflowError):
        return "time", f"time: impossible date or time '{escape_text(stamp, 40)}'"
    ts = ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")
    if not _TIME_MIN <= ts < _TIME_MAX:
        return "time", f"time: year outside 1900-2199 '{escape_text(stamp, 40)}'"
    if not _SENSOR_FULL.fullmatch(sensor) or "\ufffd" in sensor:
        return (
            "sensor",
            f"sensor: expected an id of 1-{_SENSOR_MAX} printable characters, found '{escape_text(sensor, 40)}'",
        )
    digits = "".join(frame)
    if not _HEX.fullmatch(digits):
        return "hex", f"frame: not hexadecimal '{escape_text(' '.join(frame), 40)}'"
    if len(digits) != 4:
        return "frame length", f"frame: expected 2 bytes (4 hex digits), found {len(digits)} hex digits"
    if len(frame) == 2 and (len(frame[0]), len(frame[1])) != (2, 2):
        return (
            "frame length",
            f"frame: expected 2 bytes as '4A05' or '4A 05', found '{escape_text(' '.join(frame), 40)}'",
        )
    return None


def _bools(values: pa.Array) -> np.ndarray:
    """A pyarrow boolean array as numpy, null as False."""
    return np.asarray(pc.fill_null(values, False).to_numpy(zero_copy_only=False), bool)


def _hex_byte(digits: pa.Array) -> np.ndarray:
    """Two-character hex strings (validated by the line pattern) → uint8, without a Python loop."""
    if len(digits) == 0:
        return np.zeros(0, np.uint8)
    digits = pc.cast(digits, pa.binary())
    offsets = np.frombuffer(digits.buffers()[1], np.int32)[digits.offset : digits.offset + len(digits)]
    raw = np.frombuffer(digits.buffers()[2], np.uint8)
    nib = _HEX_LUT[raw[offsets[:, None] + np.arange(2)]]
    return ((nib[:, 0] << 4) | nib[:, 1]).astype(np.uint8)


def _frame_chunk(
    chunk: Chunk, first_line: int, file_id: int, fr: FileReport, cols: FrameColumns, report: ParseReport
) -> int:
    """Parse one chunk of a frame file; returns the number of lines it held."""
    data = bytes(chunk.data)
    text = data.decode("utf-8", errors="replace")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()  # the chunk ends with a newline
    n = len(lines)
    fr.lines_read += n
    arr = pa.array(lines, pa.string())
    trimmed = pc.utf8_trim_whitespace(arr)
    blank = _bools(pc.or_(pc.equal(trimmed, ""), pc.starts_with(trimmed, "#")))
    m = pc.extract_regex(arr, _LINE_RE)  # RE2, in C++: null where the line does not match
    ok = _bools(m.is_valid()) & ~blank
    ok &= _bools(pc.less_equal(pc.utf8_length(arr), MAX_LINE_CHARS))
    ok &= ~_bools(pc.match_substring(m.field("sensor"), "\ufffd"))
    t = pd.to_datetime(pd.Series(m.field("time"), dtype=object).where(ok), format="ISO8601", utc=True, errors="coerce")
    ok &= (t.notna() & (t >= _TIME_MIN) & (t < _TIME_MAX)).to_numpy(bool)
    good = np.flatnonzero(ok)
    picked = m.take(pa.array(good, pa.int64()))
    status = _hex_byte(picked.field("b1"))
    byte2 = _hex_byte(picked.field("b2"))
    time_ns = t.iloc[good].dt.tz_convert(None).astype("datetime64[ns]").to_numpy().view(np.int64)
    line_no = good.astype(np.int64) + first_line
    sensor = picked.field("sensor").to_numpy(zero_copy_only=False)
    cols.add(time_ns, sensor, status, byte2, file_id, line_no)
    fr.records += len(good)
    fr.blank += int(blank.sum())

    bad = np.flatnonzero(~ok & ~blank)
    suspects = np.flatnonzero(suspect_mask(status, byte2))
    if len(bad) or len(suspects):
        raw_lines = data.split(b"\n")
        for i in suspects.tolist():
            cols.suspects[(file_id, int(line_no[i]))] = raw_lines[int(good[i])]
        last_open = chunk.final and not chunk.ends_with_newline()
        for i in bad.tolist():
            problem = frame_line_problem(lines[i]) or ("fields", "not a frame line '<time> <sensor> <frame>'")
            category, reason = problem
            if last_open and i == n - 1:
                category, reason = "truncated", f"truncated last line (no newline at end of file): {reason}"
            # A CRLF line's CR is its line end, not its text (as the other readers show it).
            report.reject(fr, first_line + i, category, reason, raw_lines[i].removesuffix(b"\r"))
    return n


def _read_frame_file(path: Path, file_id: int, cols: FrameColumns, report: ParseReport) -> None:
    stream, raw, info = open_input(path)
    fr = FileReport(file=str(path), encoding=info.encoding, compressed=info.compressed)
    report.files.append(fr)
    line = 1
    try:
        for item in iter_chunks(stream, info, max_line_bytes=_MAX_LINE_BYTES, name=str(path)):
            if isinstance(item, ReadFailure):  # corrupt gzip: the lines before it are kept
                fr.lines_read += 1
                report.reject(fr, line, "corrupt", item.message(line - 1), item.head)
                line += 1
            elif isinstance(item, OverlongLine):
                fr.lines_read += 1
                report.reject(
                    fr,
                    line,
                    "too long",
                    f"line of {item.length} bytes; a frame line is under {MAX_LINE_CHARS}",
                    item.head,
                )
                line += 1
            else:
                line += _frame_chunk(item, line, file_id, fr, cols, report)
        fr.bytes_read = raw.tell()
    finally:
        stream.close()
        raw.close()
    fr.ends_without_newline = info.ends_without_newline


def read_frame_lines(data: bytes, first_line: int, fr: FileReport, report: ParseReport) -> FrameColumns:
    """Complete lines of a frame log (a block of a growing one, from line ``first_line``) → frame-table
    columns (file id 0), every line counted in ``fr`` as :func:`parse_frames` counts it."""
    cols = FrameColumns()
    pieces: list[bytes] = [data]
    if len(data) > _MAX_LINE_BYTES:  # an overlong line is refused whole, as the batch reader's splitter does
        lines = data.split(b"\n")[:-1]
        pieces, run = [], []
        for raw in lines:
            if len(raw) <= _MAX_LINE_BYTES:
                run.append(raw)
                continue
            pieces.append(b"".join(r + b"\n" for r in run))
            pieces.append(raw)
            run = []
        pieces.append(b"".join(r + b"\n" for r in run))
    line = first_line
    for piece in pieces:
        if len(piece) > _MAX_LINE_BYTES and not piece.endswith(b"\n"):
            fr.lines_read += 1
            reason = f"line of {len(piece)} bytes; a frame line is under {MAX_LINE_CHARS}"
            report.reject(fr, line, "too long", reason, piece[:1024])
            line += 1
        elif piece:
            line += _frame_chunk(Chunk(piece, final=False), line, 0, fr, cols, report)
    return cols


def parse_frames(paths: Iterable[Path | str]) -> tuple[pd.DataFrame, ParseReport]:
    """Parse intelligent-sensor frame files (plain or gzip) into one frame table and a report.

    Columns (:data:`FRAME_COLUMNS`): ``time`` (datetime64[ns], naive: as
    written, or UTC when the line gave a zone), ``sensor`` (category),
    ``status`` and ``byte2`` (uint8), ``check`` (byte 2 read as the check
    byte, see :func:`check_byte_mask`), the status bits ``sys``, ``ses1``,
    ``ses2``, ``ses3``, ``der``, ``err`` (bool), ``t_since_s`` (0-3),
    ``file`` (category) and ``line`` (1-based).  Rows are in input order.
    """
    report = ParseReport()
    cols = FrameColumns()
    files = [str(Path(p)) for p in paths]
    for file_id, name in enumerate(files):
        _read_frame_file(Path(name), file_id, cols, report)
    return finish_table(cols, files, report, {}), report
