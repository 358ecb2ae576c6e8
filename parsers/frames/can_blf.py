"""BLF CAN logs → CAN frames through python-can's BLF reader, timed by the header's wall clock."""

from __future__ import annotations

import datetime as dt
import struct
import zlib
from pathlib import Path
from typing import BinaryIO, cast

import can

from parsers.frames.can_clock import wall_ns
from parsers.frames.can_messages import READER_ERRORS, CanMessages, candump_text, collect_frame
from parsers.frames.can_report import CanFileReport
from parsers.report import ParseReport
from parsers.sources import InputError, open_input

_BLF_HEADER = struct.Struct("<4sLBBBBBBBBQQLL8H8H")


def _blf_start_ns(path: Path) -> int:
    """The BLF header's start time (SYSTEMTIME, read as naive wall clock) in ns."""
    stream, raw, _ = open_input(path)
    try:
        head = stream.read(_BLF_HEADER.size)
    finally:
        stream.close()
        raw.close()
    fields = _BLF_HEADER.unpack(head)
    year, month, _, day, hour, minute, second, ms = fields[14:22]
    try:
        return wall_ns(dt.datetime(year, month, day, hour, minute, second, ms * 1000))
    except ValueError:
        return 0


def read_blf(path: Path, fr: CanFileReport, report: ParseReport, msgs: CanMessages) -> None:
    stream, raw, info = open_input(path)
    fr.encoding, fr.compressed = "binary", info.compressed
    try:
        start_ns = _blf_start_ns(path)
        reader = can.BLFReader(cast(BinaryIO, stream))
        start_s = reader.start_timestamp
        for msg in reader:
            fr.lines_read += 1
            # BLF times: the header's wall clock plus the object's offset from it.
            msg.timestamp -= start_s
            problem = collect_frame(msgs, msg, fr.lines_read, start_ns, None)
            if problem is not None:
                report.reject(fr, fr.lines_read, *problem, candump_text(msg))
        fr.bytes_read = path.stat().st_size  # the reader closes the file when done
    except (can.io.blf.BLFParseError, struct.error, zlib.error, EOFError, OSError, *READER_ERRORS) as exc:
        raise InputError(f"{path}: not a readable BLF file ({type(exc).__name__}: {exc or 'corrupt'})") from None
    finally:
        stream.close()
        raw.close()
