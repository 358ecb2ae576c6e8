"""A followed GNSS file's lines → :class:`~console.inputs.base.GnssFix` items, as the batch parsers read them.

Receiver streams (NMEA, gpsd JSON, binary packets between sentences) go
through :class:`parsers.gnss.growing.GrowingStream`, the batch stream parser
fed a block at a time; device exports (CSV, JSON lines) through
:class:`parsers.gnss.csv.DeviceLines`.  Their rows are the rows
``trackside gnss`` gives for the same file; a row is handed over once no
later line can change it (an NMEA epoch when the next one starts).

A row becomes a fix when it is one for the crossing units, as the batch
crossing analysis takes them: ``valid``, with a time and a position.  The
others (no fix, no date yet, no position) are counted in :attr:`GnssLines.no_fix`.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from console.inputs.base import GnssFix
from parsers.gnss.csv import DeviceLines
from parsers.gnss.fix_table import FixRows
from parsers.gnss.growing import GrowingStream
from parsers.report import FileReport, ParseReport

STREAM_KINDS = ("nmea", "gpsd")
DEVICE_KINDS = {"gnss-csv": "csv", "jsonl": "jsonl"}


def _lines(first_line: int, data: bytes) -> list[tuple[int, bytes]]:
    """Complete lines → (number, line without its end), as the batch line reader gives them."""
    return [(first_line + k, raw.removesuffix(b"\r")) for k, raw in enumerate(data.split(b"\n")[:-1])]


class GnssLines:
    """The GNSS half of a followed file: one per source, across its rotations."""

    def __init__(self, uri: str, report: ParseReport) -> None:
        self.uri = uri
        self.report = report
        self.stream = GrowingStream(report)
        self.device_rows = FixRows()
        self.device: DeviceLines | None = None
        self.no_fix = 0
        self.rows = 0

    def open_file(self, kind: str, fr: FileReport, stem: str, head_lines: list[tuple[int, bytes]]) -> None:
        """A file (or a rotation's next one) of ``kind``; ``head_lines``: its first lines when they are not
        delivered (following from the end), for the header a device export's rows are read by."""
        self.stream.end_file()
        self.device = None
        if kind in STREAM_KINDS:
            self.stream.open_file(fr, stem)
            return
        fmt = DEVICE_KINDS[kind]
        self.device = DeviceLines(fr, self.report, self.device_rows, fmt, stem, {})
        if head_lines and fmt == "csv":
            scratch = DeviceLines(FileReport(fr.file), ParseReport(), FixRows(), fmt, stem, {})
            for number, raw in head_lines:
                scratch.add([(number, raw)])
                if scratch.header is not None:
                    break
            self.device.header, self.device.delimiter = scratch.header, scratch.delimiter

    def add(self, first_line: int, data: bytes) -> list[GnssFix]:
        """Complete lines of the current file → the fixes that settled."""
        if self.device is None:
            self.stream.add(first_line, data)
            return self._fixes(self.stream.settle()[0])
        lines = _lines(first_line, data)
        self.device.fr.lines_read += len(lines)
        self.device.add(lines)
        rows, self.device_rows = self.device_rows, FixRows()
        self.device.rows = self.device_rows
        return self._fixes(rows.frame())

    def end_file(self) -> list[GnssFix]:
        """A stream file is complete (a rotation): lines held for a packet's bytes are read, as at its end."""
        self.stream.end_file()
        return self._fixes(self.stream.settle()[0])

    def finish(self) -> list[GnssFix]:
        """Following ends: every row still open is handed over (as the batch reader ends its last file)."""
        self.stream.end_file()
        return self._fixes(self.stream.settle(final=True)[0])

    def _fixes(self, table: pd.DataFrame) -> list[GnssFix]:
        self.rows += len(table)
        fixes, no_fix = fix_items(self.uri, table)
        self.no_fix += no_fix
        return fixes


def fix_items(uri: str, table: pd.DataFrame) -> tuple[list[GnssFix], int]:
    """GNSS rows (``trackside gnss``'s) → (the fixes for the crossing units, as recorded fixes of ``uri``; how
    many rows were not one: not valid, no time or no position)."""
    if not len(table):
        return [], 0
    t = table["time"].to_numpy("datetime64[ns]").view(np.int64)
    usable = table["valid"].to_numpy(bool) & (t != np.iinfo(np.int64).min)
    usable &= table["lat"].notna().to_numpy() & table["lon"].notna().to_numpy()
    now = time.monotonic()
    picked = table[usable]
    out = []
    for t_ns, device, role, lat, lon, speed, course, file, line, sentence, quality in zip(
        t[usable].tolist(),
        picked["device"].astype(str).tolist(),
        picked["role"].astype(str).tolist(),
        picked["lat"].tolist(),
        picked["lon"].tolist(),
        picked["speed_mps"].tolist(),
        picked["course_deg"].tolist(),
        picked["file"].astype(str).tolist(),
        picked["line"].tolist(),
        picked["sentence"].astype(str).tolist(),
        picked["fix_quality"].astype(str).tolist(),
        strict=True,
    ):  # per fix: an item each, as gpsd's are
        meta = {"file": file, "line": line, "sentence": sentence, "fix_quality": quality}
        out.append(
            GnssFix(
                uri,
                device,
                t_ns,
                lat,
                lon,
                speed,
                course,
                now,
                role=role,
                meta=meta,
                recorded=True,
            )
        )
    return out, int((~usable).sum())
