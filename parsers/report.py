"""ParseReport: every input line is counted as parsed, blank or rejected.

The invariant ``lines_read == records + blank + rejected`` holds per file and
in total; :meth:`ParseReport.check` asserts it.  Rejection details are kept up
to a cap so memory stays bounded on a file of pure junk, but every rejection
is counted, by file and by reason.
"""

from __future__ import annotations

import os
import re
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import PurePath
from typing import Any

MAX_REJECTIONS_KEPT = 1000
TEXT_CUT_CHARS = 120

REASON_CUT_CHARS = 500

# C0 (tab, CR and LF have their own escapes), DEL, C1, line/paragraph separators,
# bidi marks, embeddings, overrides and isolates (U+061C, U+200E-200F,
# U+202A-202E, U+2066-2069), the invisible ones (U+180E, U+200B-200D,
# U+2060-206F, U+FEFF, tags U+E0000-E007F), surrogates and U+FFFD (a byte
# that did not decode).  The same set as console.safe_text, which parsers cannot import.
_CONTROL = re.compile(
    r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\u061c\u180e\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff"
    r"\ud800-\udfff\ufffd\U000e0000-\U000e007f]"
)
_WHITESPACE_ESCAPES = str.maketrans({"\t": "\\t", "\r": "\\r", "\n": "\\n"})


def _escape(match: re.Match[str]) -> str:
    code = ord(match.group())
    if code < 0x100:
        return f"\\x{code:02x}"
    if 0xDC80 <= code <= 0xDCFF:
        return f"\\x{code - 0xDC00:02x}"  # a byte of a file name that is not UTF-8 (surrogateescape)
    return f"\\u{code:04x}" if code <= 0xFFFF else f"\\U{code:08x}"


def escape_text(raw: bytes | str, limit: int = TEXT_CUT_CHARS) -> str:
    """Show offending input safely: control bytes escaped, cut short.

    Undecodable bytes become ``\\xNN``; C0/C1 controls (ESC included) become
    ``\\xNN`` too, so a log line can never drive the terminal; bidi controls
    become ``\\u202e`` so it cannot display reversed.  Tabs are shown as
    ``\\t`` so the field structure stays visible.
    """
    text = raw.decode("utf-8", errors="backslashreplace") if isinstance(raw, bytes) else raw
    cut = len(text) > limit
    text = _CONTROL.sub(_escape, text[:limit].translate(_WHITESPACE_ESCAPES))
    return text + "…" if cut else text


def escape_name(name: str) -> str:
    """A file name as shown: a byte that is not UTF-8 as ``\\xff`` (as ``ls`` does), controls and bidi escaped."""
    return _CONTROL.sub(_escape, name.translate(_WHITESPACE_ESCAPES))


def device_of_file(path: str | os.PathLike[str]) -> str:
    """The device name a file gives its records when they carry none: its stem, escaped as file names are
    shown (``T\\xff\\xfe-head`` for ``T\\xff\\xfe-head.nmea``), so it can reach Arrow and JSON."""
    return escape_name(PurePath(os.fsdecode(path)).stem)


def escape_reason(reason: str) -> str:
    """A rejection reason, which may quote input: escaped like the text, cut long."""
    return escape_text(reason, REASON_CUT_CHARS)


@dataclass(frozen=True)
class Rejection:
    """One input line that could not be parsed."""

    file: str
    line: int
    reason: str
    text: str

    def to_dict(self) -> dict[str, Any]:
        return {"file": escape_name(self.file), "line": self.line, "reason": self.reason, "text": self.text}


@dataclass
class FileReport:
    """Line accounting for one input file."""

    file: str
    lines_read: int = 0
    records: int = 0
    blank: int = 0
    rejected: int = 0
    bytes_read: int = 0
    encoding: str = "utf-8"
    compressed: bool = False
    ends_without_newline: bool = False
    # Parsed records that repeat another input file's (overlapping exports):
    # still counted in ``records``; the analysis counts them once.
    overlap_records: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": escape_name(self.file),
            "lines_read": self.lines_read,
            "records": self.records,
            "blank": self.blank,
            "rejected": self.rejected,
            "overlap_records": self.overlap_records,
            "bytes_read": self.bytes_read,
            "encoding": self.encoding,
            "compressed": self.compressed,
            "ends_without_newline": self.ends_without_newline,
        }


@dataclass
class ParseReport:
    """What happened to every line of every input file."""

    files: list[FileReport] = field(default_factory=list)
    rejections: list[Rejection] = field(default_factory=list)
    rejected_by_reason: Counter[str] = field(default_factory=Counter)
    unknown_labels: Counter[str] = field(default_factory=Counter)
    # Input that is not ours to read but was recognised and passed over on
    # purpose (binary UBX/RTCM3/SBF/SiRF packets in a GNSS stream, extra CSV
    # columns), counted by kind: nothing vanishes unseen.
    skipped: Counter[str] = field(default_factory=Counter)
    max_rejections_kept: int = MAX_REJECTIONS_KEPT
    # Called with every rejection as it is found (a stream that lists them all), kept or not.
    on_reject: Callable[[Rejection], None] | None = None

    @property
    def lines_read(self) -> int:
        return sum(f.lines_read for f in self.files)

    @property
    def records(self) -> int:
        return sum(f.records for f in self.files)

    @property
    def blank(self) -> int:
        return sum(f.blank for f in self.files)

    @property
    def rejected(self) -> int:
        return sum(f.rejected for f in self.files)

    def reject(self, file_report: FileReport, line: int, category: str, reason: str, raw: bytes) -> None:
        """Count one rejected line; keep its details while under the cap."""
        file_report.rejected += 1
        self.rejected_by_reason[category] += 1
        keep = len(self.rejections) < self.max_rejections_kept
        if keep or self.on_reject is not None:
            rejection = Rejection(file_report.file, line, escape_reason(reason), escape_text(raw))
            if keep:
                self.rejections.append(rejection)
            if self.on_reject is not None:
                self.on_reject(rejection)

    def check(self) -> None:
        """Raise AssertionError if any line is unaccounted for."""
        for f in self.files:
            total = f.records + f.blank + f.rejected
            assert f.lines_read == total, f"{f.file}: {f.lines_read} lines read but {total} accounted for"
        assert sum(self.rejected_by_reason.values()) == self.rejected

    def to_dict(self) -> dict[str, Any]:
        return {
            "lines_read": self.lines_read,
            "records": self.records,
            "blank": self.blank,
            "rejected": self.rejected,
            "rejections": [r.to_dict() for r in self.rejections],
            "rejections_shown": len(self.rejections),
            "rejected_by_reason": dict(sorted(self.rejected_by_reason.items())),
            "unknown_labels": dict(sorted(self.unknown_labels.items())),
            **({"skipped": dict(sorted(self.skipped.items()))} if self.skipped else {}),
            "files": [f.to_dict() for f in self.files],
        }
