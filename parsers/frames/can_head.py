"""Which CAN log format a file holds, from its first bytes (as the parsers read them: gzip, UTF-16 undone).

One rule for :mod:`parsers.kinds` (is it a CAN log at all?) and :func:`parsers.frames.can.parse_can`
(which of python-can's readers reads it): a CAN log is told by its content, its name only when the content
says nothing (an empty file).  Light: no python-can import.
"""

from __future__ import annotations

import re
from typing import Final, Literal

CanFormat = Literal["candump", "asc", "trc", "blf"]

CANDUMP_RE: Final = re.compile(rb"\(\d+(?:\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]+#")
TRC_RECORD_RE: Final = re.compile(rb"^\d+\)\s+\d")  # a PEAK trace's message: number, time (TRC 1.0 has no $ header)
ASC_RE: Final = re.compile(rb"^(?:date |base hex|base dec|internal events|Begin Triggerblock)", re.IGNORECASE)


def record_lines(head: bytes) -> list[bytes]:
    """The head's lines that are neither empty nor ``#`` comments, stripped."""
    return [s for s in (line.strip() for line in head.split(b"\n")) if s and not s.startswith(b"#")]


def can_format_of_lines(lines: list[bytes]) -> CanFormat | None:
    """``candump``, ``asc`` or ``trc`` from a text head's record lines; None when they are no CAN log."""
    if not lines:
        return None
    first = lines[0]
    if CANDUMP_RE.match(first):
        return "candump"
    if ASC_RE.match(first):
        return "asc"
    if first.startswith(b";$FILEVERSION") or (
        first.startswith(b";") and any(TRC_RECORD_RE.match(line) for line in lines[:40])
    ):
        return "trc"
    return None


def can_format_of_head(head: bytes) -> CanFormat | None:
    """The CAN log format of a file whose first bytes are ``head``: BLF by its ``LOGG`` signature, the text
    formats by their first record line; None for anything else."""
    if head.startswith(b"LOGG"):
        return "blf"
    return can_format_of_lines(record_lines(head))
