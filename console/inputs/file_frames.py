"""A followed CAN log or sensor frame log's lines → :class:`~console.inputs.base.FrameRows`, as the batch reads them.

CAN text logs (candump ``-l``, Vector ASC, PEAK TRC) are read by python-can's
readers through :class:`parsers.frames.can_text.TextCanReader`, a block of lines at
a time, and decoded by the batch decoder (:func:`parsers.frames.can_decode.decode_messages`):
the same frames, rejections and counts by kind as ``parse_can`` on the whole
file.  Only count frames go on (other ids, remote and error frames are
counted in the file's report).  The CAN format is told by content (the
first record line), not by the file name.

ASC and TRC logs start with a header python-can reads once: their first
reader waits until a line past the header is there.  A log followed from
its end has its header read from the file's head, which is not delivered.

Sensor frame logs (``2021-06-06T10:15:02.125 AC07 4A05``) are read by the
batch's vectorized chunk reader (:func:`parsers.frames.sensor.read_frame_lines`).
"""

from __future__ import annotations

import re
import time

import numpy as np

from console.inputs.base import FrameRows
from parsers.frames.can_decode import decode_messages
from parsers.frames.can_report import CanFileReport
from parsers.frames.can_text import TextCanReader, header_complete
from parsers.frames.sensor import read_frame_lines
from parsers.frames.table import FrameColumns
from parsers.frames.trc import check_trc_head
from parsers.report import FileReport, ParseReport
from parsers.sources import InputError

_CANDUMP_LINE = re.compile(rb"\s*\(")
_ASC_MESSAGE = re.compile(rb"\s*\d+\.\d+\s+\d+\s+(?:[0-9A-Fa-f]+x?\s+(?:Rx|Tx)|ErrorFrame)\b", re.I)
_KIND_COUNT = 0  # parsers.frames.can_decode: the "kind" codes, count frames first


def can_format(first_line: bytes) -> str:
    """``candump``, ``trc`` or ``asc`` from a CAN log's first record line (classified ``can``)."""
    text = first_line.lstrip()
    if _CANDUMP_LINE.match(text):
        return "candump"
    if text.startswith(b";"):
        return "trc"
    return "asc"


def _split(first_line: int, data: bytes) -> list[tuple[int, bytes]]:
    return [(first_line + k, raw) for k, raw in enumerate(data.split(b"\n")[:-1])]


def _rows(cols: FrameColumns, source: str, label: str, kind: str, count_only: bool) -> FrameRows | None:
    if not cols.line:
        return None
    keep = slice(None)
    if count_only:
        keep = np.concatenate(cols.extra["kind"]) == _KIND_COUNT
    extra = {k: np.concatenate(cols.extra[k])[keep] for k in ("total", "seq", "can_id") if k in cols.extra}
    line = np.concatenate(cols.line)[keep]
    if not len(line):
        return None
    return FrameRows(
        source,
        label,
        kind,
        np.concatenate(cols.time_ns)[keep],
        np.concatenate(cols.sensor)[keep],
        np.concatenate(cols.status)[keep],
        np.concatenate(cols.byte2)[keep],
        line,
        time.monotonic(),
        total=extra.get("total"),
        seq=extra.get("seq"),
        can_id=extra.get("can_id"),
        text={ln: raw for (_, ln), raw in cols.suspects.items()},
    )


class CanLines:
    """One CAN text log's lines → count frames (one per followed file: a rotation starts a new one)."""

    def __init__(self, source: str, fmt: str, fr: CanFileReport, report: ParseReport) -> None:
        self.source, self.fmt, self.fr, self.report = source, fmt, fr, report
        self.reader = TextCanReader(fmt, fr, report)
        self._held: list[tuple[int, bytes]] = []  # the first lines, until the header is whole
        self.started = fmt == "candump"
        self.failed = ""

    def skip_header(self, head_lines: list[tuple[int, bytes]]) -> None:
        """A log followed from its end: read its header from the head (counting nothing), frames after it."""
        if self.fmt == "candump":
            return
        if self.fmt == "trc":
            try:
                check_trc_head(b"\n".join(raw for _, raw in head_lines) + b"\n", self.fr.file)
            except InputError as exc:
                self.failed = str(exc)
                return
        header = []
        for number, raw in head_lines:
            is_header = raw.strip().startswith(b";") if self.fmt == "trc" else not _ASC_MESSAGE.match(raw)
            if not is_header:
                break
            header.append((number, raw))
        fr, report = self.reader.feed.fr, self.reader.feed.report
        self.reader.feed.fr, self.reader.feed.report = CanFileReport(fr.file, format=fr.format), ParseReport()
        try:
            self.reader.read(iter(header))
        except InputError as exc:
            self.failed = str(exc)
        self.reader.feed.used = self.reader.feed.line_no
        self.reader.feed.fr, self.reader.feed.report = fr, report
        self.reader.take()
        self.started = True

    def add(self, first_line: int, data: bytes, final: bool = False) -> FrameRows | None:
        if self.failed:
            return None
        lines = _split(first_line, data)
        if not self.started:
            self._held += lines
            if not final and not header_complete(self.fmt, (raw for _, raw in self._held)):
                return None
            lines, self._held, self.started = self._held, [], True
            if self.fmt == "trc":
                try:
                    check_trc_head(b"\n".join(raw for _, raw in lines) + b"\n", self.fr.file)
                except InputError as exc:
                    self.failed = str(exc)
                    return None
        try:
            self.reader.read(iter(lines))
        except InputError as exc:
            self.failed = str(exc)
        if final:
            self.reader.finish()
        cols = decode_messages(self.reader.take(), self.fr, self.report)
        return _rows(cols, self.source, self.fr.file, "can", count_only=True)

    def end(self) -> FrameRows | None:
        """The file is complete: held lines are read, the last line accounted for."""
        return self.add(0, b"", final=True)


class SensorFrameLines:
    """One sensor frame log's lines → frames (each line stands alone)."""

    def __init__(self, source: str, fr: FileReport, report: ParseReport) -> None:
        self.source, self.fr, self.report = source, fr, report
        self.failed = ""

    def add(self, first_line: int, data: bytes) -> FrameRows | None:
        cols = read_frame_lines(data, first_line, self.fr, self.report)
        return _rows(cols, self.source, self.fr.file, "frame", count_only=False)

    def end(self) -> FrameRows | None:
        return None
