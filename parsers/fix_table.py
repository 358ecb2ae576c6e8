"""The GNSS fix table every GNSS source gives, and the compact builder behind it.

Columns (:data:`FIX_COLUMNS`)
-----------------------------
``time``        datetime64[ns, UTC]; NaT when unknown.
``device``      category: the file name stem, a line's device tag, or the
                device column / key of a device stream.
``role``        category ``"head"``, ``"eot"`` or ``""`` (unknown).
``lat, lon``    float64 degrees, south and west negative; NaN when absent.
``speed_mps``   float64 m/s over ground; **NaN when the source gives none**
                (never 0: a missing speed is not a standstill).
``course_deg``  float64 degrees true; NaN when the source gives none.
``valid``       bool: a real position fix (see ``fix_quality``).
``source``      category ``"nmea"``, ``"csv"``, ``"jsonl"``, ``"centre"``,
                ``"gpsd"`` (gpsd JSON TPV), ``"gpx"`` or ``"ubx"`` (UBX-NAV-PVT).
``sentence``    category: the NMEA sentences (and gpsd TPV, UBX NAV-PVT) merged
                into the row, in the order RMC, GGA, GLL, GNS, VTG, TPV, PVT joined by ``+``
                (``"RMC+GGA"``); ``""`` for sources that are not NMEA/gpsd.
``file, line``  category and int64: where the row (its first sentence) came from.
``fix_quality`` category: ``"gnss"`` a satellite fix (any augmentation),
                ``"dead_reckoning"`` dead-reckoned / propagated / estimated
                (``valid`` stays True: the source calls it a fix, but a
                consumer may weigh it less), ``"no_fix"``, or ``""`` when the
                source says nothing about the quality.

Memory: rows are kept in typed arrays and the repeated strings (device,
file) as codes into one table each, so a file of a million distinct
devices costs a few tens of bytes per row, not a Python object per field.
"""

from __future__ import annotations

import itertools
from array import array
from collections.abc import Mapping

import numpy as np
import pandas as pd

FIX_COLUMNS = (
    "time",
    "device",
    "role",
    "lat",
    "lon",
    "speed_mps",
    "course_deg",
    "valid",
    "source",
    "sentence",
    "file",
    "line",
    "fix_quality",
)
ROLES = ("head", "eot", "")
SOURCES = ("nmea", "csv", "jsonl", "centre", "gpsd", "gpx", "ubx")
SENTENCE_KINDS = ("RMC", "GGA", "GLL", "GNS", "VTG", "TPV", "PVT")
SENTENCES = (
    *("+".join(c) for n in range(1, len(SENTENCE_KINDS) + 1) for c in itertools.combinations(SENTENCE_KINDS, n)),
    "",
)
FIX_QUALITIES = ("gnss", "dead_reckoning", "no_fix", "")
ROLE_DTYPE = pd.CategoricalDtype(list(ROLES))
SOURCE_DTYPE = pd.CategoricalDtype(list(SOURCES))
SENTENCE_DTYPE = pd.CategoricalDtype(list(SENTENCES))
FIX_QUALITY_DTYPE = pd.CategoricalDtype(list(FIX_QUALITIES))

NAT_NS = int(np.iinfo(np.int64).min)  # the int64 value of NaT

_ROLE_CODE = {r: i for i, r in enumerate(ROLES)}
_SOURCE_CODE = {s: i for i, s in enumerate(SOURCES)}
_SENTENCE_CODE = {s: i for i, s in enumerate(SENTENCES)}
_QUALITY_CODE = {q: i for i, q in enumerate(FIX_QUALITIES)}


def merged_sentence(a: str, b: str) -> str:
    """``"GGA"`` + ``"RMC"`` → ``"RMC+GGA"`` (canonical order, no repeats)."""
    parts = set(a.split("+")) | set(b.split("+"))
    return "+".join(k for k in SENTENCE_KINDS if k in parts)


class _Codes:
    """Strings interned as small integer codes, in order of first sight."""

    def __init__(self) -> None:
        self.index: dict[str, int] = {}
        self.codes = array("i")

    def code_of(self, value: str) -> int:
        code = self.index.get(value)
        if code is None:
            code = self.index[value] = len(self.index)
        return code

    def append(self, value: str) -> None:
        self.codes.append(self.code_of(value))

    def categorical(self) -> pd.Categorical:
        """The codes as a Categorical whose categories are the values used, in order of first appearance
        (whatever order they were interned in: rows may be read in batches and put back in line order)."""
        names = list(self.index)
        codes = np.frombuffer(self.codes, dtype=np.int32) if len(self.codes) else np.zeros(0, np.int32)
        used, first = np.unique(codes, return_index=True)
        order = used[np.argsort(first, kind="stable")]
        renumber = np.zeros(len(names), np.int32)
        renumber[order] = np.arange(len(order), dtype=np.int32)
        categories = pd.Index([names[i] for i in order], dtype=object)
        return pd.Categorical.from_codes(renumber[codes], categories=categories)


class FixRows:
    """Fix rows being collected, column by column (``time`` in ns, NaT as :data:`NAT_NS`).

    Rows can be amended in place (:meth:`merge`) while they are collected, so
    that the sentences of one epoch become one row.
    """

    def __init__(self) -> None:
        self.time = array("q")
        self.device = _Codes()
        self.role = array("b")
        self.lat = array("d")
        self.lon = array("d")
        self.speed_mps = array("d")
        self.course_deg = array("d")
        self.valid = array("b")
        self.source = array("b")
        self.sentence = array("b")
        self.file = _Codes()
        self.line = array("q")
        self.fix_quality = array("b")

    def add(
        self,
        *,
        time_ns: int,
        device: str,
        role: str,
        lat: float,
        lon: float,
        speed_mps: float,
        course_deg: float,
        valid: bool,
        source: str,
        sentence: str,
        file: str,
        line: int,
        fix_quality: str = "",
    ) -> int:
        """Append one row; returns its index."""
        self.time.append(time_ns)
        self.device.append(device)
        self.role.append(_ROLE_CODE[role])
        self.lat.append(lat)
        self.lon.append(lon)
        self.speed_mps.append(speed_mps)
        self.course_deg.append(course_deg)
        self.valid.append(valid)
        self.source.append(_SOURCE_CODE[source])
        self.sentence.append(_SENTENCE_CODE[sentence])
        self.file.append(file)
        self.line.append(line)
        self.fix_quality.append(_QUALITY_CODE[fix_quality])
        return len(self.line) - 1

    def extend(
        self,
        *,
        time_ns: np.ndarray,
        device_names: list[str],
        device_code: np.ndarray,
        role: np.ndarray,
        lat: np.ndarray,
        lon: np.ndarray,
        speed_mps: np.ndarray,
        course_deg: np.ndarray,
        valid: np.ndarray,
        source: str,
        file: str,
        line: np.ndarray,
        fix_quality: np.ndarray,
    ) -> None:
        """Append rows given as columns (``device_code`` indexes ``device_names``): no Python loop per row."""
        n = len(line)
        if n == 0:
            return
        global_codes = np.array([self.device.code_of(d) for d in device_names], dtype=np.int32)
        self.device.codes.frombytes(global_codes[np.asarray(device_code)].astype(np.int32).tobytes())
        self.file.codes.frombytes(np.full(n, self.file.code_of(file), np.int32).tobytes())

        def small(values: np.ndarray, categories: tuple[str, ...]) -> bytes:
            codes = pd.Categorical(values, categories=list(categories)).codes
            assert (codes >= 0).all(), "a value outside its categories"
            return codes.astype(np.int8).tobytes()

        self.time.frombytes(np.asarray(time_ns, np.int64).tobytes())
        self.role.frombytes(small(role, ROLES))
        for target, values in (
            (self.lat, lat),
            (self.lon, lon),
            (self.speed_mps, speed_mps),
            (self.course_deg, course_deg),
        ):
            target.frombytes(np.asarray(values, np.float64).tobytes())
        self.valid.frombytes(np.asarray(valid, bool).astype(np.int8).tobytes())
        self.source.frombytes(np.full(n, _SOURCE_CODE[source], np.int8).tobytes())
        self.sentence.frombytes(np.full(n, _SENTENCE_CODE[""], np.int8).tobytes())
        self.line.frombytes(np.asarray(line, np.int64).tobytes())
        self.fix_quality.frombytes(small(fix_quality, FIX_QUALITIES))

    def sort_by_line_from(self, start: int) -> None:
        """Put rows ``start:`` (one file's) in line order, stably."""
        lines = np.frombuffer(self.line[start:], dtype=np.int64)
        order = np.argsort(lines, kind="stable")
        if (order == np.arange(len(order))).all():
            return
        for name in (
            "time",
            "role",
            "lat",
            "lon",
            "speed_mps",
            "course_deg",
            "valid",
            "source",
            "sentence",
            "line",
            "fix_quality",
        ):
            column = getattr(self, name)
            values = np.frombuffer(column[start:], dtype=np.dtype(column.typecode if column.typecode != "b" else "i1"))
            column[start:] = array(column.typecode, values[order].tobytes())
        for codes in (self.device.codes, self.file.codes):
            values = np.frombuffer(codes[start:], dtype=np.int32)
            codes[start:] = array("i", values[order].tobytes())

    def subset(self, rows: np.ndarray) -> FixRows:
        """The rows at ``rows`` (indices, in the order given) as new FixRows sharing the string tables."""
        out = FixRows()
        out.device.index, out.file.index = self.device.index, self.file.index
        idx = np.asarray(rows, np.int64)
        for name in (
            "time",
            "role",
            "lat",
            "lon",
            "speed_mps",
            "course_deg",
            "valid",
            "source",
            "sentence",
            "line",
            "fix_quality",
        ):
            column = getattr(self, name)
            values = np.frombuffer(column, dtype=np.dtype(column.typecode if column.typecode != "b" else "i1"))
            getattr(out, name).frombytes(values[idx].tobytes() if len(column) else b"")
        for mine, theirs in ((self.device, out.device), (self.file, out.file)):
            values = np.frombuffer(mine.codes, dtype=np.int32) if len(mine.codes) else np.zeros(0, np.int32)
            theirs.codes.frombytes(values[idx].astype(np.int32).tobytes())
        return out

    def sentence_at(self, i: int) -> str:
        return SENTENCES[self.sentence[i]]

    def quality_at(self, i: int) -> str:
        return FIX_QUALITIES[self.fix_quality[i]]

    def set_quality(self, i: int, quality: str) -> None:
        self.fix_quality[i] = _QUALITY_CODE[quality]

    def set_sentence(self, i: int, sentence: str) -> None:
        self.sentence[i] = _SENTENCE_CODE[sentence]

    def __len__(self) -> int:
        return len(self.line)

    def frame(self) -> pd.DataFrame:
        """The rows as a fix table with the documented dtypes."""

        def codes(a: array[int]) -> np.ndarray:
            return np.frombuffer(a, dtype=np.int8) if len(a) else np.zeros(0, np.int8)

        def floats(a: array[float]) -> np.ndarray:
            return np.frombuffer(a, dtype=np.float64).copy() if len(a) else np.zeros(0)

        return pd.DataFrame(
            {
                "time": utc_times(np.frombuffer(self.time, dtype=np.int64) if len(self.time) else []),
                "device": self.device.categorical(),
                "role": pd.Categorical.from_codes(codes(self.role), dtype=ROLE_DTYPE),
                "lat": floats(self.lat),
                "lon": floats(self.lon),
                "speed_mps": floats(self.speed_mps),
                "course_deg": floats(self.course_deg),
                "valid": codes(self.valid).astype(bool),
                "source": pd.Categorical.from_codes(codes(self.source), dtype=SOURCE_DTYPE),
                "sentence": pd.Categorical.from_codes(codes(self.sentence), dtype=SENTENCE_DTYPE),
                "file": self.file.categorical(),
                "line": np.frombuffer(self.line, dtype=np.int64).copy() if len(self.line) else np.zeros(0, np.int64),
                "fix_quality": pd.Categorical.from_codes(codes(self.fix_quality), dtype=FIX_QUALITY_DTYPE),
            },
            columns=list(FIX_COLUMNS),
        )


def utc_times(ns: list[int] | np.ndarray) -> pd.DatetimeIndex:
    """int64 ns since the epoch (NaT as :data:`NAT_NS`) → datetime64[ns, UTC]."""
    return pd.DatetimeIndex(np.asarray(ns, dtype="int64").view("datetime64[ns]")).tz_localize("UTC")


def check_roles(roles: Mapping[str, str] | None) -> dict[str, str]:
    """Validate a device → role mapping; ValueError naming the bad entry."""
    out = dict(roles or {})
    for device, role in out.items():
        if role not in ROLES:
            raise ValueError(f"device '{device}': role '{role}' is not one of 'head', 'eot' or '' (unknown)")
    return out
