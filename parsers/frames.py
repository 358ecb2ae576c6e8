"""Intelligent-sensor frames and CAN count frames → one frame table.

Seed 002's sensor sends its processor two bytes: byte 1 is the working
status, byte 2 the axle count while the section is occupied or the check
byte 0xA5 while it is clear.  Seed 000's counts travel to the control centre
over CAN.  This module reads both into the same table (formats only: no
railway inference); the layout of every bit and byte is in ``docs/frames.md``.

Byte 1, most significant bit first::

    bit   7    6     5     4     3    2    1  0
          SYS  SES1  SES2  SES3  DER  ERR  T1 T2

Two readers:

* :func:`parse_frames` — text files, one frame a line:
  ``2021-06-06T10:15:02.125 AC07 4A05`` (or ``4A 05``).  Lines are matched
  and the bits decoded a chunk at a time with vectorized string and numpy
  operations; only rejected lines are looked at one by one, to say why.
* :func:`parse_can` — recorded CAN traffic (candump ``.log``, Vector
  ``.asc``, Vector ``.blf``; plain or gzip) through python-can's own
  readers.  Standard id ``0x180 + n`` (n = 1..127) is node n's count frame:
  ``[status, count or 0xA5, total lo, total hi, seq]``.  Other traffic is
  counted, not rejected.

Byte 2 = 0xA5 is either the check byte or the count 165.  The parser
decides with :func:`check_byte_mask` (context rule, documented there) and
reports its reading in the ``check`` column; a frame read as a check byte
must have DER = 0, else it breaks the protocol and is rejected.
"""

from __future__ import annotations

import datetime as dt
import re
import struct
import zlib
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, TextIO, cast

import can
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc

from parsers.report import FileReport, ParseReport, escape_text
from parsers.sources import Chunk, InputError, OverlongLine, ReadFailure, iter_chunks, open_input

# --- the two-byte frame ------------------------------------------------------

SYS_BIT = 0x80  # microprocessor self-test: 0 normal, 1 fault
SES1_BIT = 0x40  # element S1 and its channel: 0 normal, 1 fault
SES2_BIT = 0x20
SES3_BIT = 0x10
DER_BIT = 0x08  # direction: 0 S1→S3, 1 S3→S1
ERR_BIT = 0x04  # 0 majority count normal, 1 the count may be wrong
T_MASK = 0x03  # T1 T2: whole seconds since the last interrupt, 0-3 (saturating)
CHECK_BYTE = 0xA5
# A count of 165 is the same byte as the check byte; see check_byte_mask.
COUNT_MAX = 255

# --- CAN count frames --------------------------------------------------------

COUNT_ID_BASE = 0x180  # standard id 0x180 + node = count frame of sensor node 1..127
NODE_MIN, NODE_MAX = 1, 127
COUNT_DLC = 5  # [status, count or 0xA5, total lo, total hi, seq]

FRAME_COLUMNS = (
    "time",
    "sensor",
    "status",
    "byte2",
    "check",
    "sys",
    "ses1",
    "ses2",
    "ses3",
    "der",
    "err",
    "t_since_s",
    "file",
    "line",
)
CAN_COLUMNS = (*FRAME_COLUMNS, "total", "seq", "can_id")

MAX_LINE_CHARS = 256  # a frame line is about 35 characters; longer is not one
MAX_CAN_LINE_CHARS = 1024  # an ASC CAN FD line with 64 data bytes is about 400
_MAX_LINE_BYTES = 64 << 10  # lines beyond this are never held whole in memory
_SENSOR_MAX = 32
_NS = 1_000_000_000
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


def encode_status(
    *,
    sys: bool = False,
    ses: tuple[bool, bool, bool] = (False, False, False),
    der: bool = False,
    err: bool = False,
    t_since_s: int = 0,
) -> int:
    """Byte 1 from its fields (the inverse of :func:`decode_status`)."""
    if not 0 <= t_since_s <= 3:
        raise ValueError(f"T1 T2 holds 0-3 seconds, not {t_since_s}")
    return (
        SYS_BIT * sys
        + SES1_BIT * ses[0]
        + SES2_BIT * ses[1]
        + SES3_BIT * ses[2]
        + DER_BIT * der
        + ERR_BIT * err
        + t_since_s
    )


def decode_status(status: np.ndarray) -> dict[str, np.ndarray]:
    """Byte 1 (uint8 array) → its fields: sys, ses1..3, der, err (bool), t_since_s (uint8)."""
    s = np.asarray(status, dtype=np.uint8)
    return {
        "sys": (s & SYS_BIT) != 0,
        "ses1": (s & SES1_BIT) != 0,
        "ses2": (s & SES2_BIT) != 0,
        "ses3": (s & SES3_BIT) != 0,
        "der": (s & DER_BIT) != 0,
        "err": (s & ERR_BIT) != 0,
        "t_since_s": (s & T_MASK).astype(np.uint8),
    }


def check_byte_mask(sensor: np.ndarray, time_ns: np.ndarray, byte2: np.ndarray) -> np.ndarray:
    """Which frames' byte 2 is the check byte 0xA5 (True) rather than a count.

    0xA5 is also the count 165.  Per sensor, in time order (input order for
    equal times), take each run of consecutive 0xA5 frames and the frames
    just before (P) and after (N) it; those are counts, by the run's
    definition.  The run is the count 165 when counting goes through it::

        P exists, P < 165, and (N > 165 if N exists, else P == 164)

    otherwise it is the check byte.  So ``164, A5, 170`` and ``160, A5, 170``
    are counts (165 passed between), ``164, A5`` at the end of the data is a
    count (a train standing at 165 axles), while ``160, A5`` and ``164, A5, 2``
    are a clear (the count restarts) and a log that starts with 0xA5 starts
    clear.  Vectorized: no Python loop over frames.
    """
    n = len(byte2)
    out = np.zeros(n, bool)
    if n == 0:
        return out
    order = np.lexsort((np.arange(n), time_ns, sensor))
    key = np.asarray(sensor)[order]
    b = np.asarray(byte2, dtype=np.int64)[order]
    is_a5 = b == CHECK_BYTE
    idx = np.arange(n)
    new_group = np.ones(n, bool)
    new_group[1:] = key[1:] != key[:-1]
    group_start = np.maximum.accumulate(np.where(new_group, idx, 0))
    last = np.empty(n, bool)
    last[:-1] = new_group[1:]
    last[-1] = True
    group_end = np.minimum.accumulate(np.where(last, idx, n - 1)[::-1])[::-1]
    # The nearest count (non-A5 frame) before and after each row.
    prev = np.maximum.accumulate(np.where(~is_a5, idx, -1))
    prev_before = np.concatenate(([-1], prev[:-1]))
    nxt = np.minimum.accumulate(np.where(~is_a5, idx, n)[::-1])[::-1]
    next_after = np.concatenate((nxt[1:], [n]))
    has_p = prev_before >= group_start
    has_n = next_after <= group_end
    p = b[np.clip(prev_before, 0, n - 1)]
    nx = b[np.clip(next_after, 0, n - 1)]
    counting = has_p & (p < CHECK_BYTE) & np.where(has_n, nx > CHECK_BYTE, p == CHECK_BYTE - 1)
    out[order] = is_a5 & ~counting
    return out


# --- text frame files ----------------------------------------------------------


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


@dataclass
class _Columns:
    """Parsed frames of all files so far, as lists of per-chunk arrays."""

    time_ns: list[np.ndarray] = field(default_factory=list)
    sensor: list[np.ndarray] = field(default_factory=list)  # str objects
    status: list[np.ndarray] = field(default_factory=list)
    byte2: list[np.ndarray] = field(default_factory=list)
    file_id: list[np.ndarray] = field(default_factory=list)
    line: list[np.ndarray] = field(default_factory=list)
    extra: dict[str, list[np.ndarray]] = field(default_factory=dict)
    # Raw text of the frames the protocol check may reject, by (file id, line).
    suspects: dict[tuple[int, int], bytes] = field(default_factory=dict)

    def add(
        self,
        time_ns: np.ndarray,
        sensor: np.ndarray,
        status: np.ndarray,
        byte2: np.ndarray,
        file_id: int,
        line: np.ndarray,
        **extra: np.ndarray,
    ) -> None:
        self.time_ns.append(time_ns.astype(np.int64))
        self.sensor.append(sensor)
        self.status.append(status.astype(np.uint8))
        self.byte2.append(byte2.astype(np.uint8))
        self.file_id.append(np.full(len(line), file_id, np.int32))
        self.line.append(line.astype(np.int64))
        for k, v in extra.items():
            self.extra.setdefault(k, []).append(v)

    def concat(self, name: str, dtype: Any) -> np.ndarray:
        parts = self.extra[name] if name in self.extra else getattr(self, name)
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)


def _suspect(status: np.ndarray, byte2: np.ndarray) -> np.ndarray:
    """Frames the protocol check could reject: byte 2 = 0xA5 with DER = 1."""
    return (byte2 == CHECK_BYTE) & ((status & DER_BIT) != 0)


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
    chunk: Chunk, first_line: int, file_id: int, fr: FileReport, cols: _Columns, report: ParseReport
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
    suspects = np.flatnonzero(_suspect(status, byte2))
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
            report.reject(fr, first_line + i, category, reason, raw_lines[i])
    return n


def _read_frame_file(path: Path, file_id: int, cols: _Columns, report: ParseReport) -> None:
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


def _categorical(values: np.ndarray) -> pd.Categorical:
    cats = pd.Index(sorted(set(values.tolist())), dtype="str")
    return pd.Categorical(values, categories=cats)


def _file_column(files: list[str], file_id: np.ndarray) -> pd.Categorical:
    """File names as a categorical (a file given twice is one category)."""
    unique = list(dict.fromkeys(files))
    remap = np.array([unique.index(f) for f in files], np.int32)
    codes = remap[file_id] if len(files) else file_id
    return pd.Categorical.from_codes(codes, categories=pd.Index(unique, dtype="str"))


def _finish(cols: _Columns, files: list[str], report: ParseReport, extra: Mapping[str, Any]) -> pd.DataFrame:
    """One table from the parsed columns; reject check-byte frames that break the protocol."""
    sensor = np.concatenate(cols.sensor) if cols.sensor else np.zeros(0, object)
    time_ns = cols.concat("time_ns", np.int64)
    status = cols.concat("status", np.uint8)
    byte2 = cols.concat("byte2", np.uint8)
    file_id = cols.concat("file_id", np.int32)
    line = cols.concat("line", np.int64)
    sensor_cat = _categorical(sensor)
    check = check_byte_mask(sensor_cat.codes, time_ns, byte2)
    broken = check & ((status & DER_BIT) != 0)
    for i in np.flatnonzero(broken).tolist():
        fr = report.files[int(file_id[i])]
        fr.records -= 1
        raw = cols.suspects.get((int(file_id[i]), int(line[i])), b"")
        reason = (
            "byte 2 is the check byte 0xA5 here (no count reaching 165 around it) but DER = 1;"
            " a check-byte frame has DER = 0"
        )
        report.reject(fr, int(line[i]), "protocol", reason, raw)
    keep = ~broken
    bits = decode_status(status[keep])
    frame = pd.DataFrame(
        {
            "time": pd.to_datetime(time_ns[keep], unit="ns").astype("datetime64[ns]"),
            "sensor": sensor_cat[keep].remove_unused_categories(),
            "status": status[keep],
            "byte2": byte2[keep],
            "check": check[keep],
            **bits,
            "file": _file_column(files, file_id[keep]),
            "line": line[keep],
            **{k: np.asarray(v)[keep] for k, v in extra.items()},
        }
    )
    report.check()
    return frame.reset_index(drop=True)


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
    cols = _Columns()
    files = [str(Path(p)) for p in paths]
    for file_id, name in enumerate(files):
        _read_frame_file(Path(name), file_id, cols, report)
    return _finish(cols, files, report, {}), report


# --- CAN count frames --------------------------------------------------------------


@dataclass
class CanFileReport(FileReport):
    """Line accounting for one CAN log, and what its traffic was.

    ``lines_read`` counts text lines (candump, ASC) or CAN objects (BLF).
    Count frames are ``records``; foreign traffic, remote and error frames,
    and ASC header, comment and event lines are ``blank`` (read and set
    aside, not errors); the first three are also counted on their own here.
    """

    format: str = ""
    messages: int = 0  # CAN frames the reader returned
    foreign: int = 0  # frames with ids other than the count ids (extended ids included)
    remote_frames: int = 0
    error_frames: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "format": self.format,
            "messages": self.messages,
            "foreign": self.foreign,
            "remote_frames": self.remote_frames,
            "error_frames": self.error_frames,
        }


_FLAG_EXT, _FLAG_REMOTE, _FLAG_ERROR = 1, 2, 4
# python-can's ASC reader: a classic CAN message or error frame on a numbered channel.
_ASC_MESSAGE_LINE = re.compile(r"\s*\d+\.\d+\s+\d+\s+(?:[0-9A-Fa-f]+x?\s+(?:Rx|Tx)|ErrorFrame)\b", re.I)
_ASC_TRIGGER = re.compile(r"\s*begin\s+triggerblock\s+\w+\s+(?P<when>.+)", re.I)
_ASC_DATE = re.compile(r"\s*date\s+\w+\s+(?P<when>.+)", re.I)
_ASC_RELATIVE = re.compile(r"\s*base\s+\w+\s+timestamps\s+relative", re.I)
_MONTHS = {
    **{m: i for i, m in enumerate(("Jan", "Feb", "Mar", "Apr", "May", "Jun"), 1)},
    **{m: i for i, m in enumerate(("Jul", "Aug", "Sep", "Oct", "Nov", "Dec"), 7)},
    "Mär": 3,
    "Mai": 5,
    "Okt": 10,
    "Dez": 12,
}
_ASC_DATE_FORMATS = ("%m %d %I:%M:%S.%f %p %Y", "%m %d %I:%M:%S %p %Y", "%m %d %H:%M:%S.%f %Y", "%m %d %H:%M:%S %Y")
_BLF_HEADER = struct.Struct("<4sLBBBBBBBBQQLL8H8H")
_EPOCH = dt.datetime(1970, 1, 1)


def asc_wall_clock_ns(when: str) -> int | None:
    """An ASC ``date``/``Begin Triggerblock`` time (``Sun Jun 06 10:15:02.125 2021``
    without its weekday) → ns since 1970 of that wall-clock time, or None.

    The same formats python-can's ASC reader accepts, read as naive wall
    clock: the recording PC's local time, not converted by this machine's zone.
    """
    text = when.strip()
    for name, number in _MONTHS.items():
        text = text.replace(name, f"{number:02d}")
    for fmt in _ASC_DATE_FORMATS:
        try:
            t = dt.datetime.strptime(text, fmt)
        except ValueError:
            continue
        delta = t - _EPOCH
        return (delta.days * 86400 + delta.seconds) * _NS + delta.microseconds * 1000
    return None


@dataclass
class _CanMessages:
    """What the readers returned, one entry per CAN frame (decoded later, vectorized)."""

    ts_us: list[int] = field(default_factory=list)  # µs: since the epoch (candump, BLF) or the ASC start
    base_ns: list[int] = field(default_factory=list)  # ASC wall-clock start, else 0
    line: list[int] = field(default_factory=list)
    can_id: list[int] = field(default_factory=list)
    flags: list[int] = field(default_factory=list)
    dlc: list[int] = field(default_factory=list)
    length: list[int] = field(default_factory=list)
    data: bytearray = field(default_factory=bytearray)  # 8 bytes per frame, zero padded
    text: dict[int, bytes] = field(default_factory=dict)  # by frame index: lines of count-id frames to reject


class _LineFeed:
    """Text lines handed to a python-can reader one at a time, numbered.

    The reader yields each message before it asks for the next line, so the
    feed's ``line_no`` is the line a message came from.  ``skipped_check``
    (ASC): a line that looks like a CAN message but produced neither a
    message nor an error was dropped by the reader; it is rejected, so
    nothing vanishes (python-can's ASC header scan eats the first line after
    the header, for instance).
    """

    def __init__(
        self,
        path: Path,
        fr: CanFileReport,
        report: ParseReport,
        skipped_check: re.Pattern[str] | None = None,
    ) -> None:
        self.fr = fr
        self.report = report
        self.skipped_check = skipped_check
        self.line_no = 0
        self.text = ""
        self.raw = b""
        self.used = 0  # the last line that produced a message or a rejection
        self.base_ns = 0  # ASC: wall-clock start of the measurement
        self.relative = False
        self._lines = self._read(path)

    def _read(self, path: Path) -> Iterator[tuple[int, bytes]]:
        stream, raw, info = open_input(path)
        self.fr.encoding, self.fr.compressed = info.encoding, info.compressed
        line = 0
        try:
            for item in iter_chunks(stream, info, max_line_bytes=_MAX_LINE_BYTES, name=str(path)):
                if isinstance(item, ReadFailure):  # corrupt gzip: the lines before it are kept
                    line += 1
                    self.fr.lines_read += 1
                    self.report.reject(self.fr, line, "corrupt", item.message(line - 1), item.head)
                    continue
                if isinstance(item, OverlongLine):
                    line += 1
                    self.fr.lines_read += 1
                    reason = f"line of {item.length} bytes; a CAN log line is under {MAX_CAN_LINE_CHARS}"
                    self.report.reject(self.fr, line, "too long", reason, item.head)
                    continue
                data = bytes(item.data)
                pieces = data.split(b"\n")
                if pieces[-1] == b"":
                    pieces.pop()
                for piece in pieces:
                    line += 1
                    yield line, piece
            self.fr.bytes_read = raw.tell()
        finally:
            stream.close()
            raw.close()
        self.fr.ends_without_newline = info.ends_without_newline

    def _check_skipped(self) -> None:
        if self.skipped_check is None or self.used == self.line_no or not self.line_no:
            return
        if self.skipped_check.match(self.text):
            self.reject("format", "a CAN message line the ASC reader did not read")

    def reject(self, category: str, reason: str) -> None:
        self.used = self.line_no
        self.report.reject(self.fr, self.line_no, category, reason, self.raw)

    def __iter__(self) -> _LineFeed:
        return self

    def __next__(self) -> str:
        self._check_skipped()
        while True:
            self.line_no, self.raw = next(self._lines)
            self.fr.lines_read += 1
            if len(self.raw) <= MAX_CAN_LINE_CHARS:
                break
            self.reject("too long", f"line of {len(self.raw)} bytes; a CAN log line is under {MAX_CAN_LINE_CHARS}")
        self.text = self.raw.decode("utf-8", errors="replace")
        if self.skipped_check is not None:  # ASC: follow the measurement start
            if _ASC_RELATIVE.match(self.text):
                raise InputError(
                    f"{self.fr.file}: ASC with relative timestamps (time since the previous event) is not supported"
                )
            found = _ASC_TRIGGER.match(self.text) or _ASC_DATE.match(self.text)
            if found:
                when = asc_wall_clock_ns(found.group("when"))
                if when is not None:
                    self.base_ns = when
        return self.text

    def finish(self) -> None:
        self._check_skipped()

    def close(self) -> None:  # python-can closes its file when done
        return


class _ResumedASCReader(can.ASCReader):
    """An ASC reader that continues after a bad line: the header is already read."""

    def _extract_header(self) -> None:
        return


_READER_ERRORS = (ValueError, IndexError, KeyError, TypeError, OverflowError)


def _collect(msgs: _CanMessages, msg: can.Message, line: int, base_ns: int, text: bytes | None) -> None:
    flags = _FLAG_EXT * msg.is_extended_id + _FLAG_REMOTE * msg.is_remote_frame + _FLAG_ERROR * msg.is_error_frame
    data = bytes(msg.data or b"")
    msgs.ts_us.append(round(msg.timestamp * 1e6))
    msgs.base_ns.append(base_ns)
    msgs.line.append(line)
    msgs.can_id.append(msg.arbitration_id)
    msgs.flags.append(flags)
    msgs.dlc.append(msg.dlc)
    msgs.length.append(len(data))
    msgs.data += data[:8].ljust(8, b"\0")
    # Keep the line only for a count-id frame the decoding may reject (bounded by those).
    suspect = len(data) != COUNT_DLC or msg.dlc != COUNT_DLC or (data[1] == CHECK_BYTE and data[0] & DER_BIT)
    if suspect and not flags and NODE_MIN <= msg.arbitration_id - COUNT_ID_BASE <= NODE_MAX:
        msgs.text[len(msgs.line) - 1] = text if text is not None else _candump_text(msg)


def _candump_text(msg: can.Message) -> bytes:
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"{ident}#{bytes(msg.data or b'').hex().upper()}".encode()


def _read_text_can(path: Path, fmt: str, fr: CanFileReport, report: ParseReport, msgs: _CanMessages) -> None:
    feed = _LineFeed(path, fr, report, _ASC_MESSAGE_LINE if fmt == "asc" else None)
    source = cast(TextIO, feed)
    reader: can.io.generic.MessageReader = (
        can.ASCReader(source, relative_timestamp=True) if fmt == "asc" else can.CanutilsLogReader(source)
    )
    what = "an ASC message line" if fmt == "asc" else "a candump line"
    while True:
        try:
            for msg in reader:
                feed.used = feed.line_no
                _collect(msgs, msg, feed.line_no, feed.base_ns, feed.raw)
            break
        except _READER_ERRORS as exc:
            feed.reject("format", f"not {what} ({type(exc).__name__}: {exc})")
            if isinstance(reader, can.ASCReader):
                resumed = _ResumedASCReader(source, relative_timestamp=True)
                resumed.base, resumed._converted_base = reader.base, reader._converted_base
                reader = resumed
            else:
                reader = can.CanutilsLogReader(source)
    feed.finish()


def _blf_start_ns(path: Path) -> int:
    """The BLF header's start time (SYSTEMTIME, read as naive wall clock) in ns."""
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_BLF_HEADER.size)
    finally:
        stream.close()
        raw.close()
    fields = _BLF_HEADER.unpack(head)
    year, month, _, day, hour, minute, second, ms = fields[14:22]
    try:
        delta = dt.datetime(year, month, day, hour, minute, second, ms * 1000) - _EPOCH
    except ValueError:
        return 0
    return (delta.days * 86400 + delta.seconds) * _NS + delta.microseconds * 1000


def _read_blf(path: Path, fr: CanFileReport, msgs: _CanMessages) -> None:
    stream, raw, info = open_input(path)
    fr.encoding, fr.compressed = "binary", info.compressed
    try:
        start_ns = _blf_start_ns(path)
        reader = can.BLFReader(cast(BinaryIO, stream))
        start_us = round(reader.start_timestamp * 1e6)
        for msg in reader:
            fr.lines_read += 1
            _collect(msgs, msg, fr.lines_read, start_ns, None)
            # BLF times: the header's wall clock plus the object's offset from it.
            msgs.ts_us[-1] -= start_us
        fr.bytes_read = path.stat().st_size  # the reader closes the file when done
    except (can.io.blf.BLFParseError, struct.error, zlib.error, EOFError, OSError, *_READER_ERRORS) as exc:
        raise InputError(f"{path}: not a readable BLF file ({type(exc).__name__}: {exc or 'corrupt'})") from None
    finally:
        stream.close()
        raw.close()


def _can_format(path: Path) -> str:
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(4)
    except (OSError, EOFError) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    finally:
        stream.close()
        raw.close()
    if head == b"LOGG":
        return "blf"
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes.pop()
    suffix = suffixes[-1] if suffixes else ""
    formats = {".log": "candump", ".asc": "asc", ".blf": "blf"}
    if suffix not in formats:
        raise InputError(
            f"{path}: unknown CAN log format '{suffix}': expected .log (candump), .asc or .blf (optionally .gz)"
        )
    if formats[suffix] == "blf":
        raise InputError(f"{path}: not a BLF file (no 'LOGG' signature)")
    return formats[suffix]


def default_sensor_name(node: int) -> str:
    """The sensor id a CAN node gets when no name is given: node 7 → ``AC07``."""
    return f"AC{node:02d}"


def parse_can(
    paths: Iterable[Path | str], *, sensor_names: Mapping[int, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Read recorded CAN traffic (candump .log, .asc, .blf; plain or gzip) into a count-frame table.

    The table has the columns of :func:`parse_frames` plus ``total``
    (uint16, cumulative axles, wraps), ``seq`` (uint8, wraps) and ``can_id``;
    ``line`` is the text line (candump, ASC) or the frame's position in the
    file (BLF).  Node n's sensor is ``sensor_names[n]``, else
    :func:`default_sensor_name`.  A file that cannot be read at all raises
    :class:`parsers.sources.InputError`.
    """
    names = dict(sensor_names or {})
    report = ParseReport()
    cols = _Columns()
    files = [str(Path(p)) for p in paths]
    for file_id, name in enumerate(files):
        path = Path(name)
        fmt = _can_format(path)
        fr = CanFileReport(file=name, format=fmt)
        report.files.append(fr)
        msgs = _CanMessages()
        if fmt == "blf":
            _read_blf(path, fr, msgs)
        else:
            _read_text_can(path, fmt, fr, report, msgs)
        _decode_can(msgs, file_id, fr, report, cols, names)
    extra = {
        "total": cols.concat("total", np.uint16),
        "seq": cols.concat("seq", np.uint8),
        "can_id": cols.concat("can_id", np.uint16),
    }
    return _finish(cols, files, report, extra), report


def _decode_can(
    msgs: _CanMessages,
    file_id: int,
    fr: CanFileReport,
    report: ParseReport,
    cols: _Columns,
    names: Mapping[int, str],
) -> None:
    """Sort one file's frames into count frames, foreign traffic and rejections (vectorized)."""
    can_id = np.array(msgs.can_id, np.int64)
    flags = np.array(msgs.flags, np.int64)
    dlc = np.array(msgs.dlc, np.int64)
    length = np.array(msgs.length, np.int64)
    line = np.array(msgs.line, np.int64)
    data = np.frombuffer(bytes(msgs.data), np.uint8).reshape(-1, 8)
    fr.messages = len(can_id)
    error = (flags & _FLAG_ERROR) != 0
    remote = ((flags & _FLAG_REMOTE) != 0) & ~error
    node = can_id - COUNT_ID_BASE
    count_id = ~error & ~remote & ((flags & _FLAG_EXT) == 0) & (node >= NODE_MIN) & (node <= NODE_MAX)
    foreign = ~error & ~remote & ~count_id
    bad_dlc = count_id & ((length != COUNT_DLC) | (dlc != COUNT_DLC))
    good = count_id & ~bad_dlc
    fr.error_frames = int(error.sum())
    fr.remote_frames = int(remote.sum())
    fr.foreign = int(foreign.sum())
    for i in np.flatnonzero(bad_dlc).tolist():
        reason = (
            f"count frame 0x{can_id[i]:03X}: expected DLC {COUNT_DLC}, found DLC {dlc[i]} with {length[i]} data bytes"
        )
        report.reject(fr, int(line[i]), "dlc", reason, msgs.text.get(i, b""))
    g = np.flatnonzero(good)
    time_ns = np.array(msgs.base_ns, np.int64)[g] + np.array(msgs.ts_us, np.int64)[g] * 1000
    d = data[g]
    nodes = node[g]
    lut = np.array([names.get(k, default_sensor_name(k)) for k in range(NODE_MAX + 1)], dtype=object)
    status, byte2 = d[:, 0], d[:, 1]
    cols.add(
        time_ns,
        lut[nodes],
        status,
        byte2,
        file_id,
        line[g],
        total=d[:, 2].astype(np.uint16) | (d[:, 3].astype(np.uint16) << 8),
        seq=d[:, 4],
        can_id=can_id[g].astype(np.uint16),
    )
    for j in np.flatnonzero(_suspect(status, byte2)).tolist():
        cols.suspects[(file_id, int(line[g[j]]))] = msgs.text.get(int(g[j]), b"")
    fr.records += len(g)
    # Every line is a count frame, a rejection, or set aside (foreign, remote,
    # error frames, ASC header and event lines, blank lines).
    fr.blank = fr.lines_read - fr.records - fr.rejected
