"""ParseReport: every input line is counted as parsed, blank or rejected.

The invariant ``lines_read == records + blank + rejected`` holds per file and
in total; :meth:`ParseReport.check` asserts it.  Rejection details are kept up
to a cap so memory stays bounded on a file of pure junk, but every rejection
is counted, by file and by reason.
"""

from __future__ import annotations

import re
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

MAX_REJECTIONS_KEPT = 1000
TEXT_CUT_CHARS = 120

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\ufffd]")


def escape_text(raw: bytes | str, limit: int = TEXT_CUT_CHARS) -> str:
    """Show offending input safely: control bytes escaped, cut short.

    Undecodable bytes become ``\\xNN``; C0/C1 controls (ESC included) become
    ``\\xNN`` too, so a log line can never drive the terminal.  Tabs are shown
    as ``\\t`` so the field structure stays visible.
    """
    text = raw.decode("utf-8", errors="backslashreplace") if isinstance(raw, bytes) else raw
    cut = len(text) > limit
    text = text[:limit]
    text = text.replace("\t", "\\t").replace("\r", "\\r").replace("\n", "\\n")
    text = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}" if ord(m.group()) < 256 else "\\ufffd", text)
    return text + "…" if cut else text


@dataclass(frozen=True)
class Rejection:
    """One input line that could not be parsed."""

    file: str
    line: int
    reason: str
    text: str

    def to_dict(self) -> dict[str, Any]:
        return {"file": self.file, "line": self.line, "reason": self.reason, "text": self.text}


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
            "file": self.file,
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
    # purpose (binary UBX/RTCM3/SiRF packets in a GNSS stream, extra CSV
    # columns), counted by kind: nothing vanishes unseen.
    skipped: Counter[str] = field(default_factory=Counter)
    max_rejections_kept: int = MAX_REJECTIONS_KEPT

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
        if len(self.rejections) < self.max_rejections_kept:
            self.rejections.append(Rejection(file_report.file, line, reason, escape_text(raw)))

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
