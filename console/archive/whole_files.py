"""The inputs read whole into a table of their own (GNSS fixes, voltages, sensor and CAN frames), not by bytes.

Their parsers keep state across lines, so a grown file is read again whole (unlike a diagnostic log,
:mod:`console.archive.parse_pass`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from parsers.report import ParseReport

# Kinds the archive stores, by the report's recognition (console.inputs.recognise.recognise).
STORED_ELSEWHERE = {"nmea": "fixes", "gnss-csv": "fixes", "gnss-jsonl": "fixes", "centre": "fixes"}


def read_whole(source: Path, kind: str, shown: str, file_seq: int) -> tuple[str, pa.Table, ParseReport]:
    """(the table it goes to, its rows as stored, the parse's report) of one file of ``kind``."""
    report: ParseReport
    if kind in STORED_ELSEWHERE:
        from parsers.gnss_files import parse_gnss

        table, report, _states = parse_gnss([source])
        name = "fixes"
    elif kind == "voltages":
        from parsers.voltages import read_voltages

        table, report = read_voltages([source])
        name = "voltages"
    elif kind == "frames":
        from parsers.frames.sensor import parse_frames

        table, report = parse_frames([source])
        name = "frames"
    else:
        from parsers.frames.can import parse_can

        table, report = parse_can([source])
        name = "frames"
    table = table.copy()
    if name == "fixes":
        # The archive's one time type: naive UTC, nanoseconds (TIMESTAMP_NS), as every other table's times.
        table["time"] = _naive_utc(table["time"])
    if "file" in table.columns:
        table["file"] = shown
    table["file_seq"] = np.int32(file_seq)
    return name, pa.Table.from_pandas(table, preserve_index=False), report


def _naive_utc(times: Any) -> Any:
    """Zone-aware times (the GNSS parser's, UTC) as naive UTC; naive ones as they are."""
    if getattr(times.dt, "tz", None) is None:
        return times
    return times.dt.tz_convert("UTC").dt.tz_localize(None)
