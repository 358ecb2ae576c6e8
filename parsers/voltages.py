"""Receiver-voltage measurements per sensor (seed 000, Table 2) → a table.

A small CSV, one row per installed sensor::

    Vị trí cảm biến,Điện áp chính pha (mv),Điện áp ngược pha (mv),Điện áp chênh lệch (mv)
    1,346,-152,498

Columns, in any order, named in English or Vietnamese (case, ``_``/``-``
and a trailing ``(mV)`` do not matter):

* ``sensor`` / ``Vị trí cảm biến``: the sensor position or name (text);
* ``in_phase_mv`` / ``Điện áp chính pha (mv)``: receiver voltage with no
  wheel, in phase with the transmitter;
* ``anti_phase_mv`` / ``Điện áp ngược pha (mv)``: receiver voltage with a
  wheel over the sensor, normally negative (anti-phase);
* optional ``difference_mv`` / ``Điện áp chênh lệch (mv)``: in − anti as
  printed.  When given it must agree with in − anti to within 0.5 mV (the
  printed resolution); a row where it does not is rejected, since one of its
  three numbers is wrong and we cannot tell which.

The delimiter is a tab, ``;`` or ``,`` (taken from the header line, in that
order of preference).  Numbers may use a decimal comma (``346,5``): with
``;`` or tab delimiters as is, with ``,`` delimiters inside quotes.  A
typographic minus (``−``) is read as ``-``.

Every line is accounted for (``parsers.report``): a row becomes a record, a
blank line is blank, anything else is rejected with its file, line and
reason.  Lines before the header (a title, say) are rejected, since they are
not the table.  The header line itself carries no record and is counted with
the blank lines, so ``lines_read == records + blank + rejected`` holds.
Files go through :mod:`parsers.sources` like every log: plain or gzip, a
file or a stream (``-``, a FIFO), UTF-8 (a BOM is allowed) or UTF-16 (with
or without a BOM), LF, CRLF or CR-only line ends.  A line that is not UTF-8
is read as CP1258 (Vietnamese Windows).  A row with a NUL, another control
character or a stray CR inside it is rejected alone, as is a number that is
not a plain decimal or is beyond any receiver voltage (|v| >
:data:`MAX_ABS_MV`).
"""

from __future__ import annotations

import csv
import math
import re
import unicodedata
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from parsers.report import FileReport, ParseReport, escape_name
from parsers.sources import OverlongLine, ReadFailure, iter_chunks, open_input

if TYPE_CHECKING:
    import pandas as pd  # loaded when a table is made: the file-kind check imports this module too

VOLTAGE_COLUMNS = ("sensor", "in_phase_mv", "anti_phase_mv", "difference_mv", "file", "line")
REQUIRED = ("sensor", "in_phase_mv", "anti_phase_mv")
DIFFERENCE_TOLERANCE_MV = 0.5
MAX_ABS_MV = 100_000.0  # 100 V: far beyond any receiver coil; a bigger number is a typo or junk
MAX_SENSOR_CHARS = 100
MAX_LINE_BYTES = 64 << 10  # a voltage row is a few dozen bytes

# Spellings of each column once normalised by _header_key.
_HEADER_ALIASES: dict[str, tuple[str, ...]] = {
    "sensor": ("sensor", "sensor position", "position", "vị trí cảm biến", "vị trí", "cảm biến"),
    "in_phase_mv": ("in phase", "in phase voltage", "điện áp chính pha", "chính pha"),
    "anti_phase_mv": ("anti phase", "anti phase voltage", "điện áp ngược pha", "ngược pha"),
    "difference_mv": ("difference", "difference voltage", "margin", "điện áp chênh lệch", "chênh lệch"),
}
_BY_KEY = {alias: column for column, aliases in _HEADER_ALIASES.items() for alias in aliases}
_UNIT_RE = re.compile(r"\s*(?:\(\s*mv\s*\)|\bmv)$")
_NUMBER_RE = re.compile(r"[+-]?[0-9]{1,15}(?:[.,][0-9]{1,15})?")  # ASCII digits: not '٣' nor 5000 of them
_CONTROL_RE = re.compile(r"[\x00-\x08\x0a-\x1f\x7f]")  # tab is a delimiter, the rest cannot be in a row
_MINUS = str.maketrans({"−": "-", "–": "-"})


class _RowError(Exception):
    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


def _header_key(cell: str) -> str:
    key = " ".join(unicodedata.normalize("NFC", cell).casefold().replace("_", " ").replace("-", " ").split())
    return _UNIT_RE.sub("", key).strip()


def _delimiter(line: str) -> str:
    return "\t" if "\t" in line else ";" if ";" in line else ","


def _cells(line: str, delimiter: str) -> list[str]:
    try:
        return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])
    except csv.Error as exc:  # e.g. an unterminated quote before a stray CR
        raise _RowError("fields", f"not a {_DELIMITER_NAMES[delimiter]}-separated row ({exc})") from None


_DELIMITER_NAMES = {"\t": "tab", ";": "';'", ",": "','"}


def _control_problem(line: str) -> _RowError | None:
    """A NUL, a stray CR or another control character: the row is broken, whatever its fields say."""
    found = _CONTROL_RE.search(line)
    if found is None:
        return None
    char = found.group()
    what = {"\x00": "a NUL byte", "\r": "a stray CR (a broken line end)"}.get(
        char, f"control character \\x{ord(char):02x}"
    )
    return _RowError("control", f"{what} at column {found.start() + 1}")


def parse_header(cells: list[str]) -> list[str]:
    """Header cells → canonical column names; ValueError with the reason if not a header."""
    columns = []
    for cell in cells:
        column = _BY_KEY.get(_header_key(cell))
        if column is None:
            raise ValueError(f"unknown column '{cell.strip()}'")
        if column in columns:
            raise ValueError(f"column '{cell.strip()}' given twice")
        columns.append(column)
    missing = [c for c in REQUIRED if c not in columns]
    if missing:
        raise ValueError(f"missing column(s) {', '.join(missing)}")
    return columns


def parse_mv(text: str, column: str) -> float:
    """``-152`` / ``346,5`` / ``−71`` → float mV; _RowError otherwise."""
    bare = text.strip().translate(_MINUS)
    if not _NUMBER_RE.fullmatch(bare):
        shown = text.strip()[:40]
        raise _RowError("number", f"{column}: expected a number in mV (e.g. -152 or 346,5), found '{shown}'")
    value = float(bare.replace(",", "."))
    if abs(value) > MAX_ABS_MV:
        raise _RowError("range", f"{column}: {value:g} mV is beyond any receiver voltage (|v| ≤ {MAX_ABS_MV:g} mV)")
    return value


def _row(cells: list[str], columns: list[str]) -> tuple[str, float, float, float]:
    if len(cells) != len(columns):
        hint = " (a decimal comma in a ','-separated file needs quotes)" if len(cells) > len(columns) else ""
        raise _RowError("fields", f"expected {len(columns)} fields, found {len(cells)}{hint}")
    by = dict(zip(columns, cells, strict=True))
    sensor = by["sensor"].strip()
    if not sensor:
        raise _RowError("sensor", "sensor: empty sensor position")
    if len(sensor) > MAX_SENSOR_CHARS:
        raise _RowError("sensor", f"sensor: name of {len(sensor)} characters, at most {MAX_SENSOR_CHARS}")
    in_mv = parse_mv(by["in_phase_mv"], "in_phase_mv")
    anti_mv = parse_mv(by["anti_phase_mv"], "anti_phase_mv")
    diff_mv = math.nan
    if by.get("difference_mv", "").strip():
        diff_mv = parse_mv(by["difference_mv"], "difference_mv")
        margin = in_mv - anti_mv
        if abs(diff_mv - margin) > DIFFERENCE_TOLERANCE_MV:
            raise _RowError(
                "difference",
                f"difference_mv: {diff_mv:g} mV does not equal in − anti = {in_mv:g} − ({anti_mv:g}) = {margin:g} mV",
            )
    return sensor, in_mv, anti_mv, diff_mv


class _Table:
    """One file's lines, in order, into rows; every line counted."""

    def __init__(self, file: str, report: ParseReport, file_report: FileReport) -> None:
        self.file = file
        self.report = report
        self.fr = file_report
        self.columns: list[str] | None = None
        self.delimiter = ","
        self.rows: list[tuple[str, float, float, float, str, int]] = []
        self.seen: dict[str, int] = {}
        # The table's file column holds text (Arrow strings): a name that is not UTF-8 is shown as ls does.
        self.shown_file = escape_name(file)

    def reject(self, number: int, category: str, reason: str, line: str) -> None:
        self.report.reject(self.fr, number, category, reason, line.encode("utf-8", errors="replace"))

    def line(self, number: int, raw_line: str) -> None:
        self.fr.lines_read += 1
        line = raw_line.removesuffix("\r")
        if number == 1:
            line = line.removeprefix("\ufeff")
        if not line.strip():
            self.fr.blank += 1
            return
        if (problem := _control_problem(line)) is not None:
            self.reject(number, problem.category, problem.reason, line)
            return
        if self.columns is None:
            self.delimiter = _delimiter(line)
            try:
                self.columns = parse_header(_cells(line, self.delimiter))
            except (ValueError, _RowError) as exc:
                expected = "sensor, in_phase_mv, anti_phase_mv[, difference_mv] (English or Vietnamese)"
                self.reject(number, "header", f"not the header: {exc}; expected columns {expected}", line)
                return
            self.fr.blank += 1  # the header: no record, nothing lost
            return
        try:
            sensor, in_mv, anti_mv, diff_mv = _row(_cells(line, self.delimiter), self.columns)
            if sensor in self.seen:
                raise _RowError("duplicate", f"sensor '{sensor}' already given on line {self.seen[sensor]}")
        except _RowError as exc:
            self.reject(number, exc.category, exc.reason, line)
            return
        self.seen[sensor] = number
        self.rows.append((sensor, in_mv, anti_mv, diff_mv, self.shown_file, number))
        self.fr.records += 1


def parse_voltage_text(
    text: str, file: str = "<text>", report: ParseReport | None = None, encoding: str = "utf-8"
) -> tuple[pd.DataFrame, ParseReport]:
    """Parse one voltage table given as text; rows and the line accounting."""
    report = report if report is not None else ParseReport()
    file_report = FileReport(file=file, encoding=encoding, bytes_read=len(text.encode("utf-8", errors="replace")))
    report.files.append(file_report)
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    else:
        file_report.ends_without_newline = bool(lines)
    table = _Table(file, report, file_report)
    for number, raw_line in enumerate(lines, start=1):
        table.line(number, raw_line)
    return _frame(table.rows), report


def _decode_line(raw: bytes) -> tuple[str, bool]:
    """(text, read as CP1258): UTF-8 if it is, else the Vietnamese Windows code page."""
    try:
        return raw.decode("utf-8"), False
    except UnicodeDecodeError:
        return raw.decode("cp1258", errors="replace"), True


def _file_lines(path: Path, report: ParseReport) -> tuple[FileReport, Iterator[tuple[int, bytes]]]:
    """A file's FileReport and its lines (without their LF); overlong and unreadable lines are rejected here."""
    stream, raw, info = open_input(path)
    fr = FileReport(file=str(path), encoding=info.encoding, compressed=info.compressed)
    report.files.append(fr)

    def lines() -> Iterator[tuple[int, bytes]]:
        number = 0
        try:
            for item in iter_chunks(stream, info, max_line_bytes=MAX_LINE_BYTES, name=str(path)):
                if isinstance(item, OverlongLine):
                    number += 1
                    fr.lines_read += 1
                    if isinstance(item, ReadFailure):
                        report.reject(fr, number, "corrupt", item.message(number - 1), item.head)
                    else:
                        reason = f"line of {item.length} bytes; a voltage row is under {MAX_LINE_BYTES}"
                        report.reject(fr, number, "too long", reason, item.head)
                    continue
                data = bytes(item.data)
                pieces = data.split(b"\n")
                if data.endswith(b"\n"):
                    pieces.pop()
                for piece in pieces:
                    number += 1
                    yield number, piece
            fr.bytes_read = raw.tell()
        finally:
            stream.close()
            raw.close()
        fr.ends_without_newline = info.ends_without_newline

    return fr, lines()


def _frame(rows: list[tuple[str, float, float, float, str, int]]) -> pd.DataFrame:
    import pandas as pd

    frame = pd.DataFrame(rows, columns=list(VOLTAGE_COLUMNS))
    return frame.astype(
        {
            "sensor": str,
            "in_phase_mv": "float64",
            "anti_phase_mv": "float64",
            "difference_mv": "float64",
            "line": "int64",
        }
    )


def read_voltages(paths: Iterable[Path | str]) -> tuple[pd.DataFrame, ParseReport]:
    """Parse voltage-table files into one table (columns :data:`VOLTAGE_COLUMNS`) and a report.

    A sensor given in two files is kept twice (once per file, with its file
    and line): two measurement days are two rows.
    """
    report = ParseReport()
    frames = []
    for path in map(Path, paths):
        fr, lines = _file_lines(path, report)
        table = _Table(str(path), report, fr)
        for number, raw_line in lines:
            text, cp1258 = _decode_line(raw_line)
            if cp1258:
                fr.encoding = "cp1258"
            table.line(number, text)
        frames.append(_frame(table.rows))
    report.check()
    if not frames:
        return _frame([]), report
    import pandas as pd

    return pd.concat(frames, ignore_index=True), report
