"""Recorded CAN traffic → the frame table, every frame in it by kind.

Seed 000's counts travel to the control centre over CAN.  Logs are read
with python-can's own readers: candump ``.log``, Vector ``.asc`` and
``.blf``, PEAK ``.trc`` (versions 1.0, 1.1, 1.3, 2.0, 2.1; see
:mod:`parsers.frames.trc`), plain or gzip.  Standard id ``0x180 + n`` (n = 1..127)
with DLC 5 is node n's count frame:
``[status, count or 0xA5, total lo, total hi, seq]`` (``docs/frames.md``).

Every CAN frame becomes a row, with its ``kind``: ``count``, ``foreign``
(other ids, extended ids), ``remote`` (RTR) or ``error``.  Only count rows
carry a sensor and status bits; the other kinds keep their id, DLC and
data.  So ``records`` counts CAN frames of every kind, and the
:class:`CanFileReport` counts them by kind; ``blank`` is what is not a
frame (headers, comments, bus events).  A count-id frame with another DLC,
a frame whose time or id is out of range, and a line the reader cannot
read are rejected with file, line and reason.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from parsers.frames.can_blf import read_blf
from parsers.frames.can_decode import decode_can
from parsers.frames.can_format import can_format
from parsers.frames.can_messages import CanMessages
from parsers.frames.can_report import FRAME_KINDS, CanFileReport
from parsers.frames.can_text import read_text_can
from parsers.frames.table import FrameColumns, finish_table
from parsers.report import ParseReport


def parse_can(
    paths: Iterable[Path | str], *, sensor_names: Mapping[int, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Read recorded CAN traffic (candump .log, .asc, .blf, .trc; plain or gzip) into a frame table.

    The table has the columns of ``parse_frames`` plus ``total`` (uint16,
    cumulative axles, wraps), ``seq`` (uint8, wraps), ``can_id`` (uint32),
    ``kind`` (category: count, foreign, remote, error), ``extended`` (29-bit
    id), ``dlc`` and ``data`` (the payload in hex).  One row per CAN frame;
    only count rows have a ``sensor`` (node n → ``sensor_names[n]``, else
    :func:`default_sensor_name`) and meaningful status, count, total and seq
    (0 elsewhere).  ``line`` is the text line (candump, ASC, TRC) or the
    frame's position in the file (BLF).  A file that cannot be read at all
    raises :class:`parsers.sources.InputError`.
    """
    names = dict(sensor_names or {})
    report = ParseReport()
    cols = FrameColumns()
    files = [str(Path(p)) for p in paths]
    for file_id, name in enumerate(files):
        path = Path(name)
        fmt = can_format(path)
        fr = CanFileReport(file=name, format=fmt)
        report.files.append(fr)
        msgs = CanMessages()
        if fmt == "blf":
            read_blf(path, fr, report, msgs)
        else:
            read_text_can(path, fmt, fr, report, msgs)
        decode_can(msgs, file_id, fr, report, cols, names)
    kind = cols.concat("kind", np.int8)
    extra = {
        "total": cols.concat("total", np.uint16),
        "seq": cols.concat("seq", np.uint8),
        "can_id": cols.concat("can_id", np.uint32),
        "kind": pd.Categorical.from_codes(kind, categories=pd.Index(FRAME_KINDS, dtype="str")),
        "extended": cols.concat("extended", bool),
        "dlc": cols.concat("dlc", np.uint8),
        "data": cols.concat("data", object),
    }
    return finish_table(cols, files, report, extra), report


def count_frames_only(frames: pd.DataFrame) -> pd.DataFrame:
    """The count frames of a frame table (a text-frame table is all count frames)."""
    if "kind" not in frames.columns:
        return frames
    return frames[frames["kind"] == "count"]
