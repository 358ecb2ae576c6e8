"""Recorded CAN traffic → the frame table, every frame in it by kind.

Seed 000's counts travel to the control centre over CAN.  Logs are read
with python-can's own readers: candump ``.log``, Vector ``.asc`` and
``.blf``, PEAK ``.trc`` (versions 1.0, 1.1, 1.3, 2.0, 2.1; see
:mod:`parsers.frames.trc`), plain or gzip.  Standard id ``0x180 + n`` (n = 1..127)
with DLC 5 is node n's count frame:
``[status, count or 0xA5, total lo, total hi, seq]`` (``docs/frames.md``).

Every CAN frame becomes a row, with its ``kind``: ``count``, ``foreign``
(other ids, extended ids), ``remote`` (RTR) or ``error``.  Only count rows
carry a sensor and status bits; the other kinds keep their id, DLC and
data.  So ``records`` counts CAN frames of every kind, and the
:class:`CanFileReport` counts them by kind; ``blank`` is what is not a
frame (headers, comments, bus events).  A count-id frame with another DLC,
a frame whose time or id is out of range, and a line the reader cannot
read are rejected with file, line and reason.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
import re
import struct
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, TextIO, cast

import can
import numpy as np
import pandas as pd

from parsers.frames.can_head import can_format_of_head
from parsers.frames.table import CHECK_BYTE, DER_BIT, FRAME_COLUMNS, FrameColumns, finish_table, suspect_mask
from parsers.frames.trc import ResumedTRCReader, check_trc_header, classify_unread, version_name
from parsers.report import FileReport, ParseReport
from parsers.sources import InputError, OverlongLine, ReadFailure, iter_chunks, open_input
from parsers.units import NS

COUNT_ID_BASE = 0x180  # standard id 0x180 + node = count frame of sensor node 1..127
NODE_MIN, NODE_MAX = 1, 127
COUNT_DLC = 5  # [status, count or 0xA5, total lo, total hi, seq]
CAN_ID_MAX = 0x1FFFFFFF  # 29 bits
FRAME_KINDS = ("count", "foreign", "remote", "error")
CAN_COLUMNS = (*FRAME_COLUMNS, "total", "seq", "can_id", "kind", "extended", "dlc", "data")

MAX_CAN_LINE_CHARS = 1024  # an ASC CAN FD line with 64 data bytes is about 400
_MAX_LINE_BYTES = 64 << 10  # lines beyond this are never held whole in memory
_EPOCH = dt.datetime(1970, 1, 1)
# Frame times outside these years are not times (and would overflow 64-bit nanoseconds).
_TIME_MIN_NS = (dt.datetime(1900, 1, 1) - _EPOCH) // dt.timedelta(microseconds=1) * 1000
_TIME_MAX_NS = (dt.datetime(2200, 1, 1) - _EPOCH) // dt.timedelta(microseconds=1) * 1000
_KIND_COUNT, _KIND_FOREIGN, _KIND_REMOTE, _KIND_ERROR = range(4)


@dataclass
class CanFileReport(FileReport):
    """Line accounting for one CAN log, and its frames by kind.

    ``lines_read`` counts text lines (candump, ASC, TRC) or CAN objects
    (BLF).  ``records`` are CAN frames of every kind, each a row of the
    table: ``count_frames + foreign + remote_frames + error_frames``.
    ``blank`` are lines that hold no frame: headers, comments, bus events.
    """

    format: str = ""
    messages: int = 0  # CAN frames the reader returned (rows and rejected frames)
    foreign: int = 0  # frames with ids other than the count ids (extended ids included)
    remote_frames: int = 0
    error_frames: int = 0

    @property
    def count_frames(self) -> int:
        """Count frames kept as rows (a protocol rejection leaves ``records``, so it leaves here too)."""
        return self.records - self.foreign - self.remote_frames - self.error_frames

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "format": self.format,
            "messages": self.messages,
            "count_frames": self.count_frames,
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
# What python-can's ASC header scan reads past: date, base and // comment lines.
_ASC_HEADER_LINE = re.compile(r"\s*(?:date\s+\w+\s+.+|base\s+(?:hex|dec)\b.*|//.*)$", re.I)
# candump: an id with SocketCAN's CAN_ERR_FLAG is an error frame, whatever else its bits say
# (python-can only calls it one when the bus-error bit is set too).
_CANDUMP_ID = re.compile(r"\s*\(\S*\)\s+\S+\s+(?P<id>[0-9A-Fa-f]{8})#")
_CAN_ERR_FLAG = 0x20000000
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


def _wall_ns(t: dt.datetime) -> int:
    delta = t - _EPOCH
    return (delta.days * 86400 + delta.seconds) * NS + delta.microseconds * 1000


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
        return _wall_ns(t)
    return None


@dataclass
class _CanMessages:
    """What the readers returned, one entry per CAN frame (decoded later, vectorized)."""

    time_ns: list[int] = field(default_factory=list)
    line: list[int] = field(default_factory=list)
    can_id: list[int] = field(default_factory=list)
    flags: list[int] = field(default_factory=list)
    dlc: list[int] = field(default_factory=list)
    length: list[int] = field(default_factory=list)
    data: bytearray = field(default_factory=bytearray)  # 8 bytes per frame, zero padded
    text: dict[int, bytes] = field(default_factory=dict)  # by frame index: lines of count-id frames to reject


def _frame_problem(msg: can.Message, time_ns: int | None) -> tuple[str, str] | None:
    """Why a frame the reader returned cannot be a row: (category, reason) naming the field, or None."""
    if time_ns is None or not _TIME_MIN_NS <= time_ns < _TIME_MAX_NS:
        return "time", f"time: timestamp {msg.timestamp!r} s is not a time in 1900-2199"
    if not 0 <= msg.arbitration_id <= CAN_ID_MAX:
        return "id", f"id: 0x{msg.arbitration_id:X} is wider than 29 bits"
    if not 0 <= msg.dlc <= 64:
        return "dlc", f"dlc: {msg.dlc} is not a CAN DLC"
    return None


def _collect(
    msgs: _CanMessages, msg: can.Message, line: int, base_ns: int, text: bytes | None, *, error: bool = False
) -> tuple[str, str] | None:
    """Add one frame; or say why it cannot be added (the caller rejects it)."""
    stamp = msg.timestamp
    time_ns = base_ns + round(stamp * 1e6) * 1000 if math.isfinite(stamp) and abs(stamp) < 1e13 else None
    problem = _frame_problem(msg, time_ns)
    if problem is not None:
        return problem
    is_error = msg.is_error_frame or error
    flags = _FLAG_EXT * msg.is_extended_id + _FLAG_REMOTE * msg.is_remote_frame + _FLAG_ERROR * is_error
    data = bytes(msg.data or b"")
    msgs.time_ns.append(cast(int, time_ns))
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
    return None


def _candump_text(msg: can.Message) -> bytes:
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"{ident}#{bytes(msg.data or b'').hex().upper()}".encode()


class _LineFeed:
    """Text lines handed to a python-can reader one at a time, numbered.

    The reader yields each message before it asks for the next line, so the
    feed's ``line_no`` is the line a message came from.  ``on_unread`` is
    called for a line that produced neither a message nor a rejection (the
    reader dropped it): the format decides whether that was a header or
    comment (blank), an error frame, or a line to reject, so nothing
    vanishes (python-can's ASC header scan eats the first line after the
    header; its TRC reader drops error frames and short lines).
    """

    def __init__(
        self, fr: CanFileReport, report: ParseReport, on_unread: Callable[[_LineFeed], None] | None = None
    ) -> None:
        self.fr = fr
        self.report = report
        self.on_unread = on_unread
        self.asc = fr.format == "asc"
        self.candump = fr.format == "candump"
        self.line_no = 0
        self.text = ""
        self.raw = b""
        self.used = 0  # the last line that produced a message or a rejection
        self.base_ns = 0  # ASC: wall-clock start of the measurement
        self.lines: Iterator[tuple[int, bytes]] = iter(())  # (number, line without its end), set by the reader

    def _check_unread(self) -> None:
        if self.on_unread is None or self.used == self.line_no or not self.line_no:
            return
        self.on_unread(self)

    def reject(self, category: str, reason: str) -> None:
        self.used = self.line_no
        self.report.reject(self.fr, self.line_no, category, reason, self.raw)

    def __iter__(self) -> _LineFeed:
        return self

    def __next__(self) -> str:
        self._check_unread()
        while True:
            self.line_no, raw = next(self.lines)
            self.raw = raw.removesuffix(b"\r")  # a CRLF line's CR is its line end, not its text
            self.fr.lines_read += 1
            if len(self.raw) <= MAX_CAN_LINE_CHARS:
                break
            self.reject("too long", f"line of {len(self.raw)} bytes; a CAN log line is under {MAX_CAN_LINE_CHARS}")
        self.text = self.raw.decode("utf-8", errors="replace").rstrip("\r")
        if self.candump and self.text.lstrip().startswith("#"):
            return ""  # a comment (an annotated capture): python-can's candump reader skips empty lines, blank here
        if self.asc:  # follow the measurement start
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
        self._check_unread()

    def close(self) -> None:  # python-can closes its file when done
        return


class _ResumedASCReader(can.ASCReader):
    """An ASC reader that continues after a bad line: the header is already read."""

    def _extract_header(self) -> None:
        return


_READER_ERRORS = (ValueError, IndexError, KeyError, TypeError, OverflowError)
_WHAT = {"asc": "an ASC message line", "candump": "a candump line", "trc": "a TRC message line"}


@contextmanager
def _quiet_trc_reader() -> Iterator[None]:
    """python-can's TRC reader logs a warning per line it drops; we reject those lines ourselves."""
    log = logging.getLogger("can.io.trc")
    was = log.disabled
    log.disabled = True
    try:
        yield
    finally:
        log.disabled = was


def _new_reader(fmt: str, source: TextIO, previous: can.io.generic.MessageReader | None) -> Any:
    if fmt == "asc":
        if previous is None:
            return can.ASCReader(source, relative_timestamp=True)
        resumed = _ResumedASCReader(source, relative_timestamp=True)
        resumed.base, resumed._converted_base = previous.base, previous._converted_base  # type: ignore[attr-defined]
        return resumed
    if fmt == "trc":
        if previous is None:
            return can.TRCReader(source)
        return ResumedTRCReader(source, cast(can.TRCReader, previous))
    return can.CanutilsLogReader(source)


def _file_lines(path: Path, fr: CanFileReport, report: ParseReport) -> Iterator[tuple[int, bytes]]:
    """A CAN log's lines (number, line without its end); overlong and unreadable ones rejected here."""
    stream, raw, info = open_input(path)
    fr.encoding, fr.compressed = info.encoding, info.compressed
    line = 0
    try:
        for item in iter_chunks(stream, info, max_line_bytes=_MAX_LINE_BYTES, name=str(path)):
            if isinstance(item, OverlongLine):
                line += 1
                fr.lines_read += 1
                if isinstance(item, ReadFailure):
                    report.reject(fr, line, "corrupt", item.message(line - 1), item.head)
                    continue
                reason = f"line of {item.length} bytes; a CAN log line is under {MAX_CAN_LINE_CHARS}"
                report.reject(fr, line, "too long", reason, item.head)
                continue
            data = bytes(item.data)
            pieces = data.split(b"\n")
            if pieces[-1] == b"":
                pieces.pop()
            for piece in pieces:
                line += 1
                yield line, piece
        fr.bytes_read = raw.tell()
    finally:
        stream.close()
        raw.close()
    fr.ends_without_newline = info.ends_without_newline


class TextCanReader:
    """A text CAN log (candump, ASC, TRC) → CAN frames through python-can's reader, line by line.

    :meth:`read` takes the lines at hand, all of a file or a block of a growing
    one: a reader that ran out of lines is followed by a resumed one (the
    header's state carried, as after a line the reader failed on), so the
    frames are those of one read of the whole file.  Frames collect in
    :attr:`msgs` (:meth:`take` hands them over).
    """

    def __init__(self, fmt: str, fr: CanFileReport, report: ParseReport, msgs: _CanMessages | None = None) -> None:
        self.fmt = fmt
        self.fr = fr
        self.msgs = msgs if msgs is not None else _CanMessages()
        self.reader: Any = None
        self._failed_at = -1
        on_unread = {"asc": self._unread_asc, "trc": self._unread_trc}.get(fmt)
        self.feed = _LineFeed(fr, report, on_unread)

    def _add(self, msg: can.Message, *, error: bool = False) -> None:
        feed = self.feed
        feed.used = feed.line_no
        problem = _collect(self.msgs, msg, feed.line_no, feed.base_ns, feed.raw, error=error)
        if problem is not None:
            feed.reject(*problem)

    def _unread_asc(self, f: _LineFeed) -> None:
        if _ASC_MESSAGE_LINE.match(f.text):
            f.reject("format", "a CAN message line the ASC reader did not read")

    def _unread_trc(self, f: _LineFeed) -> None:
        what = classify_unread(self.reader, f.text)
        if what.kind == "error":
            start = self.reader._start_time or 0.0
            self._add(can.Message(timestamp=what.offset_ms / 1000.0 + start, is_error_frame=True), error=True)
        elif what.kind == "reject":
            f.reject("format", what.reason)

    def read(self, lines: Iterator[tuple[int, bytes]]) -> None:
        """Read ``lines`` (number, line without its end) to their end; InputError if the reader cannot go on."""
        feed = self.feed
        feed.lines = lines
        source = cast(TextIO, feed)
        fmt = self.fmt
        with _quiet_trc_reader():
            while True:
                try:
                    self.reader = _new_reader(fmt, source, self.reader)
                    for msg in self.reader:
                        self._add(msg, error=fmt == "candump" and _candump_error_id(feed.text))
                    return
                except _READER_ERRORS as exc:
                    if feed.line_no == self._failed_at:  # no line consumed since the last failure: it cannot go on
                        raise InputError(
                            f"{self.fr.file}: {_WHAT[fmt]} reader failed at line {feed.line_no} ({exc})"
                        ) from None
                    self._failed_at = feed.line_no
                    what = (
                        _WHAT[fmt] if fmt != "trc" else f"a TRC {version_name(self.reader.file_version)} message line"
                    )
                    feed.reject("format", f"not {what} ({type(exc).__name__}: {exc})")

    def finish(self) -> None:
        """The file ends: its last line is accounted for."""
        self.feed.finish()

    def take(self) -> _CanMessages:
        """The frames read since the last take."""
        msgs, self.msgs = self.msgs, _CanMessages()
        return msgs


def header_complete(fmt: str, lines: Iterable[bytes]) -> bool:
    """Whether ``lines``, a CAN log's first lines, hold its whole header (a line past it): python-can
    reads the header once, so a growing log's first reader waits for it."""
    if fmt == "trc":
        return any(not line.strip().startswith(b";") for line in lines)
    if fmt == "asc":
        return any(not _ASC_HEADER_LINE.match(line.decode("utf-8", errors="replace")) for line in lines)
    return True


def _read_text_can(path: Path, fmt: str, fr: CanFileReport, report: ParseReport, msgs: _CanMessages) -> None:
    reader = TextCanReader(fmt, fr, report, msgs)
    reader.read(_file_lines(path, fr, report))
    reader.finish()


def _candump_error_id(text: str) -> bool:
    found = _CANDUMP_ID.match(text)
    return found is not None and int(found.group("id"), 16) & _CAN_ERR_FLAG != 0


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
        return _wall_ns(dt.datetime(year, month, day, hour, minute, second, ms * 1000))
    except ValueError:
        return 0


def _read_blf(path: Path, fr: CanFileReport, report: ParseReport, msgs: _CanMessages) -> None:
    stream, raw, info = open_input(path)
    fr.encoding, fr.compressed = "binary", info.compressed
    try:
        start_ns = _blf_start_ns(path)
        reader = can.BLFReader(cast(BinaryIO, stream))
        start_s = reader.start_timestamp
        for msg in reader:
            fr.lines_read += 1
            # BLF times: the header's wall clock plus the object's offset from it.
            msg.timestamp -= start_s
            problem = _collect(msgs, msg, fr.lines_read, start_ns, None)
            if problem is not None:
                report.reject(fr, fr.lines_read, *problem, _candump_text(msg))
        fr.bytes_read = path.stat().st_size  # the reader closes the file when done
    except (can.io.blf.BLFParseError, struct.error, zlib.error, EOFError, OSError, *_READER_ERRORS) as exc:
        raise InputError(f"{path}: not a readable BLF file ({type(exc).__name__}: {exc or 'corrupt'})") from None
    finally:
        stream.close()
        raw.close()


_FORMATS = {".log": "candump", ".asc": "asc", ".blf": "blf", ".trc": "trc"}
_FORMAT_HEAD_BYTES = 64 * 1024  # a long run of comments or an ASC header before the first frame


def can_log_format(path: Path) -> str | None:
    """'candump', 'asc', 'blf' or 'trc' by name (``.gz`` aside; BLF also by its signature), else None."""
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes.pop()
    return _FORMATS.get(suffixes[-1] if suffixes else "")


def _can_format(path: Path) -> str:
    """The file's format by its content (a candump saved as ``.txt``, an ASC export as ``.log``); by its name
    only when the content is no CAN log at all (an empty file)."""
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_FORMAT_HEAD_BYTES)
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    finally:
        stream.close()
        raw.close()
    by_content = can_format_of_head(head)
    if by_content is not None:
        if by_content == "trc":
            check_trc_header(path)
        return by_content
    fmt = can_log_format(path)
    if fmt is None:
        suffix = path.suffix.lower()
        raise InputError(
            f"{path}: unknown CAN log format '{suffix}': expected .log (candump), .asc, .blf or .trc (optionally .gz)"
        )
    if fmt == "blf":
        raise InputError(f"{path}: not a BLF file (no 'LOGG' signature)")
    if fmt == "trc":
        check_trc_header(path)
    return fmt


def default_sensor_name(node: int) -> str:
    """The sensor id a CAN node gets when no name is given: node 7 → ``AC07``."""
    return f"AC{node:02d}"


def parse_can(
    paths: Iterable[Path | str], *, sensor_names: Mapping[int, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Read recorded CAN traffic (candump .log, .asc, .blf, .trc; plain or gzip) into a frame table.

    The table has the columns of ``parse_frames`` plus ``total`` (uint16,
    cumulative axles, wraps), ``seq`` (uint8, wraps), ``can_id`` (uint32),
    ``kind`` (category: count, foreign, remote, error), ``extended`` (29-bit
    id), ``dlc`` and ``data`` (the payload in hex).  One row per CAN frame;
    only count rows have a ``sensor`` (node n → ``sensor_names[n]``, else
    :func:`default_sensor_name`) and meaningful status, count, total and seq
    (0 elsewhere).  ``line`` is the text line (candump, ASC, TRC) or the
    frame's position in the file (BLF).  A file that cannot be read at all
    raises :class:`parsers.sources.InputError`.
    """
    names = dict(sensor_names or {})
    report = ParseReport()
    cols = FrameColumns()
    files = [str(Path(p)) for p in paths]
    for file_id, name in enumerate(files):
        path = Path(name)
        fmt = _can_format(path)
        fr = CanFileReport(file=name, format=fmt)
        report.files.append(fr)
        msgs = _CanMessages()
        if fmt == "blf":
            _read_blf(path, fr, report, msgs)
        else:
            _read_text_can(path, fmt, fr, report, msgs)
        _decode_can(msgs, file_id, fr, report, cols, names)
    kind = cols.concat("kind", np.int8)
    extra = {
        "total": cols.concat("total", np.uint16),
        "seq": cols.concat("seq", np.uint8),
        "can_id": cols.concat("can_id", np.uint32),
        "kind": pd.Categorical.from_codes(kind, categories=pd.Index(FRAME_KINDS, dtype="str")),
        "extended": cols.concat("extended", bool),
        "dlc": cols.concat("dlc", np.uint8),
        "data": cols.concat("data", object),
    }
    return finish_table(cols, files, report, extra), report


def decode_messages(
    msgs: _CanMessages, fr: CanFileReport, report: ParseReport, sensor_names: Mapping[int, str] | None = None
) -> FrameColumns:
    """Frames a :class:`TextCanReader` took (a block of a growing log) → frame-table columns, as
    :func:`parse_can` makes them (file id 0); bad count frames rejected, the file's counts added to."""
    cols = FrameColumns()
    _decode_can(msgs, 0, fr, report, cols, dict(sensor_names or {}))
    return cols


def count_frames_only(frames: pd.DataFrame) -> pd.DataFrame:
    """The count frames of a frame table (a text-frame table is all count frames)."""
    if "kind" not in frames.columns:
        return frames
    return frames[frames["kind"] == "count"]


_HEX_PAIRS = np.array([f"{b:02X}" for b in range(256)], dtype="S2").view(np.uint8).reshape(256, 2)


def _hex_payloads(data: np.ndarray, length: np.ndarray) -> np.ndarray:
    """(n, 8) payload bytes and their lengths → hex strings, without a Python loop per frame."""
    if len(data) == 0:
        return np.zeros(0, object)
    chars = _HEX_PAIRS[data].reshape(len(data), 16)
    chars[np.arange(16)[None, :] >= 2 * np.minimum(length, 8)[:, None]] = ord(" ")
    text = np.char.rstrip(chars.copy().view("S16").ravel()).astype("U16")
    return text.astype(object)


def _decode_can(
    msgs: _CanMessages,
    file_id: int,
    fr: CanFileReport,
    report: ParseReport,
    cols: FrameColumns,
    names: Mapping[int, str],
) -> None:
    """Sort one file's frames by kind, reject bad count frames, add the rest as rows (vectorized).

    Called once per file, or once per block of a growing file: the counts add up.
    """
    can_id = np.array(msgs.can_id, np.int64)
    flags = np.array(msgs.flags, np.int64)
    dlc = np.array(msgs.dlc, np.int64)
    length = np.array(msgs.length, np.int64)
    line = np.array(msgs.line, np.int64)
    data = np.frombuffer(bytes(msgs.data), np.uint8).reshape(-1, 8)
    fr.messages += len(can_id)
    error = (flags & _FLAG_ERROR) != 0
    remote = ((flags & _FLAG_REMOTE) != 0) & ~error
    node = can_id - COUNT_ID_BASE
    count_id = ~error & ~remote & ((flags & _FLAG_EXT) == 0) & (node >= NODE_MIN) & (node <= NODE_MAX)
    foreign = ~error & ~remote & ~count_id
    bad_dlc = count_id & ((length != COUNT_DLC) | (dlc != COUNT_DLC))
    for i in np.flatnonzero(bad_dlc).tolist():
        reason = (
            f"count frame 0x{can_id[i]:03X}: expected DLC {COUNT_DLC}, found DLC {dlc[i]} with {length[i]} data bytes"
        )
        report.reject(fr, int(line[i]), "dlc", reason, msgs.text.get(i, b""))
    fr.error_frames += int(error.sum())
    fr.remote_frames += int(remote.sum())
    fr.foreign += int(foreign.sum())
    rows = np.flatnonzero(~bad_dlc)
    is_count = count_id[rows]
    kind = np.select(
        [is_count, foreign[rows], remote[rows]], [_KIND_COUNT, _KIND_FOREIGN, _KIND_REMOTE], _KIND_ERROR
    ).astype(np.int8)
    d = data[rows]
    lut = np.array([names.get(k, default_sensor_name(k)) for k in range(NODE_MAX + 1)], dtype=object)
    sensor = lut[np.clip(node[rows], 0, NODE_MAX)]
    sensor[~is_count] = None
    # Status, count, total and seq mean something only in a count frame.
    status = np.where(is_count, d[:, 0], 0).astype(np.uint8)
    byte2 = np.where(is_count, d[:, 1], 0).astype(np.uint8)
    total = np.where(is_count, d[:, 2].astype(np.uint16) | (d[:, 3].astype(np.uint16) << 8), 0)
    cols.add(
        np.array(msgs.time_ns, np.int64)[rows],
        sensor,
        status,
        byte2,
        file_id,
        line[rows],
        total=total.astype(np.uint16),
        seq=np.where(is_count, d[:, 4], 0).astype(np.uint8),
        can_id=can_id[rows].astype(np.uint32),
        kind=kind,
        extended=(flags[rows] & _FLAG_EXT) != 0,
        dlc=dlc[rows].astype(np.uint8),
        data=_hex_payloads(d, np.where(remote[rows] | error[rows], 0, length[rows])),
    )
    for j in np.flatnonzero(suspect_mask(status, byte2)).tolist():
        cols.suspects[(file_id, int(line[rows[j]]))] = msgs.text.get(int(rows[j]), b"")
    fr.records += len(rows)
    # Every line is a frame (a row), a rejection, or holds no frame (headers, comments, bus events).
    fr.blank = fr.lines_read - fr.records - fr.rejected
