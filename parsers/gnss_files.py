"""GNSS files of any format → one fix table: each file's kind recognised, then read by its reader.

This sits above the recogniser of file kinds (:mod:`parsers.kinds`), which
sits above the format families: a GNSS reader does not know what else a file
could be, the recogniser knows every family.

By content, from the file's head: NMEA sentences or binary receiver packets
anywhere in it, or gpsd JSON → stream (:mod:`parsers.gnss.stream`); other
JSON lines → device stream (:mod:`parsers.gnss.csv`); ``<gpx`` → GPX; a
header that reads as a centre table (it has a train column) → centre
(:mod:`parsers.gnss.centre`); a header that reads as a device export → CSV.
Anything else: every line is rejected with the reason, no exception;
commands refuse such a file up front (:func:`parsers.kinds.not_gnss_reason`,
:func:`nothing_read`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from parsers.gnss.centre import CrossingRows, in_time_order, parse_centre_file
from parsers.gnss.csv import parse_device_file
from parsers.gnss.fix_table import FixColumns, FixRows, check_roles
from parsers.gnss.gpx import parse_gpx_file
from parsers.gnss.lines import open_lines
from parsers.gnss.stream import StreamParser
from parsers.kinds import classify_file
from parsers.report import ParseReport

if TYPE_CHECKING:
    import pandas as pd

GnssFormat = Literal["nmea", "jsonl", "csv", "centre", "gpx", "unknown"]

_KIND_FORMATS: dict[str, GnssFormat] = {
    "nmea": "nmea",
    "gpsd": "nmea",  # gpsd JSON is read by the stream parser, beside any NMEA in the file
    "jsonl": "jsonl",
    "gnss-csv": "csv",
    "centre": "centre",
    "gpx": "gpx",
}


def recognise_format(path: Path | str) -> GnssFormat:
    """``"nmea"`` (any receiver stream: NMEA, gpsd JSON, binary packets), ``"jsonl"``, ``"centre"``,
    ``"csv"``, ``"gpx"`` or ``"unknown"``, from the file's head (:func:`parsers.kinds.classify_file`)."""
    return _KIND_FORMATS.get(classify_file(path).kind, "unknown")


def _reject_all(path: Path, report: ParseReport) -> None:
    fr, lines = open_lines(path, report)
    reason = (
        "unrecognised GNSS format: expected NMEA sentences ($…), JSON lines ({…}), "
        "a device CSV (time, device, role, lat, lon, speed) or a monitoring-centre table (TIMESTAMP, Mã tàu, …)"
    )
    for number, raw in lines:
        if raw.strip():
            report.reject(fr, number, "format", reason, raw)
        else:
            fr.blank += 1


def parse_gnss(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None, utc_offset_h: float = 0.0
) -> tuple[pd.DataFrame, ParseReport, pd.DataFrame]:
    """Parse GNSS files of any known format: (fixes in time order, report, crossing states).

    Each file's format is recognised by content (:func:`recognise_format`).
    Fixes are sorted by time, stably (unknown times last); crossing states
    come from centre tables, empty if there are none.  ``roles`` (device →
    head/eot) applies to NMEA devices and to stream rows that give no role;
    ``utc_offset_h`` to the zone-less times of centre tables.
    """
    rows, report, crossings = _read_gnss(paths, roles, utc_offset_h)
    return rows.frame(time_order=True, release=True), report, in_time_order(crossings.frame())


def parse_gnss_columns(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None, utc_offset_h: float = 0.0
) -> tuple[FixColumns, ParseReport]:
    """:func:`parse_gnss`'s fixes as numpy columns (no pandas: what `trackside gnss` shows), and the report."""
    rows, report, _ = _read_gnss(paths, roles, utc_offset_h)
    return rows.columns(time_order=True, release=True), report


def _read_gnss(
    paths: Iterable[Path | str], roles: Mapping[str, str] | None, utc_offset_h: float
) -> tuple[FixRows, ParseReport, CrossingRows]:
    report = ParseReport()
    role_map = check_roles(roles)
    rows, crossings = FixRows(), CrossingRows()  # one table, in file order, before the sort
    nmea = StreamParser(report, role_map, rows)
    for path in map(Path, paths):
        fmt = recognise_format(path)
        if fmt == "nmea":
            nmea.parse_file(path)
        elif fmt == "centre":
            parse_centre_file(path, report, rows, crossings, utc_offset_h)
        elif fmt in ("csv", "jsonl"):
            parse_device_file(path, report, rows, fmt, role_map)
        elif fmt == "gpx":
            parse_gpx_file(path, report, rows, role_map)
        else:
            _reject_all(path, report)
    report.check()
    return rows, report, crossings


def nothing_read(report: ParseReport) -> list[str]:
    """One line per file of which no line was readable (no record, some rejected), with the main reason.

    For commands that refuse such a file (exit 2) rather than report on nothing.
    """
    out = []
    for fr in report.files:
        if fr.records or not fr.rejected:
            continue
        first = next((r for r in report.rejections if r.file == fr.file), None)
        example = f"; line {first.line}: {first.reason}" if first is not None else ""
        lines = "line" if fr.rejected == 1 else "lines"
        out.append(f"{fr.file}: nothing readable as GNSS: {fr.rejected} {lines} rejected, none read{example}")
    if out and report.skipped:
        skipped = ", ".join(f"{n} {kind}" for kind, n in sorted(report.skipped.items()))
        out[0] += f" (skipped, not decoded: {skipped})"
    return out


def _is_jsonl(path: Path) -> bool:
    return classify_file(path).kind in ("jsonl", "gpsd")


def parse_device_stream(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Parse device streams (CSV or JSON lines, told apart by content) into a fix table in file order.

    ``roles`` fills in the role of rows that give none (device → head/eot).
    """
    report = ParseReport()
    rows = FixRows()
    role_map = check_roles(roles)
    for path in map(Path, paths):
        parse_device_file(path, report, rows, "jsonl" if _is_jsonl(path) else "csv", role_map)
    report.check()
    return rows.frame(release=True), report
