"""What a followed file is, and its lines → the items the live engine takes.

A followed file's format is recognised from its first lines by the
classifier ``report`` and the wrong-kind checks use
(:func:`parsers.kinds.classify_head`), then its lines go where the batch
commands would read them:

=====================================  ==========================================
diagnostic log                         :class:`LineBlock` (the diagnostic follower parses it)
NMEA / gpsd JSON / device CSV or JSON  :class:`GnssFix` (:mod:`console.inputs.file_gnss`)
CAN log (candump, ASC, TRC), frames    :class:`FrameRows` (:mod:`console.inputs.file_frames`)
=====================================  ==========================================

A file whose first lines do not tell yet (empty, or nothing but a partial
line) waits.  A file of another kind (a GPX track, a centre table, a
voltage table) or of none is one ``unrecognised`` note with the reason, and
its lines are counted, not rejected one by one.  Following from the end,
the first lines are read from the file's head (they are not delivered):
they tell the format, and give the header a device CSV's rows or an ASC/TRC
log's frames are read by.  Each file of a rotation (and a file truncated
and written again) is recognised anew; a change of format is said in the
note.

Lines the parsers reject are counted as ``malformed`` in the source's
status and shown as notes (the first :data:`SHOWN_MALFORMED`, then one per
thousand), never fatal.
"""

from __future__ import annotations

import codecs
from pathlib import Path
from typing import Any, Protocol

from console.inputs.base import GnssFix, Item, LineBlock, SourceStatus
from console.inputs.file_frames import CanLines, SensorFrameLines, can_format
from console.inputs.file_gnss import DEVICE_KINDS, STREAM_KINDS, GnssLines
from parsers.frames.can_report import CanFileReport
from parsers.kinds import DESCRIPTIONS, HEAD_BYTES, classify_head
from parsers.report import FileReport, ParseReport, Rejection, device_of_file

FOLLOWED = frozenset({"diag", *STREAM_KINDS, *DEVICE_KINDS, "can", "frames"})
DECIDE_LINES = 16  # record lines after which a head that is still no known format is taken as none
SHOWN_MALFORMED = 20  # shown one by one; after that one note per 1000 (as MQTT's malformed messages)


class FollowingSource(Protocol):
    """What a followed file's lines need of the source reading it (:class:`console.inputs.line_source.LineSource`:
    a followed file, or a stream)."""

    uri: str
    watching: str  # how the file is watched: "inotify" or "poll"; "stream" for a pipe

    def note(self, kind: str, detail: str) -> None: ...
    def set_connected(self, connected: bool, detail: str) -> None: ...
    def count_malformed(self, n: int = 1) -> None: ...
    def status(self) -> SourceStatus: ...


_WHAT_IS_FOLLOWED = (
    "file: follows diagnostic logs, GNSS streams (NMEA, gpsd JSON, device CSV or JSON lines),"
    " CAN logs (candump, ASC, TRC) and sensor frame logs"
)


def _record_lines(head: bytes) -> list[bytes]:
    return [s for s in (line.strip() for line in head.split(b"\n")[:-1]) if s and not s.startswith(b"#")]


def _numbered(data: bytes, first_line: int = 1) -> list[tuple[int, bytes]]:
    return [(first_line + k, raw) for k, raw in enumerate(data.split(b"\n")[:-1])]


def _unreadable(head: bytes) -> str:
    """Why bytes we do not follow look as they do, when it is something a person can act on."""
    if head.startswith(b"\x1f\x8b"):
        return "gzip-compressed: a compressed file cannot be followed while it grows"
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "UTF-16 text: follow reads UTF-8"
    return ""


class FileLines:
    """A followed source's files: recognised one by one, their lines turned into items."""

    def __init__(self, source: FollowingSource, path: Path) -> None:
        self.source = source
        self.path = path
        self.report = ParseReport(on_reject=self._rejected)
        self.gnss = GnssLines(source.uri, self.report)
        self.label = ""
        self.kind = ""  # the current file's kind; "" while not recognised
        self.previous_kind = ""
        self.ignored_lines = 0
        self._not_read: dict[str, int] = {}  # a file of a kind not followed -> its lines (counted, not read)
        self._head = b""  # the file's first bytes (up to HEAD_BYTES), while it is not recognised
        self._skipped: list[tuple[int, bytes]] = []  # its first lines that are not delivered
        self._pending: list[LineBlock] = []
        self._reader: CanLines | SensorFrameLines | None = None

    # -- the source's calls ---------------------------------------------------
    def start(self, label: str, skipped_head: bytes) -> list[Item]:
        """A file is opened (the first, or the next after a rotation or a truncation).

        ``skipped_head``: its complete lines before where reading starts (following from the end),
        up to :data:`HEAD_BYTES`.
        """
        out = self.end_file()
        self.label, self.kind, self._pending, self._reader = label, "", [], None
        head = skipped_head.removeprefix(codecs.BOM_UTF8)
        self._head, self._skipped = head, _numbered(head)
        return out + self._recognise(final=False)

    def lines(self, block: LineBlock) -> list[Item]:
        """Complete lines of the current file → items."""
        if self.kind:
            return self._route(block)
        self._pending.append(block)
        if len(self._head) < HEAD_BYTES:
            data = block.data.removeprefix(codecs.BOM_UTF8) if block.first_line == 1 else block.data
            self._head += data[: HEAD_BYTES - len(self._head)]
        return self._recognise(final=False)

    def end_file(self) -> list[Item]:
        """The current file is complete (rotated away, truncated, or following ends)."""
        out: list[Item] = []
        if not self.kind and self._pending:
            out += self._recognise(final=True)
        if self._reader is not None:
            rows = self._reader.end()
            out += [rows] if rows is not None else []
        if self.kind in STREAM_KINDS:
            out += self.gnss.end_file()
        return out

    def finish(self) -> list[Item]:
        """Following ends: what waited for more lines is handed over."""
        out = self.end_file()
        return out + list(self.gnss.finish())

    def reports(self) -> list[dict[str, Any]]:
        """Line accounting of the files read here (not the diagnostic ones: the engine reads those); a file of
        no kind followed (its ``unrecognised`` note says what it looks like) has its lines as ``unrecognised``."""
        out = [
            {"file": f.file, "lines_read": f.lines_read, "records": f.records, "blank": f.blank, "rejected": f.rejected}
            for f in self.report.files
        ]
        zero = {"records": 0, "blank": 0, "rejected": 0}
        return out + [{"file": k, "lines_read": n, **zero, "unrecognised": n} for k, n in self._not_read.items()]

    # -- recognition ------------------------------------------------------------
    def _recognise(self, final: bool) -> list[Item]:
        guess = classify_head(self._head)
        kind, why = guess.kind, guess.why
        if kind == "empty":
            return []  # nothing but blank and comment lines: nothing to tell, nothing to read
        if kind == "unknown":
            records = _record_lines(self._head)
            if any(r.startswith(b"Diag_id:") for r in records):
                # A diagnostic log whose first line is damaged: read as one, as before.
                kind, why = "diag", "Diag_id: records after a first line that is not one"
            elif unreadable := _unreadable(self._head):
                why = unreadable
            elif not final and len(self._head) < HEAD_BYTES and len(records) < DECIDE_LINES:
                return []
        followed = kind in FOLLOWED and not self._head.startswith(b"LOGG")
        if kind == "can" and not followed:
            why += ": a binary log, not followed as it grows (trackside frames reads it whole)"
        return self._decide(kind, why, followed)

    def _decide(self, kind: str, why: str, followed: bool) -> list[Item]:
        source, label = self.source, self.label
        out: list[Item] = []
        if self.previous_kind in STREAM_KINDS and kind not in STREAM_KINDS:
            out += self.gnss.finish()  # the receiver's last epoch ends with its stream
        changed = f"; the file before it was {DESCRIPTIONS[self.previous_kind]}" if self.previous_kind else ""
        if self.previous_kind == kind:
            changed = ""
        self.kind = kind if followed else "ignored"
        self.previous_kind = kind
        pending = self._pending
        if not followed:
            source.note(
                "unrecognised", f"{label}: {DESCRIPTIONS[kind]} ({why}){changed}; not read: {_WHAT_IS_FOLLOWED}"
            )
            source.set_connected(True, f"following; not read: {DESCRIPTIONS[kind]}")
        else:
            source.note("info", f"{label}: {why}: read as {DESCRIPTIONS[kind]}{changed}")
            source.set_connected(True, f"following {DESCRIPTIONS[kind]} ({source.watching})")
            self._open_reader(kind)
        self._skipped, self._pending, self._head = [], [], b""
        for block in pending:
            out += self._route(block)
        return out

    def _open_reader(self, kind: str) -> None:
        label, stem = self.label, device_of_file(self.path)
        if kind in STREAM_KINDS or kind in DEVICE_KINDS:
            fr = FileReport(file=label)
            self.report.files.append(fr)
            self.gnss.open_file(kind, fr, stem, self._skipped)
        elif kind == "can":
            fr = CanFileReport(file=label, format=can_format(_record_lines(self._head + b"\n")[0]))
            self.report.files.append(fr)
            reader = CanLines(self.source.uri, fr.format, fr, self.report)
            if self._skipped:
                reader.skip_header(self._skipped)
                if reader.failed:
                    self.source.note("unrecognised", f"{label}: {reader.failed}; its lines are not read")
            self._reader = reader
        elif kind == "frames":
            fr = FileReport(file=label)
            self.report.files.append(fr)
            self._reader = SensorFrameLines(self.source.uri, fr, self.report)

    # -- lines → items --------------------------------------------------------
    def _route(self, block: LineBlock) -> list[Item]:
        kind = self.kind
        if kind == "diag":
            return [block]
        if kind == "ignored":
            n = block.data.count(b"\n")
            self.ignored_lines += n
            self._not_read[self.label] = self._not_read.get(self.label, 0) + n
            return []
        data = block.data.removeprefix(codecs.BOM_UTF8) if block.first_line == 1 else block.data
        if self._reader is not None:
            failed = self._reader.failed
            rows = self._reader.add(block.first_line, data)
            if self._reader.failed and not failed:
                self.source.note("unrecognised", f"{self.label}: {self._reader.failed}; its lines are not read")
            return [rows] if rows is not None else []
        fixes: list[GnssFix] = self.gnss.add(block.first_line, data)
        return list(fixes)

    def _rejected(self, r: Rejection) -> None:
        self.source.count_malformed()
        n = self.source.status().malformed
        text = f"{r.file} line {r.line}: {r.reason}: {r.text}"
        if n <= SHOWN_MALFORMED:
            self.source.note("malformed", text)
        elif n % 1000 == 0:
            self.source.note("malformed", f"{n} malformed lines so far; latest: {text}")
