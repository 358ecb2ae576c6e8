"""Monitoring-centre tables of GNSS telemetry → fixes and crossing states.

All sources give the one fix table of :data:`FIX_COLUMNS` (defined and
documented in ``parsers.gnss.fix_table``); the centre table also
gives crossing states (:data:`CROSSING_COLUMNS`).

Monitoring-centre table (seed 004, Table 1)
-------------------------------------------
::

    TIMESTAMP  Mã tàu  Vĩ độ  Kinh độ  Vận tốc (km/h)  Mã đường ngang 1  Trạng thái kết nối đường ngang 1  …
    2026-01-19 17:06:41  VN0001  20,7  105,9  54,6  11+850  Cảnh báo  …

* delimiter: tab, ``;`` or ``,``, taken from the header line in that order
  of preference; decimal commas (``20,7``) as is with tab or ``;``, inside
  quotes with ``,``;
* headers in Vietnamese or English, any order, case and spacing free:
  ``TIMESTAMP``; ``Mã tàu`` / ``train code``; ``Vĩ độ`` / ``latitude``;
  ``Kinh độ`` / ``longitude``; ``Vận tốc (km/h)`` / ``speed (km/h)`` (a bare
  ``speed`` is km/h here); then any number N of crossing pairs ``Mã đường
  ngang N`` / ``crossing N code`` and ``Trạng thái kết nối đường ngang N`` /
  ``crossing N state``;
* times ``YYYY-MM-DD HH:MM:SS[.fff]`` (or ``DD/MM/YYYY HH:MM:SS``), without a
  zone: read as UTC unless ``utc_offset_h`` says the table is local time
  (the paper does not say; Vietnam is UTC+7);
* crossing codes are kilometre posts ``km+metres``: ``11+850`` is km 11.850
  (``chainage_m`` 11850.0); an optional ``Km`` prefix and a decimal metre
  part are accepted and the code is written back as ``11+850``;
* states: ``Cảnh báo``/``warning``, ``Bình thường``/``normal``, ``Mất kết
  nối``/``disconnected`` → ``warning``, ``normal``, ``disconnected``; any other
  state is kept verbatim in ``state`` and counted in the report's
  ``unknown_labels``; ``state_raw`` always holds the text as written.  A pair
  with neither code nor state gives no crossing row;
* the centre writes newest first; rows come back in time order (stable),
  each with its original line number.

Each data row gives one fix: ``device`` = the train code, ``role`` ``head``
(the centre reports the locomotive unit), ``source`` ``centre``, speed from
km/h, ``valid`` True (the centre gives no fix quality), no course.

Other GNSS sources (each its own module)
----------------------------------------
* receiver streams — NMEA, gpsd JSON, binary UBX/RTCM3/SBF/SiRF packets, mixed
  line by line: ``parsers.gnss.stream``;
* device exports, CSV and JSON lines: ``parsers.gnss.csv``;
* GPX 1.0/1.1 tracks: ``parsers.gnss.gpx``.

Files of any of these formats, each recognised by its content: :func:`parsers.gnss_files.parse_gnss`.
"""

from __future__ import annotations

import datetime as dt
import math
import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from parsers.gnss.fields import RowError
from parsers.gnss.fields import cells_of as _cells
from parsers.gnss.fields import decode_line as _decode
from parsers.gnss.fields import delimiter_of as _delimiter
from parsers.gnss.fields import position as _position
from parsers.gnss.fields import speed as _speed
from parsers.gnss.fields import time_field as _time
from parsers.gnss.fix_table import FixRows, utc_times
from parsers.gnss.headers import CentreHeader, parse_centre_header
from parsers.gnss.lines import open_lines
from parsers.gnss.nmea import KMH_MPS
from parsers.report import ParseReport

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["CROSSING_COLUMNS", "CROSSING_STATES", "parse_centre_table", "parse_crossing_code"]

CROSSING_COLUMNS = ("time", "train", "crossing", "chainage_m", "state", "state_raw", "file", "line")
CROSSING_STATES = ("warning", "normal", "disconnected")

_PEEK_BYTES = 64 * 1024

_EPOCH = dt.date(1970, 1, 1)

_STATE_ALIASES = {
    "cảnh báo": "warning",
    "warning": "warning",
    "bình thường": "normal",
    "normal": "normal",
    "mất kết nối": "disconnected",
    "disconnected": "disconnected",
}
_KM_POST_RE = re.compile(r"(?:km\s*)?(\d{1,4})\s*\+\s*(\d{3}(?:[.,]\d+)?)", re.IGNORECASE)
# ------------------------------------------------------------------- fields


def parse_crossing_code(text: str) -> tuple[str, float]:
    """Kilometre post ``11+850`` (or ``Km11+850``, ``11 + 850,5``) → (``11+850``, 11850.0 m); ValueError otherwise."""
    m = _KM_POST_RE.fullmatch(text.strip())
    if m is None:
        raise ValueError(f"crossing code '{text.strip()}' is not a kilometre post km+metres (e.g. 11+850)")
    km, metres = int(m.group(1)), float(m.group(2).replace(",", "."))
    return f"{km}+{m.group(2).replace(',', '.')}", km * 1000.0 + metres


# ------------------------------------------------------------- centre table


def _file_categorical(files: list[str]) -> pd.Categorical:
    """File names with object categories: a name that is not UTF-8 cannot be an Arrow string."""
    import pandas as pd

    names = list(dict.fromkeys(files))
    index = {name: i for i, name in enumerate(names)}
    codes = np.fromiter((index[f] for f in files), dtype=np.int32, count=len(files))
    return pd.Categorical.from_codes(codes, categories=pd.Index(names, dtype=object))


@dataclass
class CrossingRows:
    """Crossing-state rows being collected."""

    time: list[int] = field(default_factory=list)
    train: list[str] = field(default_factory=list)
    crossing: list[str] = field(default_factory=list)
    chainage_m: list[float] = field(default_factory=list)
    state: list[str] = field(default_factory=list)
    state_raw: list[str] = field(default_factory=list)
    file: list[str] = field(default_factory=list)
    line: list[int] = field(default_factory=list)

    def frame(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(
            {
                "time": utc_times(self.time),
                "train": pd.Categorical(self.train),
                "crossing": pd.Categorical(self.crossing),
                "chainage_m": np.array(self.chainage_m, dtype="float64"),
                "state": pd.Categorical(self.state),
                "state_raw": pd.Series(self.state_raw, dtype=str),
                "file": _file_categorical(self.file),
                "line": np.array(self.line, dtype="int64"),
            },
            columns=list(CROSSING_COLUMNS),
        )


def _centre_row(
    cells: list[str], header: CentreHeader, utc_offset_h: float
) -> tuple[int, str, float, float, float, list[tuple[str, float, str, str]]]:
    if len(cells) != header.width:
        hint = " (a decimal comma in a ','-separated file needs quotes)" if len(cells) > header.width else ""
        raise RowError("fields", f"expected {header.width} fields, found {len(cells)}{hint}")
    col = header.columns
    time_ns = _time(cells[col["time"]], utc_offset_h)
    train = cells[col["train"]].strip()
    if not train:
        raise RowError("train", "train code: empty")
    lat, lon = _position(cells[col["lat"]], cells[col["lon"]])
    speed = _speed(cells[col["speed_kmh"]], "speed (km/h)", KMH_MPS)
    crossings = []
    for n, code_at, state_at in header.crossings:
        code_raw, state_raw = cells[code_at].strip(), cells[state_at].strip()
        if not code_raw and not state_raw:
            continue
        if not code_raw or not state_raw:
            raise RowError("crossing", f"crossing {n}: a code needs a state and a state a code")
        try:
            code, chainage = parse_crossing_code(code_raw)
        except ValueError as exc:
            raise RowError("crossing", f"crossing {n}: {exc}") from None
        state = _STATE_ALIASES.get(" ".join(unicodedata.normalize("NFC", state_raw).casefold().split()), state_raw)
        crossings.append((code, chainage, state, state_raw))
    return time_ns, train, lat, lon, speed, crossings


def parse_centre_file(
    path: Path, report: ParseReport, fixes: FixRows, crossings: CrossingRows, utc_offset_h: float
) -> None:
    fr, lines = open_lines(path, report)
    header: CentreHeader | None = None
    delimiter = "\t"
    for number, raw in lines:
        text = _decode(raw, fr)
        if not text.strip() or text.lstrip().startswith("#"):
            fr.blank += 1
            continue
        if header is None:
            delimiter = _delimiter(text)
            try:
                header = parse_centre_header(_cells(text, delimiter))
            except ValueError as exc:
                reason = f"not the centre table header: {exc}; expected TIMESTAMP, train code, latitude, …"
                report.reject(fr, number, "header", reason, raw)
                continue
            fr.blank += 1  # the header: no record, nothing lost
            continue
        try:
            time_ns, train, lat, lon, speed, states = _centre_row(_cells(text, delimiter), header, utc_offset_h)
        except RowError as exc:
            report.reject(fr, number, exc.category, exc.reason, raw)
            continue
        fr.records += 1
        fixes.add(
            time_ns=time_ns,
            device=train,
            role="head",
            lat=lat,
            lon=lon,
            speed_mps=speed,
            course_deg=math.nan,
            valid=not math.isnan(lat),
            source="centre",
            sentence="",
            file=fr.file,
            line=number,
        )
        for code, chainage, state, state_raw in states:
            if state not in CROSSING_STATES:
                report.unknown_labels[f"crossing state '{state_raw}'"] += 1
            crossings.time.append(time_ns)
            crossings.train.append(train)
            crossings.crossing.append(code)
            crossings.chainage_m.append(chainage)
            crossings.state.append(state)
            crossings.state_raw.append(state_raw)
            crossings.file.append(fr.file)
            crossings.line.append(number)


def in_time_order(frame: pd.DataFrame) -> pd.DataFrame:
    """Stable sort by time, unknown times last."""
    return frame.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)


def parse_centre_table(
    paths: Iterable[Path | str], *, utc_offset_h: float = 0.0
) -> tuple[pd.DataFrame, pd.DataFrame, ParseReport]:
    """Parse monitoring-centre tables: (fixes in time order, crossing states in time order, report).

    ``utc_offset_h``: the tables' local time zone, hours east of UTC (times
    carry no zone; default: they are UTC).
    """
    report = ParseReport()
    fixes, crossings = FixRows(), CrossingRows()
    for path in paths:
        parse_centre_file(Path(path), report, fixes, crossings, utc_offset_h)
    report.check()
    return fixes.frame(time_order=True, release=True), in_time_order(crossings.frame()), report
