"""A source whose bytes are the lines of a log: cut at newlines, then recognised and read by :class:`FileLines`.

A followed file (:mod:`console.inputs.follow`) and a read stream — a pipe,
FIFO or standard input (:mod:`console.inputs.stream`) — differ only in how
their bytes arrive: positions, rotation and truncation for the one, reads
until end of stream for the other.  What happens to the bytes is this one
class's: complete lines only (a half-written line waits for its newline), a
runaway line handed over as one line, numbers that stay true, and each
block of lines through the one recogniser and the batch parsers.
"""

from __future__ import annotations

import time
from abc import abstractmethod
from pathlib import Path
from typing import Any

from console.inputs.base import Item, LineBlock, Source
from console.inputs.file_lines import FileLines

MAX_LINE_BYTES = 4 << 20
PIECE_BYTES = 64 << 10


class LineSource(Source):
    """Lines of a log as they are read; subclasses say where the bytes come from (:meth:`_deliver` them)."""

    # Its reader may be made to wait while the engine catches up (console.live.backlog): a file keeps,
    # and a pipe's writer waits on the full pipe.  Nothing is lost by waiting.
    waits_for_room = True

    def __init__(self, uri: str, path: Path) -> None:
        super().__init__(uri)
        self.path = path
        self._line = 1
        self._carry = b""
        self._overlong = False  # inside a runaway line whose start was handed over
        self.watching = "poll"  # how new bytes are noticed, as the source's notes say it
        self.files = FileLines(self, path)

    @property
    @abstractmethod
    def label(self) -> str:
        """The name its lines are reported under (rejections, the summary's files, ``not_analysed``)."""

    def file_reports(self) -> list[dict[str, Any]]:
        return self.files.reports()

    def _restart_lines(self) -> None:
        """A new file begins (opened, rotated in, truncated): its lines count from 1."""
        self._line, self._carry, self._overlong = 1, b"", False

    def _deliver(self, block: bytes) -> None:
        """Bytes read, in order: the complete lines among them go on, an unfinished last one waits."""
        if self._overlong:
            # The rest of a runaway line already handed over (as one line, as a batch read counts it).
            nl = block.find(b"\n")
            if nl < 0:
                return
            self._overlong, block = False, block[nl + 1 :]
        data = self._carry + block if self._carry else block
        cut = data.rfind(b"\n") + 1
        if cut == 0:
            self._carry = data
            if len(data) > MAX_LINE_BYTES:  # a runaway line: hand it over, the parser rejects it
                self._flush_carry("overlong")
                self._overlong = True
            return
        self._carry = data[cut:]
        self._emit(data[:cut])

    def _emit(self, lines: bytes) -> None:
        start = 0
        while start < len(lines):
            # A file read here (not a diagnostic log: the engine parses those) goes in pieces, so that
            # its items, and the count of its lines, keep flowing while a big file is read.
            cut = len(lines)
            if self.files.kind != "diag" and cut - start > PIECE_BYTES:
                cut = lines.rfind(b"\n", start, start + PIECE_BYTES) + 1
                if cut <= start:  # one line longer than a piece
                    cut = lines.index(b"\n", start) + 1
            piece = lines[start:cut] if start or cut < len(lines) else lines
            n = piece.count(b"\n")
            block = LineBlock(self.uri, self.label, self._line, piece, time.monotonic())
            self._line += n
            self.count_messages(n)
            self._hand_over(self.files.lines(block))
            start = cut

    def _hand_over(self, items: list[Item]) -> None:
        for item in items:
            self.emit(item, messages=0)

    def _flush_carry(self, why: str) -> None:
        """An unfinished line when the file ends for good: handed over, so it is accounted for."""
        if self._carry:
            carry, self._carry = self._carry, b""
            self.note("info", f"{self.label} line {self._line}: unfinished line ({len(carry)} bytes) at {why}")
            self._emit(carry + b"\n")
