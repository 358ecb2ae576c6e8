"""GPX 1.0 / 1.1 tracks → fix rows.

What phones and loggers export: ``<trkpt lat=".." lon=".."><time>…</time></trkpt>``
inside ``<trk><trkseg>``.  Read per track point:

* ``lat``, ``lon`` attributes (degrees, WGS 84); required, in range;
* ``<time>`` (ISO 8601, UTC); a point without one has time NaT;
* speed (m/s) and course (degrees true), when given: GPX 1.0 puts
  ``<speed>`` and ``<course>`` in the point itself; GPX 1.1 has no such
  elements and exporters put them in ``<extensions>`` (Garmin's
  TrackPointExtension ``<gpxtpx:speed>``/``<gpxtpx:course>``, or a bare
  ``<speed>``/``<course>``); any element of that local name inside the point
  is taken, whatever its namespace.  No speed: NaN, never 0;
* ``<fix>`` (``none``, ``2d``, ``3d``, ``dgps``, ``pps``): ``none`` makes a
  no-fix row.

Waypoints and route points are not a track: counted in ``report.skipped``.
The device is the file's stem; roles come from the ``roles`` mapping.

Safety: parsed with expat, streaming (memory does not grow with the file);
a document type declaration is refused (no entity expansion, so no "billion
laughs").  Line accounting: a line where a track point starts is a record
(or rejected, with the reason, if the point is unusable); other lines are
markup, counted blank.  An XML error stops the reading: its line is rejected
with expat's message, and so is every line after it (the document cannot be
read on past a syntax error).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.parsers import expat

from parsers.gnss.fix_table import NAT_NS, FixRows
from parsers.gnss.lines import open_gnss_stream
from parsers.gnss.times import parse_time_ns
from parsers.report import FileReport, ParseReport, device_of_file

_READ_BYTES = 1 << 20
_TEXT_ELEMENTS = frozenset({"time", "speed", "course", "fix"})


class _Refused(Exception):
    """A construct we do not read (a DTD)."""


@dataclass
class _Point:
    line: int
    attrs: dict[str, str]
    text: dict[str, str] = field(default_factory=dict)


class _GpxReader:
    def __init__(self, fr: FileReport, report: ParseReport, rows: FixRows, device: str, role: str) -> None:
        self.fr, self.report, self.rows = fr, report, rows
        self.device, self.role = device, role
        self.point: _Point | None = None
        self.text_of: str | None = None
        self.buffer: list[str] = []
        self.line_status: dict[int, str] = {}  # line → "record" or "rejected", for lines holding points
        self.parser = expat.ParserCreate(namespace_separator=" ")
        self.parser.StartElementHandler = self.start
        self.parser.EndElementHandler = self.end
        self.parser.CharacterDataHandler = self.chars
        self.parser.StartDoctypeDeclHandler = self.doctype
        self.parser.EntityDeclHandler = self.entity

    @staticmethod
    def doctype(*_: Any) -> None:
        raise _Refused("a document type declaration is not read (entity expansion)")

    @staticmethod
    def entity(*_: Any) -> None:
        raise _Refused("an entity declaration is not read")

    def start(self, name: str, attrs: dict[str, str]) -> None:
        local = name.rsplit(" ", 1)[-1]
        if local == "trkpt":
            self.point = _Point(self.parser.CurrentLineNumber, {k.rsplit(" ", 1)[-1]: v for k, v in attrs.items()})
        elif local in ("wpt", "rtept"):
            self.report.skipped[f"GPX {local} (not a track point)"] += 1
        elif self.point is not None and local in _TEXT_ELEMENTS and local not in self.point.text:
            self.text_of, self.buffer = local, []

    def chars(self, data: str) -> None:
        if self.text_of is not None:
            self.buffer.append(data)

    def end(self, name: str) -> None:
        local = name.rsplit(" ", 1)[-1]
        if self.point is not None and local == self.text_of:
            self.point.text[local] = "".join(self.buffer).strip()
            self.text_of = None
        elif local == "trkpt" and self.point is not None:
            self.finish(self.point)
            self.point = None

    def finish(self, point: _Point) -> None:
        try:
            fields = _point_fields(point)
        except ValueError as exc:
            if self.line_status.get(point.line) != "rejected":
                self.line_status[point.line] = "rejected"
                self.report.reject(self.fr, point.line, "gpx", f"track point: {exc}", b"<trkpt ...>")
            return
        self.line_status.setdefault(point.line, "record")
        self.rows.add(
            **fields, device=self.device, role=self.role, source="gpx", sentence="", file=self.fr.file, line=point.line
        )


def _number(text: str | None, what: str) -> float:
    if text is None or text == "":
        return math.nan
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{what} '{text[:40]}' is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{what} '{text[:40]}' is not a finite number")
    return value


def _point_fields(point: _Point) -> dict[str, Any]:
    lat = _number(point.attrs.get("lat"), "lat")
    lon = _number(point.attrs.get("lon"), "lon")
    if math.isnan(lat) or math.isnan(lon):
        raise ValueError("lat and lon attributes are required")
    if abs(lat) > 90 or abs(lon) > 180:
        raise ValueError(f"position {lat:g}, {lon:g} is out of range")
    time_text = point.text.get("time")
    time_ns = NAT_NS if not time_text else parse_time_ns(time_text)
    speed = _number(point.text.get("speed"), "speed")
    if speed < 0:
        raise ValueError(f"speed {speed:g} m/s is negative")
    fix = point.text.get("fix", "").casefold()
    valid = fix != "none"
    return {
        "time_ns": time_ns,
        "lat": lat,
        "lon": lon,
        "speed_mps": speed,
        "course_deg": _number(point.text.get("course"), "course"),
        "valid": valid,
        "fix_quality": "no_fix" if not valid else "gnss" if fix else "",
    }


def parse_gpx_file(path: Path, report: ParseReport, rows: FixRows, roles: Mapping[str, str]) -> None:
    """Parse one GPX file; its track points are appended to ``rows``; every line is counted in ``report``."""
    stream, raw, encoding, compressed = open_gnss_stream(path)
    fr = FileReport(file=str(path), encoding=encoding, compressed=compressed)
    report.files.append(fr)
    device = device_of_file(path)
    reader = _GpxReader(fr, report, rows, device, roles.get(device, ""))
    lines = 0
    ends_with_newline = True
    failed: tuple[int, str] | None = None
    try:
        while chunk := stream.read(_READ_BYTES):
            lines += chunk.count(b"\n")
            ends_with_newline = chunk.endswith(b"\n")
            if failed is None:
                try:
                    reader.parser.Parse(chunk, False)
                except expat.ExpatError as exc:
                    failed = (exc.lineno, f"not well-formed XML: {expat.ErrorString(exc.code)}")
                except (_Refused, ValueError) as exc:
                    failed = (reader.parser.CurrentLineNumber, str(exc))
        if failed is None:
            try:
                reader.parser.Parse(b"", True)
            except expat.ExpatError as exc:
                failed = (exc.lineno, f"not well-formed XML: {expat.ErrorString(exc.code)}")
        fr.bytes_read = raw.tell()
    finally:
        stream.close()
        raw.close()
    if not ends_with_newline:
        lines += 1
        fr.ends_without_newline = True
    fr.lines_read = lines
    if lines == 0:
        return  # an empty file: nothing to count (parsers.kinds calls it empty)
    _account(fr, report, reader.line_status, lines, failed)


def _account(
    fr: FileReport, report: ParseReport, status: dict[int, str], lines: int, failed: tuple[int, str] | None
) -> None:
    """Count every line once: records and rejections by line, the rest blank (markup)."""
    stop = lines + 1
    if failed is not None:
        stop = min(max(failed[0], 1), lines)
        for line in [n for n in status if n >= stop]:
            if status.pop(line) == "rejected":
                fr.rejected -= 1  # re-counted below with the document error
                report.rejected_by_reason["gpx"] -= 1
        report.reject(fr, stop, "xml", failed[1], b"")
        for line in range(stop + 1, lines + 1):
            report.reject(fr, line, "xml", f"after the XML error at line {stop}, the document cannot be read on", b"")
    fr.records = sum(1 for s in status.values() if s == "record")
    fr.blank = fr.lines_read - fr.records - fr.rejected
    report.rejected_by_reason += type(report.rejected_by_reason)()  # drop zero counts
