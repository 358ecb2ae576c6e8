"""PEAK trace files (``.trc``): what python-can's ``TRCReader`` reads, and what it leaves unsaid.

PEAK's PCAN-View and PCAN-Explorer write trace files in several versions
(PEAK, "PCAN-Trace file format", ``;$FILEVERSION=``).  python-can 4.x reads
1.0, 1.1, 1.3, 2.0 and 2.1.  The reader has gaps that would lose lines or
misread whole files without a word, so this module deals with them:

* A version it does not know (1.2, for instance) is read by the 1.0 parser,
  which takes the wrong columns.  :func:`check_trc_header` refuses such a
  file first, with an :class:`InputError` naming the version.  It also
  refuses a 2.x file without ``;$COLUMNS`` and a ``;$STARTTIME`` that is
  not a day number.  python-can would raise a ``ValueError`` or an
  ``OverflowError`` there, or take time 0 without a word.
* Lines it cannot parse are dropped with a log warning when too short, and
  stop the iteration when a number is bad.  Error frames (``Error`` in 1.x,
  ``ER`` in 2.x) and bus events (``Warng``, ``ST``, ``EC``, ``EV``) are
  dropped as "unsupported type".  :func:`classify_unread` says what each
  line that produced no message was: a comment or event (blank), an error
  frame (with its time), or a line to reject (with the reason).

Times are python-can's: ``;$STARTTIME`` (days since 1899-12-30, the
recording PC's wall clock) plus the line's offset in ms, read as written.
A 1.0 file has no start time, so its times are offsets from 1970-01-01.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import can
from can.io.trc import TRCFileVersion

from parsers.sources import READ_ERRORS, InputError, open_input

TRC_VERSIONS_READ = ("1.0", "1.1", "1.3", "2.0", "2.1")  # what python-can's TRCReader implements
_HEADER_SCAN_BYTES = 64 << 10
_MAX_START_DAYS = 120_000.0  # 2228 AD: a larger day number is not a date (and overflows python-can)
_V1_ERROR_TYPES = {"Error"}
_V1_EVENT_TYPES = {"Warng"}
_V2_ERROR_TYPES = {"ER"}
_V2_EVENT_TYPES = {"ST", "EC", "EV"}
_V1_TYPE_COLUMN = {TRCFileVersion.V1_1: 2, TRCFileVersion.V1_3: 3}
_BUS_INFO_ID = "FFFFFFFF"  # 1.0: a bus information line, not a frame


@dataclass(frozen=True)
class TrcHeader:
    version: str  # "1.0" when the file names none (PEAK's 1.0 has no $FILEVERSION)
    start_days: float | None
    columns: tuple[str, ...]


def check_trc_header(path: Path) -> TrcHeader:
    """Read the ``;$`` header lines and refuse what python-can would misread; InputError if so."""
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_HEADER_SCAN_BYTES)
    except READ_ERRORS as exc:
        raise InputError(f"{path}: cannot read ({exc})") from None
    finally:
        stream.close()
        raw.close()
    return check_trc_head(head, str(path))


def check_trc_head(head: bytes, name: str) -> TrcHeader:
    """:func:`check_trc_header` on a file's first bytes (``name`` for the message)."""
    version, start = "1.0", None
    columns: tuple[str, ...] = ()
    for line in head.decode("utf-8", errors="replace").splitlines():
        text = line.strip()
        if text and not text.startswith(";"):
            break
        key, _, value = text.partition("=")
        if key == ";$FILEVERSION":
            version = value.strip()
        elif key == ";$STARTTIME":
            try:
                start = float(value)
            except ValueError:
                start = None
            if start is None or not 0.0 <= start <= _MAX_START_DAYS:
                raise InputError(f"{name}: ;$STARTTIME: expected a day number since 1899-12-30, found '{value[:40]}'")
        elif key == ";$COLUMNS":
            columns = tuple(value.strip().split(","))
    if version not in TRC_VERSIONS_READ:
        raise InputError(
            f"{name}: TRC file version '{version[:20]}' is not read (python-can reads {', '.join(TRC_VERSIONS_READ)})"
        )
    if version.startswith("2.") and not {"O", "T", "I", "d"} <= set(columns):
        raise InputError(f"{name}: TRC {version} without a ;$COLUMNS line naming O, T, I and d")
    return TrcHeader(version, start, columns)


@dataclass(frozen=True)
class Unread:
    """What a trace line that gave no message was."""

    kind: str  # "blank" (comment, empty, bus event), "error" (an error frame) or "reject"
    reason: str = ""  # reject: why
    offset_ms: float = 0.0  # error: the line's time offset


def _offset(cols: list[str], index: int) -> float | None:
    try:
        value = float(cols[index])
    except (IndexError, ValueError):
        return None
    return value if abs(value) < 1e15 else None  # about 30 000 years of ms: beyond that not a time


def classify_unread(reader: can.TRCReader, text: str) -> Unread:
    """What ``text``, a line the reader consumed without giving a message, was."""
    line = text.strip()
    if not line or line.startswith(";"):
        return Unread("blank")
    version = reader.file_version
    if version >= TRCFileVersion.V2_0:
        cols = line.split(maxsplit=max(reader._num_columns, 0))
        t = reader.columns.get("T")
        kind = cols[t] if t is not None and t < len(cols) else ""
        offset_at = reader.columns.get("O", 1)
        errors, events = _V2_ERROR_TYPES, _V2_EVENT_TYPES
    elif version in _V1_TYPE_COLUMN:
        cols = line.split()
        i = _V1_TYPE_COLUMN[version]
        kind = cols[i] if i < len(cols) else ""
        offset_at = 1
        errors, events = _V1_ERROR_TYPES, _V1_EVENT_TYPES
    else:  # 1.0: no type column
        cols = line.split()
        if len(cols) > 2 and cols[2].upper() == _BUS_INFO_ID:
            return Unread("blank")
        return Unread("reject", "not a TRC 1.0 message line")
    if kind in events:
        return Unread("blank")
    if kind in errors:
        offset = _offset(cols, offset_at)
        if offset is None:
            return Unread("reject", f"error frame without a time offset in column {offset_at + 1}")
        return Unread("error", offset_ms=offset)
    return Unread("reject", f"not a TRC {version_name(version)} message line")


def version_name(version: TRCFileVersion) -> str:
    return "1.0" if version is TRCFileVersion.UNKNOWN else f"{version.value // 100}.{version.value % 100}"


class ResumedTRCReader(can.TRCReader):
    """A trace reader that continues after a bad line with the header state of the one before."""

    def __init__(self, file: object, previous: can.TRCReader) -> None:
        super().__init__(file)  # type: ignore[arg-type]
        self.file_version = previous.file_version
        self._start_time = previous._start_time
        self.columns = previous.columns
        self._num_columns = previous._num_columns
        self._parse_cols = previous._parse_cols

    def _extract_header(self) -> str:
        return None  # type: ignore[return-value]  # header already read: python-can's __iter__ skips None
