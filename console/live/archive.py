"""``follow --archive DIR``: what is followed is kept, and ingested into the archive.

Followed diagnostic logs are appended, exactly as read, to spool files beside
the archive (``DIR.live/``: one per followed file, one per rotation); GNSS
fixes (gpsd, MQTT, followed NMEA or device files) go to a device CSV
(``time,device,role,lat,lon,speed,course``, the stream form ``trackside
gnss`` reads); CAN frames (a bus, or count frames of a followed CAN log) to
a candump log, and sensor frames of a followed frame log to a frame log, the
forms ``trackside frames`` reads.  Every
``INGEST_EVERY_S`` and at the end, the spool is ingested with the archive's
own ingest (``console.archive.ingest.run_ingest``), which reads a grown file
from where the last ingest stopped: nothing is stored twice, and the
archive holds what the batch commands would read from the spool.

A followed log read again (``follow --from-start --archive`` after a restart)
repeats, from its first line, what an earlier run spooled: while a file's
lines (or fixes, frames) are the same bytes its spool file holds from its
start, they are counted (:attr:`LiveArchiver.repeated_lines`) and not spooled
again; from the first block that differs (the log was rotated or rewritten),
or past the spool's end, they are appended.  A file read from its first line is
compared with each spool file of its followed path (one per rotation), since a
restarted run numbers the rotations again from the current file.
"""

from __future__ import annotations

import errno
import math
import os
import re
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from console.analysis.timefmt import iso
from console.inputs.base import CanFrame, FrameRows, GnssFix, Item, LineBlock

INGEST_EVERY_S = 30.0
FLUSH_LINES = 4096  # CAN frames come one by one: written in blocks
_ROTATION = re.compile(r"#\d+$")  # the Nth file after a rotation: LineBlock.file's suffix
FIXES_HEADER = b"time,device,role,lat,lon,speed,course\n"
_HEX = np.array([f"{b:02X}" for b in range(256)], dtype=object)


def candump_line(frame: CanFrame) -> str:
    """One frame as ``candump -l`` writes it: ``(1622974500.000000) can0 187#03A5E80300``."""
    s, ns = divmod(frame.t_ns, 1_000_000_000)
    ident = f"{frame.arbitration_id:08X}" if frame.extended else f"{frame.arbitration_id:03X}"
    channel = "".join(c for c in frame.channel if c.isalnum() or c in "-_.") or "can0"
    payload = "R" if frame.remote else frame.data.hex().upper()
    return f"({s}.{ns // 1000:06d}) {channel} {ident}#{payload}\n"


def frame_rows_text(rows: FrameRows) -> str:
    """Count frames read from a followed log, as a log of their kind (candump for CAN, frame lines else)."""
    t = np.asarray(rows.time_ns, np.int64)
    hexes = _HEX[rows.status] + _HEX[rows.byte2]
    if rows.kind == "can" and rows.can_id is not None and rows.total is not None and rows.seq is not None:
        s, us = t // 1_000_000_000, (t % 1_000_000_000) // 1000
        stamp = pd.Series(s).astype(str) + "." + pd.Series(us).astype(str).str.zfill(6)
        ident = pd.Series(rows.can_id).map("{:03X}".format)
        total = np.asarray(rows.total, np.int64)
        payload = hexes + _HEX[total & 0xFF] + _HEX[total >> 8] + _HEX[rows.seq]
        lines = "(" + stamp + ") log " + ident + "#" + pd.Series(payload)
    else:
        stamp = pd.Series(np.datetime_as_string(t.view("datetime64[ns]"), unit="ns"))
        lines = stamp + " " + pd.Series(rows.sensor).astype(str) + " " + pd.Series(hexes)
    return "".join((lines + "\n").tolist())


def _safe(key: str) -> str:
    """A followed source's name as a spool file's (its last 120 characters, unusual ones as ``_``)."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in key)[-120:]


def spool_dir(archive: Path) -> Path:
    return archive.with_name(archive.name + ".live")


class LiveArchiver:
    """Spools followed items and ingests the spool into the archive now and then."""

    def __init__(self, archive: Path, layout: str | None = None) -> None:
        from console.archive.store import ArchiveError, ensure_layout

        # Absolute: "" and "." name a directory whose spool needs a name of its own.
        self.archive = archive = Path(os.path.abspath(archive))
        self.layout = layout
        # Checked before anything is followed (a file, a folder of other files, no permission: ArchiveError),
        # not at the first ingest a minute on, which could only log it.
        ensure_layout(archive)
        self.spool = spool_dir(archive)
        try:
            self.spool.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ArchiveError(f"{self.spool}: cannot spool there ({exc.strerror or exc})") from None
        self._files: dict[str, Path] = {}
        self._last_ingest = time.monotonic()
        self._thread: threading.Thread | None = None
        self._can_lines: dict[str, list[str]] = {}  # by source: frames not written yet
        self.ingests = 0
        self.errors: list[str] = []
        # Per followed file: how far its lines have matched its spool file's bytes from their start (an earlier
        # run's); -1: appended to since this run began (no longer compared).
        self._matched: dict[Path, int] = {}
        self.repeated_lines = 0
        self._unwritable: set[Path] = set()
        self.spool_errors: list[str] = []
        self.unspooled_lines = 0  # not spooled (and so never archived): their spool file could not be written

    def _path(self, key: str, suffix: str) -> Path:
        p = self._files.get(key)
        if p is None:
            p = self._files[key] = self.spool / f"{_safe(key)}{suffix}"
        return p

    def _log_path(self, item: LineBlock) -> Path:
        """The spool file of a followed log's lines.  Read from its first line, a file goes to the spool file of
        its followed path whose content it repeats from the start, else to a new one: a run's rotation count
        (``x.log#2``) starts again with each run, so a restarted run's names do not say which file is which."""
        p = self._files.get(item.file)
        if p is not None:
            return p
        if item.first_line != 1:
            return self._path(item.file, ".log")  # the middle of a file: nothing to compare its start with
        base = _safe(_ROTATION.sub("", item.file))
        taken = set(self._files.values())
        n = 1
        while True:
            p = self.spool / (f"{base}.log" if n == 1 else f"{base}_{n}.log")
            if p not in taken and (not p.exists() or self._repeats_start(p, item.data)):
                self._files[item.file] = p
                return p
            n += 1

    def _repeats_start(self, path: Path, data: bytes) -> bool:
        try:
            with path.open("rb") as f:
                held = f.read(len(data))
        except OSError:
            return False
        return data.startswith(held)

    def __call__(self, item: Item) -> None:
        if isinstance(item, LineBlock):
            self._append(self._log_path(item), item.data, first_line=item.first_line)
        elif isinstance(item, GnssFix) and not (math.isnan(item.lat_deg) or math.isnan(item.lon_deg)):
            role = item.role or ("eot" if item.device.endswith("-eot") else "head")
            speed = "" if math.isnan(item.speed_mps) else f"{item.speed_mps:.2f}"
            course = "" if math.isnan(item.course_deg) else f"{item.course_deg:.1f}"
            device = f"{item.train}-{role}" if item.train else item.device
            line = f"{iso(item.t_fix_ns)},{device},{role},{item.lat_deg:.7f},{item.lon_deg:.7f},{speed},{course}\n"
            self._append(self._path("gnss-" + item.source, ".csv"), line.encode(), header=FIXES_HEADER)
        elif isinstance(item, CanFrame):
            pending = self._can_lines.setdefault(item.source, [])
            pending.append(candump_line(item))
            if len(pending) >= FLUSH_LINES:
                self._write_can()
        elif isinstance(item, FrameRows) and len(item):
            key, suffix = ("can-", ".log") if item.kind == "can" else ("frames-", ".txt")
            self._append(self._path(key + item.source, suffix), frame_rows_text(item).encode())

    def _append(self, path: Path, data: bytes, header: bytes = b"", first_line: int | None = None) -> None:
        """``data`` (whole lines) to the spool file at ``path``, less what it repeats (see the module).

        A spool file that cannot be written (a full disk) takes nothing more in this run, so the archive
        never holds a log with a gap in it; the lines it did not take are counted, and it is said where
        they start (``first_line``: the block's first line in the followed file)."""
        if path in self._unwritable:
            self.unspooled_lines += data.count(b"\n")
            return
        try:
            if header and not path.exists():
                with path.open("ab") as f:
                    f.write(header)
            data = self._not_spooled(path, data, len(header))
            if data:
                with path.open("ab") as f:
                    f.write(data)
        except OSError as exc:
            self._unwritable.add(path)
            self.unspooled_lines += data.count(b"\n")
            why = "no space left on device" if exc.errno == errno.ENOSPC else exc.strerror or str(exc)
            where = f" from line {first_line} of the followed file" if first_line is not None else ""
            self.spool_errors.append(f"{path}: cannot spool ({why}): not archived{where} on")

    def _not_spooled(self, path: Path, data: bytes, start: int) -> bytes:
        """The part of ``data`` the spool file does not hold yet at the same place: this run's lines are compared
        with the file's from ``start`` (past its header) until one differs or the file ends."""
        at = self._matched.get(path, start)
        if at < 0:
            return data
        try:
            with path.open("rb") as f:
                f.seek(at)
                held = f.read(len(data))
        except FileNotFoundError:
            held = b""
        same = len(held) if data.startswith(held) else 0
        if same == len(data):
            self._matched[path] = at + same
            self.repeated_lines += data.count(b"\n")
            return b""
        # Differs, or the spool ends within the block: from here on it is new (a mismatch keeps the whole block).
        self._matched[path] = -1
        if same and held.endswith(b"\n"):  # the spool's end, on a line's end: the lines after it are new
            self.repeated_lines += held.count(b"\n")
            return data[same:]
        return data

    def _write_can(self) -> None:
        for source, lines in self._can_lines.items():
            if lines:
                self._append(self._path("can-" + source, ".log"), "".join(lines).encode())
                lines.clear()

    def summary(self) -> dict[str, Any]:
        """What the run's summary says of the archiving, where there is something to say."""
        out: dict[str, Any] = {}
        if self.repeated_lines:  # lines an earlier run had spooled, read again: not stored twice
            out["archive_repeated_lines"] = self.repeated_lines
        if self.spool_errors:  # a spool file that could not be written took nothing more: said, and how much
            out["archive_spool_errors"] = self.spool_errors
            out["archive_lines_not_spooled"] = self.unspooled_lines
        if self.errors:  # a failed ingest of the spool (a full disk…): the spool keeps it for the next one
            out["archive_errors"] = list(dict.fromkeys(self.errors))
        return out

    def tick(self) -> None:
        """Ingest in the background every INGEST_EVERY_S (never two at once)."""
        self._write_can()
        if time.monotonic() - self._last_ingest < INGEST_EVERY_S:
            return
        if self._thread is not None and self._thread.is_alive():
            return
        self._last_ingest = time.monotonic()
        self._thread = threading.Thread(target=self.ingest, kwargs={"wait": False}, daemon=True)
        self._thread.start()

    def ingest(self, wait: bool = True) -> None:
        from console.archive.ingest import run_ingest
        from console.archive.store import ArchiveBusy, ArchiveError

        files = sorted(p for p in self.spool.iterdir() if p.is_file())
        if not files:
            return
        try:
            run_ingest(files, self.archive, layout=self.layout, wait=wait)
            self.ingests += 1
        except ArchiveBusy:
            pass  # another ingest is writing: the next turn takes it
        except ArchiveError as exc:
            self.errors.append(str(exc))
        except OSError as exc:  # as `trackside ingest` says it (pyarrow's text of ENOSPC is two errnos long)
            why = "no space left on device" if exc.errno == errno.ENOSPC else exc.strerror or str(exc)
            self.errors.append(f"{exc.filename or self.archive}: {why}: archive unchanged")

    def finish(self) -> None:
        if self._thread is not None:
            self._thread.join()
        self._write_can()
        self.ingest(wait=True)
