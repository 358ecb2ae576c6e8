"""What kind of input a file is, from its head: for commands given a file of the wrong kind.

:func:`classify_file` reads the first 64 KiB (gzip, UTF-16 with or without a
BOM and CR-only line ends undone, as the parsers read them) and names one of
:data:`KINDS`, with a phrase for people (``"an axle-counter diagnostic
log"``).  A command that reads one family of inputs refuses a file of
another kind up front, with one line naming the file and what it looks like
(exit 2), instead of rejecting every line of it::

    trackside: error: ws4.log: nothing readable as GNSS: looks like an axle-counter diagnostic log

Recognition is by content, never by the file name (exception: none), in
this order: a BLF container (``LOGG``); GPX (``<gpx`` in an XML head);
diagnostic records (``Diag_id:``); CAN logs (candump ``(…) can0 …``, ASC
``date``/``base hex`` headers, PEAK TRC ``;$FILEVERSION`` or, version 1.0,
``;`` comments before numbered messages); gpsd JSON
(objects with a ``class``) and other JSON lines; NMEA or binary receiver
packets anywhere in the head; then one of the first record lines as a table
header (monitoring-centre table, device-stream CSV, receiver voltages; a
title or Excel's ``sep=`` line may come first) or the first as a
sensor-frame line.
"""

from __future__ import annotations

import csv
import re
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Final, Literal

from parsers.frames.can_head import can_format_of_lines, record_lines
from parsers.gnss.fields import delimiter_of
from parsers.gnss.headers import commented_header_cells, parse_centre_header, parse_device_header
from parsers.sources import InputError, open_input

Kind = Literal[
    "diag", "nmea", "gpsd", "jsonl", "gpx", "gnss-csv", "centre", "frames", "can", "voltages", "empty", "unknown"
]
KINDS: Final = (
    "diag",
    "nmea",
    "gpsd",
    "jsonl",
    "gpx",
    "gnss-csv",
    "centre",
    "frames",
    "can",
    "voltages",
    "empty",
    "unknown",
)
GNSS_KINDS: Final = frozenset({"nmea", "gpsd", "jsonl", "gpx", "gnss-csv", "centre"})

DESCRIPTIONS: Final = {
    "diag": "an axle-counter diagnostic log",
    "nmea": "a GNSS receiver stream (NMEA, binary packets)",
    "gpsd": "gpsd JSON reports",
    "jsonl": "GNSS device JSON lines",
    "gpx": "a GPX track",
    "gnss-csv": "a GNSS device CSV export",
    "centre": "a monitoring-centre table",
    "frames": "an intelligent-sensor frame log",
    "can": "a CAN bus log",
    "voltages": "a receiver-voltage table",
    "empty": "an empty file",
    "unknown": "no format trackside reads",
}

# Enough for a banner or a long run of comments before the first record (a preamble of 3,000 lines, a
# 70 kB line of junk), and still a moment's read.
HEAD_BYTES: Final = 1024 * 1024
_TABLE_HEADER_WITHIN = 5  # record lines in which a table's header is looked for (a title, a 'sep=' line first)
_NMEA_RE = re.compile(rb"[$!][A-Z][A-Z0-9]{4},")


@dataclass(frozen=True)
class KindGuess:
    """What a file looks like, and why we think so."""

    kind: str
    why: str = ""

    @property
    def description(self) -> str:
        return DESCRIPTIONS[self.kind]


def _has_packet(head: bytes) -> bool:
    from parsers.gnss import packets  # pyubx2, pysbf2, pyrtcm (0.2 s): only for heads that are none of the above

    for m in packets.SYNC_RE.finditer(head):
        kind = packets.packet_kind(head[m.start() : m.start() + 2])
        if kind is not None and packets.read_packet(kind, packets.ByteWindow(head, m.start())) is not None:
            return True
    return False


def _cells(text: str) -> list[str]:
    """The first line's cells; none for a line the csv module refuses (a stray CR, a NUL): no header."""
    delimiter = "\t" if "\t" in text else ";" if ";" in text else ","
    try:
        return next(csv.reader([text], delimiter=delimiter, skipinitialspace=True), [])
    except csv.Error:
        return []


def _commented_device_header(head: bytes) -> list[str] | None:
    comments = [s for s in (line.strip() for line in head.split(b"\n")) if s.startswith(b"#")]
    for line in comments[:_TABLE_HEADER_WITHIN]:
        text = line.decode("utf-8", errors="replace")
        cells = commented_header_cells(text, delimiter_of(text))
        if cells is not None:
            return cells
    return None


def classify_head(head: bytes) -> KindGuess:
    """The kind of input whose first bytes (decoded to UTF-8-ish, LF line ends) are ``head``."""
    if head.startswith(b"LOGG"):
        return KindGuess("can", "a BLF container")
    lines = record_lines(head)
    if not lines:
        return KindGuess("empty", "no line to read")
    first = lines[0]
    lowered = head[:4096].lower()
    if b"<gpx" in lowered and (first.startswith(b"<") or lowered.lstrip().startswith(b"<?xml")):
        return KindGuess("gpx", "a <gpx> document")
    if first.startswith(b"Diag_id:") or any(line.startswith(b"Diag_id:") for line in lines[1:]):
        # Records after a banner or junk lines: the parser rejects those lines one by one, with their reason.
        return KindGuess("diag", "lines of Diag_id:… records")
    can_format = can_format_of_lines(lines)
    if can_format is not None:
        return KindGuess("can", "PEAK trace lines" if can_format == "trc" else "CAN log lines")
    if first.startswith(b"{"):
        if b'"class"' in first:
            return KindGuess("gpsd", "JSON objects with a gpsd class")
        return KindGuess("jsonl", "JSON objects")
    if _NMEA_RE.search(head) or _has_packet(head):
        return KindGuess("nmea", "NMEA sentences or receiver packets")
    text = first.decode("utf-8", errors="replace")
    from parsers.voltages import parse_header as parse_voltage_header  # pandas: not for every kind asked

    # A title or Excel's 'sep=;' line may stand before a table's header: the table readers reject such lines
    # one by one and read on from the header, so the header is looked for among the first few lines.
    for line in lines[:_TABLE_HEADER_WITHIN]:
        cells = _cells(line.decode("utf-8", errors="replace"))
        for kind, check in (
            ("centre", parse_centre_header),
            ("gnss-csv", parse_device_header),
            ("voltages", parse_voltage_header),
        ):
            try:
                check(cells)
            except ValueError:
                continue
            return KindGuess(kind, "its header")
    if _commented_device_header(head) is not None:
        return KindGuess("gnss-csv", "its header, after '#' (gpsd's gpscsv --header 2)")
    from parsers.frames.sensor import frame_line_problem

    if len(text.split()) in (3, 4) and frame_line_problem(text) is None:
        return KindGuess("frames", "frame lines")
    if b"\0" in head[:4096]:
        return KindGuess("unknown", "binary data")
    return KindGuess("unknown", "no NMEA sentence, JSON object, GPX track or known table header")


def read_head(path: Path) -> bytes:
    """The first :data:`HEAD_BYTES` as every parser reads them (gzip, UTF-16 and CR line ends undone).

    InputError if the file cannot be opened or its head read (a corrupt or truncated gzip).
    """
    stream, raw, _ = open_input(path)
    try:
        return stream.read(HEAD_BYTES)
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(f"{path}: cannot be read, corrupt or truncated ({exc})") from None
    finally:
        stream.close()
        raw.close()


def classify_file(path: Path | str) -> KindGuess:
    """The kind of one file (see the module docstring); InputError if it cannot be read."""
    return classify_head(read_head(Path(path)))


def not_gnss_reason(path: Path | str) -> str | None:
    """None if the file may hold GNSS data, else ``"looks like …"`` for the error line.

    An empty file is zero fixes, not an error (a unit that logged nothing), as an empty log is zero records.
    """
    guess = classify_file(path)
    if guess.kind in GNSS_KINDS or guess.kind == "empty":
        return None
    if guess.kind == "unknown":
        return f"{guess.description} ({guess.why})"
    return f"looks like {guess.description}"
