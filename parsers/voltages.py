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
Files are read as UTF-8 (a BOM is allowed), else as CP1258 (Vietnamese
Windows).
"""

from __future__ import annotations

import csv
import math
import re
import unicodedata
from collections.abc import Iterable
from pathlib import Path

import pandas as pd

from parsers.report import FileReport, ParseReport

VOLTAGE_COLUMNS = ("sensor", "in_phase_mv", "anti_phase_mv", "difference_mv", "file", "line")
REQUIRED = ("sensor", "in_phase_mv", "anti_phase_mv")
DIFFERENCE_TOLERANCE_MV = 0.5

# Spellings of each column once normalised by _header_key.
_HEADER_ALIASES: dict[str, tuple[str, ...]] = {
    "sensor": ("sensor", "sensor position", "position", "vị trí cảm biến", "vị trí", "cảm biến"),
    "in_phase_mv": ("in phase", "in phase voltage", "điện áp chính pha", "chính pha"),
    "anti_phase_mv": ("anti phase", "anti phase voltage", "điện áp ngược pha", "ngược pha"),
    "difference_mv": ("difference", "difference voltage", "margin", "điện áp chênh lệch", "chênh lệch"),
}
_BY_KEY = {alias: column for column, aliases in _HEADER_ALIASES.items() for alias in aliases}
_UNIT_RE = re.compile(r"\s*(?:\(\s*mv\s*\)|\bmv)$")
_NUMBER_RE = re.compile(r"[+-]?\d+(?:[.,]\d+)?")
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
    return next(csv.reader([line], delimiter=delimiter, skipinitialspace=True), [])


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
        raise _RowError("number", f"{column}: expected a number in mV (e.g. -152 or 346,5), found '{text.strip()}'")
    return float(bare.replace(",", "."))


def _row(cells: list[str], columns: list[str]) -> tuple[str, float, float, float]:
    if len(cells) != len(columns):
        hint = " (a decimal comma in a ','-separated file needs quotes)" if len(cells) > len(columns) else ""
        raise _RowError("fields", f"expected {len(columns)} fields, found {len(cells)}{hint}")
    by = dict(zip(columns, cells, strict=True))
    sensor = by["sensor"].strip()
    if not sensor:
        raise _RowError("sensor", "sensor: empty sensor position")
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


def _decode(raw: bytes) -> tuple[str, str]:
    try:
        return raw.decode("utf-8-sig"), "utf-8"
    except UnicodeDecodeError:
        return raw.decode("cp1258", errors="replace"), "cp1258"


def parse_voltage_text(
    text: str, file: str = "<text>", report: ParseReport | None = None, encoding: str = "utf-8"
) -> tuple[pd.DataFrame, ParseReport]:
    """Parse one voltage table given as text; rows and the line accounting."""
    report = report if report is not None else ParseReport()
    file_report = FileReport(file=file, encoding=encoding, bytes_read=len(text.encode("utf-8")))
    report.files.append(file_report)
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    else:
        file_report.ends_without_newline = bool(lines)
    columns: list[str] | None = None
    delimiter = ","
    rows: list[tuple[str, float, float, float, str, int]] = []
    seen: dict[str, int] = {}
    for number, raw_line in enumerate(lines, start=1):
        file_report.lines_read += 1
        line = raw_line.removesuffix("\r")
        if number == 1:
            line = line.removeprefix("\ufeff")
        if not line.strip():
            file_report.blank += 1
            continue
        if columns is None:
            delimiter = _delimiter(line)
            try:
                columns = parse_header(_cells(line, delimiter))
            except ValueError as exc:
                expected = "sensor, in_phase_mv, anti_phase_mv[, difference_mv] (English or Vietnamese)"
                report.reject(
                    file_report, number, "header", f"not the header: {exc}; expected columns {expected}", line.encode()
                )
                continue
            file_report.blank += 1  # the header: no record, nothing lost
            continue
        try:
            sensor, in_mv, anti_mv, diff_mv = _row(_cells(line, delimiter), columns)
            if sensor in seen:
                raise _RowError("duplicate", f"sensor '{sensor}' already given on line {seen[sensor]}")
        except _RowError as exc:
            report.reject(file_report, number, exc.category, exc.reason, line.encode())
            continue
        seen[sensor] = number
        rows.append((sensor, in_mv, anti_mv, diff_mv, file, number))
        file_report.records += 1
    return _frame(rows), report


def _frame(rows: list[tuple[str, float, float, float, str, int]]) -> pd.DataFrame:
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
    for path in paths:
        raw = Path(path).read_bytes()
        text, encoding = _decode(raw)
        frame, _ = parse_voltage_text(text, str(path), report, encoding)
        report.files[-1].bytes_read = len(raw)
        frames.append(frame)
    if not frames:
        return _frame([]), report
    return pd.concat(frames, ignore_index=True), report
