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
                ``"gpsd"`` (gpsd JSON TPV), ``"gpx"``, ``"ubx"`` (u-blox UBX
                messages) or ``"sbf"`` (Septentrio SBF blocks).
``sentence``    category: the NMEA sentences, gpsd TPV, UBX messages and SBF
                blocks merged into the row, in the order of
                :data:`SENTENCE_KINDS`, joined by ``+`` (``"RMC+GGA"``,
                ``"NAV-SOL+NAV-TIMEGPS"``); ``""`` for sources that are none of these.
                The categories are :data:`SENTENCES` (every NMEA/TPV combination),
                then the other combinations the rows use.
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
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast, overload

import numpy as np

from parsers.dictionary import StringDictionary

if TYPE_CHECKING:
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
# FixRows' columns held as numbers (device and file are string codes of their own).
_NUMERIC_COLUMNS = tuple(c for c in FIX_COLUMNS if c not in ("device", "file"))


def _as_numpy(column: array) -> np.ndarray:
    """A column's values as a numpy view (array's "b" is numpy's int8)."""
    return np.frombuffer(column, dtype=np.dtype(column.typecode if column.typecode != "b" else "i1"))


ROLES = ("head", "eot", "")
SOURCES = ("nmea", "csv", "jsonl", "centre", "gpsd", "gpx", "ubx", "sbf")
_NMEA_KINDS = ("RMC", "GGA", "GLL", "GNS", "VTG", "TPV")
# Binary messages that give a row its position, velocity, time or fix status (parsers.gnss.binary).
UBX_KINDS = (
    "NAV-PVT",
    "HNR-PVT",
    "NAV-PVAT",
    "NAV-SOL",
    "NAV-POSLLH",
    "NAV-HPPOSLLH",
    "NAV-POSECEF",
    "NAV-VELNED",
    "NAV-VELECEF",
    "NAV-STATUS",
    "NAV-TIMEGPS",
    "NAV-TIMEUTC",
    "NAV-TIMELS",
    "LOG-BATCH",
    "LOG-RETRIEVEPOS",
)
SBF_KINDS = ("PVTGeodetic", "PVTCartesian", "ReceiverTime", "GPSUtc")
BINARY_KINDS = (*UBX_KINDS, *SBF_KINDS)
SENTENCE_KINDS = (*_NMEA_KINDS, *BINARY_KINDS)
assert len(SENTENCE_KINDS) <= 31, "a row's sentence is an int32 bit mask"
# Every combination of the NMEA kinds (a fixed list: the column's first categories).
SENTENCES = (
    *("+".join(c) for n in range(1, len(_NMEA_KINDS) + 1) for c in itertools.combinations(_NMEA_KINDS, n)),
    "",
)
FIX_QUALITIES = ("gnss", "dead_reckoning", "no_fix", "")

NAT_NS = int(np.iinfo(np.int64).min)  # the int64 value of NaT

_ROLE_CODE = {r: i for i, r in enumerate(ROLES)}
_SOURCE_CODE = {s: i for i, s in enumerate(SOURCES)}
_QUALITY_CODE = {q: i for i, q in enumerate(FIX_QUALITIES)}
# A row's sentence is held as a bit mask over SENTENCE_KINDS (there are too many combinations to list).
_KIND_BIT = {k: 1 << i for i, k in enumerate(SENTENCE_KINDS)}


def sentence_mask(sentence: str) -> int:
    """``"RMC+GGA"`` → its bits (KeyError for a kind not in :data:`SENTENCE_KINDS`)."""
    mask = 0
    for kind in sentence.split("+") if sentence else ():
        mask |= _KIND_BIT[kind]
    return mask


def _masks(sentences: pd.Series) -> np.ndarray:
    """A table's sentence column (names) as bit masks: one lookup per category."""
    column = sentences.astype("category")
    mapping = np.array([sentence_mask(str(c)) for c in column.cat.categories], np.int32)
    return mapping[column.cat.codes.to_numpy()] if len(mapping) else np.zeros(len(column), np.int32)


def sentence_name(mask: int) -> str:
    """Bits → ``"RMC+GGA"`` (canonical order)."""
    return "+".join(k for k in SENTENCE_KINDS if mask & _KIND_BIT[k])


def merged_sentence(a: str, b: str) -> str:
    """``"GGA"`` + ``"RMC"`` → ``"RMC+GGA"`` (canonical order, no repeats)."""
    return sentence_name(sentence_mask(a) | sentence_mask(b))


def _sentence_categorical(masks: np.ndarray) -> pd.Categorical:
    """Sentence masks → the column: :data:`SENTENCES` first, then any other combination used, in mask order."""
    import pandas as pd

    used, codes = np.unique(masks, return_inverse=True)
    names = [sentence_name(int(m)) for m in used]
    fixed = {s: i for i, s in enumerate(SENTENCES)}
    extra = [n for n in names if n not in fixed]
    categories = [*SENTENCES, *extra]
    index = {s: i for i, s in enumerate(categories)}
    lookup = np.array([index[n] for n in names], dtype=np.int32)
    out = lookup[codes.reshape(-1)] if len(masks) else np.zeros(0, np.int32)
    return cast(pd.Categorical, pd.Categorical.from_codes(out, dtype=pd.CategoricalDtype(categories)))


class _Codes:
    """Strings interned as small integer codes, in order of first sight.

    The strings are kept flat while rows are collected (:class:`~parsers.dictionary.StringDictionary`,
    no ``dict`` entry per device); they become Python strings once, as the categorical's categories.
    """

    def __init__(self) -> None:
        self.names = StringDictionary()
        self.codes = array("i")

    def code_of(self, value: str) -> int:
        return self.names.code(value)

    def codes_of(self, values: list[str]) -> np.ndarray:
        """Codes of many strings at once (int32)."""
        return self.names.codes(values)

    def append(self, value: str) -> None:
        self.codes.append(self.code_of(value))

    def used(self, order: np.ndarray | None = None) -> tuple[np.ndarray, NameTable]:
        """The codes (taken at ``order``, if given) renumbered over the values used, and those values,
        in order of first appearance in the rows as collected (whatever order they were interned in: rows
        may be read in batches and put back in line order)."""
        codes = np.frombuffer(self.codes, dtype=np.int32) if len(self.codes) else np.zeros(0, np.int32)
        used, first = np.unique(codes, return_index=True)
        in_order = used[np.argsort(first, kind="stable")]
        renumber = np.zeros(len(self.names), np.int32)
        renumber[in_order] = np.arange(len(in_order), dtype=np.int32)
        out = renumber[codes] if order is None else renumber[codes[order]]
        return out, NameTable(self.names, in_order)


class NameTable(Sequence[str]):
    """The strings a column's codes index, left in their flat :class:`StringDictionary` until read.

    A file of a million devices would otherwise hold a million Python strings for as long as its
    fixes: here a name becomes a string when it is shown or written (:meth:`take`, a block at a time).
    Equal to any sequence of the same strings (a list compares equal to it).
    """

    __slots__ = ("_at", "_names")

    def __init__(self, names: StringDictionary, at: np.ndarray) -> None:
        self._names = names
        self._at = np.asarray(at, np.int64)  # code here → code in ``names``

    def __len__(self) -> int:
        return len(self._at)

    @overload
    def __getitem__(self, i: int) -> str: ...
    @overload
    def __getitem__(self, i: slice) -> list[str]: ...
    def __getitem__(self, i: int | slice) -> str | list[str]:
        if isinstance(i, slice):
            return self._names.take(self._at[i])
        return self._names.value(int(self._at[i]))

    def __iter__(self) -> Iterator[str]:
        for start in range(0, len(self._at), 65_536):
            yield from self._names.take(self._at[start : start + 65_536])

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, str):
            return NotImplemented
        return len(self) == len(other) and all(a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"NameTable({list(self)!r})"

    def take(self, codes: np.ndarray) -> list[str]:
        """The strings of ``codes`` (codes of this table), as a new list."""
        return self._names.take(self._at[np.asarray(codes, np.int64)])

    def reordered(self, positions: np.ndarray) -> NameTable:
        """The names at ``positions``, in that order (a table over the same strings: none made)."""
        return NameTable(self._names, self._at[np.asarray(positions, np.int64)])

    def string_order(self, positions: np.ndarray) -> np.ndarray:
        """``positions`` sorted by their names in Python's string order, read from the UTF-8 bytes
        (whose order is the code points'): no Python string per name."""
        import pyarrow as pa
        import pyarrow.compute as pc

        positions = np.asarray(positions, np.int64)
        if not len(positions):
            return positions
        at = self._at[positions]
        names = self._names.binary().take(pa.Array.from_buffers(pa.int64(), len(at), [None, pa.py_buffer(at)]))
        order = pc.sort_indices(names)
        del names
        ranked = np.frombuffer(order.buffers()[1], np.uint64, len(order), order.offset * 8)
        return positions[ranked.astype(np.int64)]


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
        self.sentence = array("i")  # bit masks (sentence_mask): 25 kinds fit in 31 bits
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
        self.sentence.append(sentence_mask(sentence))
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
        global_codes = self.device.codes_of(device_names)
        self.device.codes.frombytes(global_codes[np.asarray(device_code)].astype(np.int32).tobytes())
        self.file.codes.frombytes(np.full(n, self.file.code_of(file), np.int32).tobytes())

        def small(values: np.ndarray, categories: tuple[str, ...]) -> bytes:
            distinct, inverse = np.unique(np.asarray(values, dtype=object).astype(str), return_inverse=True)
            at = {c: i for i, c in enumerate(categories)}
            assert all(d in at for d in distinct), "a value outside its categories"
            return np.array([at[d] for d in distinct], np.int8)[inverse.reshape(-1)].tobytes()

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
        self.sentence.frombytes(np.zeros(n, np.int32).tobytes())
        self.line.frombytes(np.asarray(line, np.int64).tobytes())
        self.fix_quality.frombytes(small(fix_quality, FIX_QUALITIES))

    def sort_by_line_from(self, start: int) -> None:
        """Put rows ``start:`` (one file's) in line order, stably."""
        lines = np.frombuffer(self.line[start:], dtype=np.int64)
        order = np.argsort(lines, kind="stable")
        if (order == np.arange(len(order))).all():
            return
        for name in _NUMERIC_COLUMNS:
            column = getattr(self, name)
            values = _as_numpy(column[start:])
            column[start:] = array(column.typecode, values[order].tobytes())
        for codes in (self.device.codes, self.file.codes):
            values = np.frombuffer(codes[start:], dtype=np.int32)
            codes[start:] = array("i", values[order].tobytes())

    def subset(self, rows: np.ndarray) -> FixRows:
        """The rows at ``rows`` (indices, in the order given) as new FixRows sharing the string tables."""
        out = FixRows()
        out.device.names, out.file.names = self.device.names, self.file.names
        idx = np.asarray(rows, np.int64)
        for name in _NUMERIC_COLUMNS:
            column = getattr(self, name)
            values = _as_numpy(column)
            getattr(out, name).frombytes(values[idx].tobytes() if len(column) else b"")
        for mine, theirs in ((self.device, out.device), (self.file, out.file)):
            values = np.frombuffer(mine.codes, dtype=np.int32) if len(mine.codes) else np.zeros(0, np.int32)
            theirs.codes.frombytes(values[idx].astype(np.int32).tobytes())
        return out

    def sentence_at(self, i: int) -> str:
        return sentence_name(self.sentence[i])

    def add_sentence(self, i: int, kind: str) -> None:
        """Join ``kind`` (one of :data:`SENTENCE_KINDS`) to row ``i``'s sentence."""
        self.sentence[i] |= _KIND_BIT[kind]

    def source_at(self, i: int) -> str:
        return SOURCES[self.source[i]]

    def quality_at(self, i: int) -> str:
        return FIX_QUALITIES[self.fix_quality[i]]

    def set_quality(self, i: int, quality: str) -> None:
        self.fix_quality[i] = _QUALITY_CODE[quality]

    def set_sentence(self, i: int, sentence: str) -> None:
        self.sentence[i] = sentence_mask(sentence)

    def __len__(self) -> int:
        return len(self.line)

    def columns(self, time_order: bool = False, release: bool = False) -> FixColumns:
        """The rows as numpy columns (:class:`FixColumns`); with ``time_order``, sorted by time, stably,
        unknown times last (each column taken in that order once: no second table is made to sort).

        With ``release`` the rows are handed over: each column collected is dropped once converted, so
        the rows and the columns are not both held whole (the collector is empty afterwards).
        """
        n = len(self)
        if release:  # the names are all in: their lookup (~19 MB a million) goes before the copies are made
            self.device.names.freeze()
            self.file.names.freeze()
        order = None
        if time_order and n:
            t = np.frombuffer(self.time, dtype=np.int64)
            order = np.lexsort((t, t == NAT_NS))
            del t
            if (order == np.arange(n)).all():
                order = None

        def col(name: str, dtype: type) -> np.ndarray:
            a = getattr(self, name)
            if not len(a):
                return np.zeros(0, dtype)
            values: np.ndarray = np.frombuffer(a, dtype=dtype)
            out = values.copy() if order is None else values[order]
            if release:
                del values
                setattr(self, name, array(a.typecode))
            return out

        def strings(codes: _Codes) -> tuple[np.ndarray, NameTable]:
            out = codes.used(order)
            if release:
                codes.codes = array("i")
            return out

        device_codes, device_names = strings(self.device)
        file_codes, file_names = strings(self.file)
        return FixColumns(
            time_ns=col("time", np.int64),
            device_codes=device_codes,
            device_names=device_names,
            role=col("role", np.int8),
            lat=col("lat", np.float64),
            lon=col("lon", np.float64),
            speed_mps=col("speed_mps", np.float64),
            course_deg=col("course_deg", np.float64),
            valid=col("valid", np.int8).astype(bool),
            source=col("source", np.int8),
            sentence=col("sentence", np.int32),
            file_codes=file_codes,
            file_names=file_names,
            line=col("line", np.int64),
            fix_quality=col("fix_quality", np.int8),
        )

    def frame(self, time_order: bool = False, release: bool = False) -> pd.DataFrame:
        """The rows as a fix table with the documented dtypes (see :meth:`columns`)."""
        return self.columns(time_order, release).frame()


@dataclass
class FixColumns:
    """The fix table as numpy columns, without pandas (a small input's start-up does not pay for it).

    ``device_codes`` and ``file_codes`` index ``device_names`` and ``file_names`` (in order of first
    appearance); ``role``, ``source`` and ``fix_quality`` are codes into :data:`ROLES`, :data:`SOURCES` and
    :data:`FIX_QUALITIES`, ``sentence`` bit masks over :data:`SENTENCE_KINDS` (:func:`sentence_name`);
    ``time_ns`` holds NaT as :data:`NAT_NS`.
    :meth:`frame` gives the documented table.
    """

    time_ns: np.ndarray
    device_codes: np.ndarray
    device_names: Sequence[str]  # a NameTable from the readers (strings made when read)
    role: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    speed_mps: np.ndarray
    course_deg: np.ndarray
    valid: np.ndarray
    source: np.ndarray
    sentence: np.ndarray
    file_codes: np.ndarray
    file_names: Sequence[str]
    line: np.ndarray
    fix_quality: np.ndarray

    def __len__(self) -> int:
        return len(self.line)

    def head(self, n: int) -> FixColumns:
        """The first ``n`` rows (the string tables shared)."""
        return FixColumns(**{k: v if k.endswith("_names") else v[:n] for k, v in vars(self).items()})

    def frame(self) -> pd.DataFrame:
        """The fix table (:data:`FIX_COLUMNS`, the documented dtypes)."""
        import pandas as pd

        def categorical(codes: np.ndarray, names: Sequence[str]) -> pd.Categorical[Any]:
            # Python strings (object): pandas would make them for Arrow strings anyway, to check them unique.
            return pd.Categorical.from_codes(codes, categories=pd.Index(list(names), dtype=object))

        def coded(codes: np.ndarray, values: tuple[str, ...]) -> pd.Categorical[Any]:
            return pd.Categorical.from_codes(codes, dtype=pd.CategoricalDtype(list(values)))

        # copy=False: the columns are new arrays, each its own block (no second copy to consolidate them).
        return pd.DataFrame(
            {
                "time": utc_times(self.time_ns),
                "device": categorical(self.device_codes, self.device_names),
                "role": coded(self.role, ROLES),
                "lat": self.lat,
                "lon": self.lon,
                "speed_mps": self.speed_mps,
                "course_deg": self.course_deg,
                "valid": self.valid,
                "source": coded(self.source, SOURCES),
                "sentence": _sentence_categorical(self.sentence),
                "file": categorical(self.file_codes, self.file_names),
                "line": self.line,
                "fix_quality": coded(self.fix_quality, FIX_QUALITIES),
            },
            columns=list(FIX_COLUMNS),
            copy=False,
        )

    @classmethod
    def from_frame(cls, fixes: pd.DataFrame) -> FixColumns:
        """The columns of a fix table (as :meth:`frame` or any GNSS reader gives it)."""

        def strings(name: str) -> tuple[np.ndarray, list[str]]:
            values = fixes[name].astype("category") if len(fixes) else fixes[name].astype(object).astype("category")
            return values.cat.codes.to_numpy(np.int32), [str(x) for x in values.cat.categories]

        def coded(name: str, values: tuple[str, ...]) -> np.ndarray:
            column = fixes[name].astype("category")
            at = {v: i for i, v in enumerate(values)}
            # One lookup per category, then a take over the codes: no Python per row.
            mapping = np.array([at[str(c)] for c in column.cat.categories], np.int8)
            return mapping[column.cat.codes.to_numpy()] if len(mapping) else np.zeros(len(column), np.int8)

        times = fixes["time"]
        if getattr(times.dt, "tz", None) is not None:
            times = times.dt.tz_convert(None)
        device_codes, device_names = strings("device")
        file_codes, file_names = strings("file")
        return cls(
            time_ns=np.asarray(times.to_numpy(dtype="datetime64[ns]")).view(np.int64),
            device_codes=device_codes,
            device_names=device_names,
            role=coded("role", ROLES),
            lat=fixes["lat"].to_numpy(np.float64),
            lon=fixes["lon"].to_numpy(np.float64),
            speed_mps=fixes["speed_mps"].to_numpy(np.float64),
            course_deg=fixes["course_deg"].to_numpy(np.float64),
            valid=fixes["valid"].to_numpy(bool),
            source=coded("source", SOURCES),
            sentence=_masks(fixes["sentence"]),
            file_codes=file_codes,
            file_names=file_names,
            line=fixes["line"].to_numpy(np.int64),
            fix_quality=coded("fix_quality", FIX_QUALITIES),
        )


def utc_times(ns: list[int] | np.ndarray) -> pd.DatetimeIndex:
    """int64 ns since the epoch (NaT as :data:`NAT_NS`) → datetime64[ns, UTC]."""
    import pandas as pd

    return pd.DatetimeIndex(np.asarray(ns, dtype="int64").view("datetime64[ns]")).tz_localize("UTC")


def check_roles(roles: Mapping[str, str] | None) -> dict[str, str]:
    """Validate a device → role mapping; ValueError naming the bad entry."""
    out = dict(roles or {})
    for device, role in out.items():
        if role not in ROLES:
            raise ValueError(f"device '{device}': role '{role}' is not one of 'head', 'eot' or '' (unknown)")
    return out
