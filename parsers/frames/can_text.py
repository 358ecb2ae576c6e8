"""Text CAN logs (candump, ASC, TRC) → CAN frames through python-can's readers, line by line.

A line feed numbers the lines a reader takes; :class:`TextCanReader` resumes
after a line the reader failed on and across the blocks of a growing log.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO, cast

import can

from parsers.frames.can_clock import asc_wall_clock_ns
from parsers.frames.can_messages import READER_ERRORS, CanMessages, collect_frame
from parsers.frames.can_report import CanFileReport
from parsers.frames.trc import ResumedTRCReader, classify_unread, version_name
from parsers.report import ParseReport
from parsers.sources import InputError, OverlongLine, ReadFailure, iter_chunks, open_input

MAX_CAN_LINE_CHARS = 1024  # an ASC CAN FD line with 64 data bytes is about 400
_MAX_LINE_BYTES = 64 << 10  # lines beyond this are never held whole in memory
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

    def __init__(self, fmt: str, fr: CanFileReport, report: ParseReport, msgs: CanMessages | None = None) -> None:
        self.fmt = fmt
        self.fr = fr
        self.msgs = msgs if msgs is not None else CanMessages()
        self.reader: Any = None
        self._failed_at = -1
        on_unread = {"asc": self._unread_asc, "trc": self._unread_trc}.get(fmt)
        self.feed = _LineFeed(fr, report, on_unread)

    def _add(self, msg: can.Message, *, error: bool = False) -> None:
        feed = self.feed
        feed.used = feed.line_no
        problem = collect_frame(self.msgs, msg, feed.line_no, feed.base_ns, feed.raw, error=error)
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
                except READER_ERRORS as exc:
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

    def take(self) -> CanMessages:
        """The frames read since the last take."""
        msgs, self.msgs = self.msgs, CanMessages()
        return msgs


def header_complete(fmt: str, lines: Iterable[bytes]) -> bool:
    """Whether ``lines``, a CAN log's first lines, hold its whole header (a line past it): python-can
    reads the header once, so a growing log's first reader waits for it."""
    if fmt == "trc":
        return any(not line.strip().startswith(b";") for line in lines)
    if fmt == "asc":
        return any(not _ASC_HEADER_LINE.match(line.decode("utf-8", errors="replace")) for line in lines)
    return True


def read_text_can(path: Path, fmt: str, fr: CanFileReport, report: ParseReport, msgs: CanMessages) -> None:
    reader = TextCanReader(fmt, fr, report, msgs)
    reader.read(_file_lines(path, fr, report))
    reader.finish()


def _candump_error_id(text: str) -> bool:
    found = _CANDUMP_ID.match(text)
    return found is not None and int(found.group("id"), 16) & _CAN_ERR_FLAG != 0
