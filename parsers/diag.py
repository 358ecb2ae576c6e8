"""Frauscher-style diagnostic records → a columnar table.

A record is one line of twelve tab-separated ``Key:Value`` fields::

    Diag_id:00002  ID:4083  Device:IM  Type:013  GS:GS03  Trackinfo:WS4  ch:1
    Adr:080  Label:Summenzä  Data:18  Date:2015-10-31  Time:09:32:24[.125]

How it stays fast and bounded (no Python loop per record):

* the file is read in line-aligned chunks (``parsers.sources``); numpy finds
  the newlines and tabs of a chunk in one pass;
* each line is cut into three spans: fields 1–9 (the *register span*: device,
  counting head, channel, address, label), fields 10–11 (*value span*: data
  and date) and the time.  The two text spans are wrapped, without copying,
  as Arrow binary-view arrays and dictionary-encoded in C++: a log has a few
  thousand distinct spans however many million records it holds, and each
  distinct span is validated and decoded once, in Python;
* the time, which is nearly unique per record, is parsed with vectorized
  byte arithmetic;
* chunks are tokenized on a thread pool (numpy and Arrow release the GIL)
  while the main thread merges the small per-chunk dictionaries.

Every line ends up as a record, a blank line or a rejection with its file,
line number and reason (``parsers.report``).
"""

from __future__ import annotations

import datetime as dt
import re
import sys
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from parsers.labels import canonical_label, decode_label
from parsers.report import FileReport, ParseReport, escape_name, escape_text
from parsers.sources import (
    DEFAULT_CHUNK_BYTES,
    DEFAULT_MAX_LINE_BYTES,
    Chunk,
    OverlongLine,
    ReadFailure,
    iter_chunks,
    open_input,
)

if TYPE_CHECKING:
    import pandas as pd

FIELD_KEYS = (
    "Diag_id",
    "ID",
    "Device",
    "Type",
    "GS",
    "Trackinfo",
    "ch",
    "Adr",
    "Label",
    "Data",
    "Date",
    "Time",
)
REGISTER_FIELDS = FIELD_KEYS[:9]

# Arrow's binary-view layout stores spans of up to 12 bytes inline; every
# valid span here is longer, so shorter ones are rejected before viewing.
_VIEW_INLINE_MAX = 12
_VIEW = np.dtype([("len", "<i4"), ("prefix", "<u4"), ("buf", "<i4"), ("off", "<i4")])
_TIME_KEY = int.from_bytes(b"Time:", "little")
_NS = 1_000_000_000
_POW10 = np.array([10**k for k in range(10)], dtype=np.int64)
_ERROR_CACHE_MAX = 20_000
_VALUE_CACHE_MAX = 200_000

_INT_RE = re.compile(r"-?\d+")
_HEX_RE = re.compile(r"0[xX][0-9A-Fa-f]{1,16}")
_ISO_DATE_RE = re.compile(r"(\d{4})-(\d{2})-(\d{2})")
_DE_DATE_RE = re.compile(r"(\d{2})\.(\d{2})\.(\d{4})")
_CONTROL_RE = re.compile(r"[\x00-\x1f\x7f-\x9f]")

DATA_KINDS = ("decimal", "hex", "char")


class FieldError(Exception):
    """A field that does not hold what its key promises."""

    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


@dataclass(frozen=True, slots=True)  # slots: a log of a million heads holds a million keys
class RegisterKey:
    """Fields 1–9 of a record: who wrote it, on which channel, which register."""

    diag_id: int
    device_id: int
    device: str
    type: str
    gs: str
    counting_head: str
    channel: int
    address: int
    label: str
    label_canonical: str | None
    label_encoding: str


class _Interner:
    """Strings → dense codes, for categorical columns shared across chunks."""

    def __init__(self) -> None:
        self.values: list[str] = []
        self._codes: dict[str, int] = {}

    def code(self, value: str) -> int:
        found = self._codes.get(value)
        if found is None:
            found = self._codes[value] = len(self.values)
            self.values.append(value)
        return found


def _text(raw: bytes, key: str) -> str:
    text, _ = decode_label(raw)
    text = text.strip()
    if _CONTROL_RE.search(text):
        raise FieldError(key, f"{key}: control characters in '{escape_text(raw, 40)}'")
    return text


def _digits(raw: bytes, key: str, what: str) -> int:
    text = raw.strip()
    if not text.isdigit() or len(text) > 9:
        raise FieldError(key, f"{key}: expected {what}, found '{escape_text(raw, 40)}'")
    return int(text)


def _split_fields(span: bytes, keys: tuple[str, ...], first_index: int) -> list[bytes]:
    parts = span.split(b"\t")
    values = []
    for i, (key, part) in enumerate(zip(keys, parts, strict=True)):
        name, sep, value = part.partition(b":")
        if not sep or name.strip() != key.encode():
            raise FieldError(
                "fields",
                f"field {first_index + i}: expected '{key}:…', found '{escape_text(part, 40)}'",
            )
        values.append(value)
    return values


def parse_register_span(span: bytes) -> RegisterKey:
    """Validate and decode fields 1–9 of a record (once per distinct span)."""
    diag, dev_id, device, typ, gs, head, ch, adr, label = _split_fields(span, REGISTER_FIELDS, 1)
    channel = _digits(ch, "ch", "a channel number (1 = Sys1, 2 = Sys2)")
    if channel > 15:
        raise FieldError("ch", f"ch: expected a channel number 0-15, found {channel}")
    counting_head = _text(head, "Trackinfo")
    if not counting_head:
        raise FieldError("Trackinfo", "Trackinfo: empty counting head name")
    device_name = _text(device, "Device")
    label_text, label_encoding = decode_label(label)
    if _CONTROL_RE.search(label_text):
        raise FieldError("Label", f"Label: control characters in '{escape_text(label, 40)}'")
    label_text = label_text.strip()
    # Names shared by many registers are one string each (sys.intern), not one per register.
    return RegisterKey(
        diag_id=_digits(diag, "Diag_id", "digits"),
        device_id=_digits(dev_id, "ID", "a numeric device id"),
        device=sys.intern(device_name),
        type=sys.intern(_text(typ, "Type")),
        gs=sys.intern(_text(gs, "GS")),
        counting_head=counting_head,
        channel=channel,
        address=_digits(adr, "Adr", "a numeric register address"),
        label=sys.intern(label_text),
        label_canonical=canonical_label(label_text) if label_text else None,
        label_encoding=label_encoding,
    )


def decode_data(raw: bytes) -> tuple[str, int, str]:
    """``18`` → 18, ``0xD8`` → 216, ``'T'`` → ord('T'); returns (text, value, kind)."""
    text, _ = decode_label(raw)
    bare = text.strip()
    if _INT_RE.fullmatch(bare):
        if len(bare.lstrip("-")) > 18:
            raise FieldError("Data", f"Data: number too large '{escape_text(raw, 40)}'")
        return bare, int(bare), "decimal"
    if _HEX_RE.fullmatch(bare):
        value = int(bare, 16)
        if value >= 1 << 63:
            raise FieldError("Data", f"Data: number too large '{escape_text(raw, 40)}'")
        return bare, value, "hex"
    if len(bare) == 3 and bare[0] == bare[2] == "'" and not _CONTROL_RE.match(bare[1]):
        return bare, ord(bare[1]), "char"
    raise FieldError(
        "Data",
        f"Data: expected a number, a hex byte (0xD8) or a quoted character ('T'), found '{escape_text(raw, 40)}'",
    )


_EPOCH = dt.date(1970, 1, 1)
# Whole days whose every time of day fits in int64 ns since the epoch
# (1677-09-21 00:12:43 to 2262-04-11 23:47:16).
_FIRST_DAY = dt.date(1677, 9, 22)
_LAST_DAY = dt.date(2262, 4, 10)


def decode_date(raw: bytes) -> int:
    """``2015-10-31`` (or German ``31.10.2015``) → ns since the epoch at midnight."""
    text = raw.decode("ascii", errors="replace").strip()
    iso = _ISO_DATE_RE.fullmatch(text)
    de = _DE_DATE_RE.fullmatch(text)
    if iso:
        y, m, d = (int(g) for g in iso.groups())
    elif de:
        d, m, y = (int(g) for g in de.groups())
    else:
        raise FieldError("Date", f"Date: expected YYYY-MM-DD, found '{escape_text(raw, 40)}'")
    try:
        day = dt.date(y, m, d)
    except ValueError:
        raise FieldError("Date", f"Date: impossible date '{text}'") from None
    if not _FIRST_DAY <= day <= _LAST_DAY:
        # Times are int64 ns (pandas' range): a year 0001 or 9999, or a bit
        # flipped in the year, would overflow the whole read.
        raise FieldError("Date", f"Date: date out of range '{text}' (times hold {_FIRST_DAY} to {_LAST_DAY})")
    return (day - _EPOCH).days * 86400 * _NS


_TIME_RE = re.compile(r"(\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?")


def parse_time(raw: bytes) -> tuple[int, bool]:
    """``Time:09:32:24[.125]`` → (ns since midnight, has a fraction).

    The per-line reference for the vectorized time parse in :func:`_tokenize`
    (same rules), used for lines off the fast path.
    """
    name, sep, value = raw.partition(b":")
    if not sep or name.strip() != b"Time":
        raise FieldError("fields", f"field 12: expected 'Time:…', found '{escape_text(raw, 40)}'")
    text = value.decode("utf-8", errors="replace").strip()
    m = _TIME_RE.fullmatch(text)
    if not m:
        raise FieldError("Time", f"Time: expected HH:MM:SS or HH:MM:SS.fff, found '{escape_text(value, 40)}'")
    hh, mm, ss = int(m[1]), int(m[2]), int(m[3])
    if hh > 23 or mm > 59 or ss > 59:
        raise FieldError("Time", f"Time: impossible time '{text}'")
    frac = m[4] or ""
    return ((hh * 60 + mm) * 60 + ss) * _NS + (int(frac.ljust(9, "0")) if frac else 0), bool(frac)


@dataclass
class DiagRegistry:
    """Dimension tables shared by all chunks of one read.

    Records carry a ``register_id`` into :attr:`registers`; categorical string
    columns carry codes into the interners.  Both only ever grow, so codes in
    an early chunk stay valid for the final table.
    """

    registers: list[RegisterKey] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    devices: _Interner = field(default_factory=_Interner)
    types: _Interner = field(default_factory=_Interner)
    gs: _Interner = field(default_factory=_Interner)
    heads: _Interner = field(default_factory=_Interner)
    labels: _Interner = field(default_factory=_Interner)
    canonicals: _Interner = field(default_factory=_Interner)
    data: _Interner = field(default_factory=_Interner)
    _register_ids: dict[bytes, int] = field(default_factory=dict)
    _register_errors: dict[bytes, FieldError] = field(default_factory=dict)
    _values: dict[bytes, tuple[int, int, int, int] | FieldError] = field(default_factory=dict)
    _data: dict[bytes, tuple[int, int, int] | FieldError] = field(default_factory=dict)
    _days: dict[bytes, int | FieldError] = field(default_factory=dict)
    _arrays: dict[str, np.ndarray] = field(default_factory=dict)
    _arrays_len: int = -1
    record_counts: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def count_records(self, register_id: np.ndarray) -> None:
        """Add parsed records to the per-register totals."""
        counts = np.bincount(register_id, minlength=len(self.registers))
        if len(self.record_counts) < len(counts):
            grown = np.zeros(len(counts), np.int64)
            grown[: len(self.record_counts)] = self.record_counts
            self.record_counts = grown
        self.record_counts[: len(counts)] += counts

    def unknown_labels(self) -> dict[str, int]:
        """Records per label that maps to no known register (kept verbatim)."""
        out: dict[str, int] = {}
        for rid, r in enumerate(self.registers):
            if r.label and r.label_canonical is None and rid < len(self.record_counts):
                out[r.label] = out.get(r.label, 0) + int(self.record_counts[rid])
        return {k: v for k, v in out.items() if v}

    def register_id(self, span: bytes) -> int | FieldError:
        found = self._register_ids.get(span)
        if found is not None:
            return found
        err = self._register_errors.get(span)
        if err is not None:
            return err
        try:
            key = parse_register_span(span)
        except FieldError as exc:
            if len(self._register_errors) < _ERROR_CACHE_MAX:
                self._register_errors[span] = exc
            return exc
        except ValueError:  # wrong number of parts: only for malformed spans
            return FieldError("fields", "expected 12 tab-separated Key:Value fields")
        rid = self._register_ids[span] = self.add_register(key)
        return rid

    def add_register(self, key: RegisterKey) -> int:
        """Append a register and intern its strings; its id.  (Also used by readers
        that rebuild a registry from stored records, such as the archive.)"""
        rid = len(self.registers)
        self.registers.append(key)
        for interner, value in (
            (self.devices, key.device),
            (self.types, key.type),
            (self.gs, key.gs),
            (self.heads, key.counting_head),
            (self.labels, key.label),
            (self.canonicals, key.label_canonical or key.label),
        ):
            interner.code(value)
        return rid

    def value(self, span: bytes) -> tuple[int, int, int, int] | FieldError:
        """(data code, value, kind code, day ns) for a value span ``Data:…\tDate:…``.

        The data and date halves have caches of their own: a long log meets
        every (value, day) pair anew, but few values and few days.
        """
        found = self._values.get(span)
        if found is not None:
            return found
        parts = span.split(b"\t")
        result: tuple[int, int, int, int] | FieldError
        if len(parts) != 2:
            result = FieldError("fields", "expected 12 tab-separated Key:Value fields")
        else:
            data = self._data.get(parts[0])
            if data is None:
                data = self._data[parts[0]] = self._parse_data(parts[0])
            day = self._days.get(parts[1])
            if day is None:
                day = self._days[parts[1]] = self._parse_day(parts[1])
            if isinstance(data, FieldError):
                result = data
            elif isinstance(day, FieldError):
                result = day
            else:
                result = (*data, day)
        if len(self._values) >= _VALUE_CACHE_MAX:
            self._values.clear()  # bounded: a cache, not a store
            self._data.clear()
            self._days.clear()
        self._values[span] = result
        return result

    def _parse_data(self, field_bytes: bytes) -> tuple[int, int, int] | FieldError:
        try:
            (raw,) = _split_fields(field_bytes, ("Data",), 10)
            text, value, kind = decode_data(raw)
        except FieldError as exc:
            return exc
        return self.data.code(text), value, DATA_KINDS.index(kind)

    @staticmethod
    def _parse_day(field_bytes: bytes) -> int | FieldError:
        try:
            (raw,) = _split_fields(field_bytes, ("Date",), 11)
            return decode_date(raw)
        except FieldError as exc:
            return exc

    def arrays(self) -> dict[str, np.ndarray]:
        """Per-register lookup arrays (indexed by register_id), extended for new registers only."""
        done = max(self._arrays_len, 0)
        if done != len(self.registers) or not self._arrays:  # not self._arrays: none built yet (no register)
            regs = self.registers[done:]
            new: dict[str, np.ndarray] = {
                "diag_id": np.array([r.diag_id for r in regs], dtype=np.int32),
                "device_id": np.array([r.device_id for r in regs], dtype=np.int32),
                "device": np.array([self.devices.code(r.device) for r in regs], dtype=np.int32),
                "type": np.array([self.types.code(r.type) for r in regs], dtype=np.int32),
                "gs": np.array([self.gs.code(r.gs) for r in regs], dtype=np.int32),
                "counting_head": np.array([self.heads.code(r.counting_head) for r in regs], dtype=np.int32),
                "channel": np.array([r.channel for r in regs], dtype=np.int8),
                "address": np.array([r.address for r in regs], dtype=np.int32),
                "label": np.array([self.labels.code(r.label) for r in regs], dtype=np.int32),
                "label_canonical": np.array(
                    [self.canonicals.code(r.label_canonical or r.label) for r in regs], dtype=np.int32
                ),
            }
            # A log of a million heads adds registers in every chunk: never rebuild the old ones.
            self._arrays = {k: np.concatenate([self._arrays[k], v]) for k, v in new.items()} if done else new
            self._arrays_len = len(self.registers)
        return self._arrays


@dataclass
class DiagChunk:
    """Parsed records of one chunk: a fact table keyed into a DiagRegistry."""

    file_id: int
    register_id: np.ndarray  # int32
    time_ns: np.ndarray  # int64, ns since epoch (log local time, naive)
    subsecond: np.ndarray  # bool: the time carried a fraction
    value: np.ndarray  # int64
    data_code: np.ndarray  # int32
    data_kind: np.ndarray  # int8
    line: np.ndarray  # int64, 1-based

    def __len__(self) -> int:
        return len(self.register_id)

    def take(self, mask: np.ndarray) -> DiagChunk:
        """The records where mask is true."""
        return DiagChunk(
            self.file_id,
            self.register_id[mask],
            self.time_ns[mask],
            self.subsecond[mask],
            self.value[mask],
            self.data_code[mask],
            self.data_kind[mask],
            self.line[mask],
        )


@dataclass
class _Tokens:
    """A chunk cut into spans (thread-pool output, before dictionary merging).

    ``fast`` lists the lines whose shape the vectorized pass recognised; all
    other non-blank lines go through :meth:`DiagReader._slow_line`.
    """

    chunk: Chunk
    buf: memoryview | bytes
    starts: np.ndarray
    ends: np.ndarray
    blank: np.ndarray
    fast: np.ndarray
    reg_idx: np.ndarray
    reg_dict: list[bytes]
    val_idx: np.ndarray
    val_dict: list[bytes]
    tod_ns: np.ndarray
    subsecond: np.ndarray
    time_ok: np.ndarray


def _views(view_buf: pa.Buffer, u4: np.ndarray, starts: np.ndarray, lens: np.ndarray) -> pa.Array:
    v = np.empty(len(starts), _VIEW)
    v["len"] = lens
    v["prefix"] = u4[starts]
    v["buf"] = 0
    v["off"] = starts
    return pa.Array.from_buffers(pa.binary_view(), len(starts), [None, pa.py_buffer(v), view_buf])


def _encode(
    view_buf: pa.Buffer, u4: np.ndarray, starts: np.ndarray, lens: np.ndarray
) -> tuple[np.ndarray, list[bytes]]:
    if len(starts) == 0:
        return np.zeros(0, np.int32), []
    enc = _views(view_buf, u4, starts, lens).dictionary_encode()
    # The indices (no nulls) read straight from their buffer: Arrow's to_numpy
    # would import pandas.  intp: the main thread's lookups need no conversion.
    idx = enc.indices
    width = idx.type.bit_width // 8
    codes = np.frombuffer(idx.buffers()[1], f"<i{width}", count=len(idx), offset=idx.offset * width)
    return codes.astype(np.intp), enc.dictionary.to_pylist()


_LO7 = np.uint64(0x7F7F7F7F7F7F7F7F)
_HMS_PATTERN = np.uint64(int.from_bytes(b"00:00:00", "little"))
_HMS_COLONS = np.uint64(0x0000FF0000FF0000)
_HMS_DIGIT_LIMIT = np.uint64(0x7676767676767676)  # + 0x76 sets a byte's top bit from 10 up
_HIGH_BITS = np.uint64(0x8080808080808080)
_TABS = np.uint64(0x0909090909090909)


def _tab_bytes(words: np.ndarray) -> np.ndarray:
    """Per 8-byte word: the high bit of each byte that is a tab (exact, no borrows)."""
    x = words ^ _TABS
    return ~(((x & _LO7) + _LO7) | x | _LO7)


def _last_tab(u8: np.ndarray, window_end: np.ndarray, words: int) -> np.ndarray:
    """Offset of the last tab in the ``8 * words`` bytes before window_end, or -1."""
    found = np.full(len(window_end), -1, np.int64)
    todo = np.ones(len(window_end), bool)
    for k in range(1, words + 1):
        base = window_end - 8 * k
        mask = _tab_bytes(u8[base])
        hit = todo & (mask != 0)
        if hit.any():
            # Set bits sit at 8j+7 and are sparse, so float log2 finds the top one exactly.
            top = (np.log2(mask[hit].astype(np.float64)).astype(np.int64) - 7) // 8
            found[hit] = base[hit] + top
            todo &= ~hit
    return found


# A valid record is never shorter than this; shorter lines take the slow path,
# which also keeps the backward byte windows inside the line.
_MIN_FAST_LINE = 64


def _tokenize(chunk: Chunk) -> _Tokens:
    """Cut a chunk into lines and spans: numpy and Arrow only, no per-line Python.

    Only newlines are scanned for.  In a record the last three tabs stand
    before Time (at most 24 bytes from the end), before Date (exactly 16
    bytes earlier: ``Date:YYYY-MM-DD``) and before Data (a short field);
    they are found with 8-byte loads.  The tab count of the rest is checked
    when each distinct register span is parsed.
    """
    data = chunk.data if chunk.ends_with_newline() else bytes(chunk.data) + b"\n"
    size = len(data)
    buf = data
    arr = np.frombuffer(buf, np.uint8)
    # Unaligned 4- and 8-byte little-endian loads at any offset.  Every load
    # below stays inside a line of at least _MIN_FAST_LINE bytes, so no
    # padding (and no copy of the chunk) is needed.
    u4 = np.ndarray(shape=(max(size - 3, 0),), dtype="<u4", buffer=buf, strides=(1,))
    u8 = np.ndarray(shape=(max(size - 7, 0),), dtype="<u8", buffer=buf, strides=(1,))

    nl = np.flatnonzero(arr[:size] == 10)
    starts = np.empty_like(nl)
    starts[:1] = 0
    starts[1:] = nl[:-1] + 1
    ends = nl.copy()
    # CRLF and trailing blanks: trim a few rounds, only where needed.
    for _ in range(4):
        trail = (ends > starts) & ((arr[ends - 1] == 13) | (arr[ends - 1] == 32))
        if not trail.any():
            break
        ends -= trail
    blank = ends == starts

    fast = np.flatnonzero(ends - starts >= _MIN_FAST_LINE)
    st, en = starts[fast], ends[fast]
    # Whole-second (13 bytes) and millisecond (17 bytes) times by direct look;
    # other fraction lengths by searching the last 24 bytes.
    t10 = np.where(arr[en - 14] == 9, en - 14, np.where(arr[en - 18] == 9, en - 18, -1))
    odd = t10 < 0
    if odd.any():
        t10[odd] = _last_tab(u8, en[odd], 3)
    t9 = t10 - 16
    ok = (t10 >= 0) & (arr[np.maximum(t9, 0)] == 9)
    t8 = _last_tab(u8, np.where(ok, t9, en), 2)
    ok &= (t8 - st > _VIEW_INLINE_MAX) & (en - t10 >= 14)
    if not ok.all():
        fast, st, en, t8, t10 = fast[ok], st[ok], en[ok], t8[ok], t10[ok]
    view_buf = pa.py_buffer(buf)
    reg_idx, reg_dict = _encode(view_buf, u4, st, t8 - st)
    val_idx, val_dict = _encode(view_buf, u4, t8 + 1, t10 - t8 - 1)

    # Time: "Time:HH:MM:SS" plus an optional ".f" of 1-9 digits (rules of parse_time).
    ts = t10 + 1
    tlen = en - ts
    w_key = u8[ts]
    w_hms = u8[ts + 5]
    time_ok = (w_key & np.uint64(0xFF_FFFF_FFFF)) == np.uint64(_TIME_KEY)
    time_ok &= (tlen == 13) | ((tlen >= 15) & (tlen <= 23))
    # "HH:MM:SS" in one 8-byte word: XOR with "00:00:00" leaves every digit
    # as 0-9 and every colon as 0; a byte that is 10 or more (or has its top
    # bit set) after the XOR was not a digit.  Then byte k * 10 + byte k+1
    # gives the two-digit fields at bytes 0, 3 and 6 (no carries: bytes ≤ 9).
    x = w_hms ^ _HMS_PATTERN
    time_ok &= ((x & _HMS_COLONS) == 0) & ((((x + _HMS_DIGIT_LIMIT) | x) & _HIGH_BITS) == 0)
    pairs = x * np.uint64(10) + (x >> np.uint64(8))
    hh = (pairs & np.uint64(0xFF)).astype(np.int64)
    mm = ((pairs >> np.uint64(24)) & np.uint64(0xFF)).astype(np.int64)
    ss = ((pairs >> np.uint64(48)) & np.uint64(0xFF)).astype(np.int64)
    time_ok &= (hh < 24) & (mm < 60) & (ss < 60)
    tod = ((hh * 60 + mm) * 60 + ss) * _NS
    n_frac = np.where((tlen >= 15) & (tlen <= 23), tlen - 14, 0)
    subsecond = n_frac > 0
    if subsecond.any():
        time_ok &= ~subsecond | (arr[np.minimum(ts + 13, size - 1)] == ord("."))
        frac = np.zeros(len(ts), np.int64)
        for k in range(int(n_frac.max())):
            has = n_frac > k
            b = arr[np.minimum(ts + 14 + k, size - 1)].astype(np.int64) - 48
            time_ok &= ~has | ((b >= 0) & (b <= 9))
            frac = np.where(has, frac * 10 + b, frac)
        tod += frac * _POW10[9 - np.minimum(n_frac, 9)]
    return _Tokens(
        chunk=chunk,
        buf=data,
        starts=starts,
        ends=ends,
        blank=blank,
        fast=fast,
        reg_idx=reg_idx,
        reg_dict=reg_dict,
        val_idx=val_idx,
        val_dict=val_dict,
        tod_ns=tod,
        subsecond=subsecond,
        time_ok=time_ok,
    )


# Below this chunk size the thread pool's hand-over costs more than tokenizing in the reading thread.
_POOL_MIN_CHUNK_BYTES = 256 << 10


@dataclass
class _Ready:
    """A chunk tokenized in the reading thread, queued like a worker's future."""

    tokens: _Tokens

    def result(self) -> _Tokens:
        return self.tokens


class DiagReader:
    """Streams diagnostic records from files as :class:`DiagChunk` batches.

    Use :meth:`chunks` for bounded-memory streaming, or :func:`read_diag` for
    one DataFrame.  After iteration, :attr:`report` accounts for every line.
    """

    def __init__(
        self,
        paths: Iterable[Path],
        *,
        chunk_bytes: int = DEFAULT_CHUNK_BYTES,
        max_line_bytes: int = DEFAULT_MAX_LINE_BYTES,
        workers: int = 2,
        on_progress: Callable[[int], None] | None = None,
    ) -> None:
        self.paths = [Path(p) for p in paths]
        self.chunk_bytes = chunk_bytes
        self.max_line_bytes = max_line_bytes
        self.workers = workers
        self.on_progress = on_progress
        self.registry = DiagRegistry()
        self.report = ParseReport()

    def chunks(self) -> Iterator[DiagChunk]:
        """Parse all files in order; yields chunks of records as they are ready."""
        with ThreadPoolExecutor(max_workers=max(1, self.workers)) as pool:
            for path in self.paths:
                yield from self._file_chunks(path, pool)
        self.report.unknown_labels.update(self.registry.unknown_labels())
        self.report.check()

    def _file_chunks(self, path: Path, pool: ThreadPoolExecutor) -> Iterator[DiagChunk]:
        stream, raw, info = open_input(path)
        name = str(path)
        file_id = len(self.registry.files)
        self.registry.files.append(name)
        fr = FileReport(file=name, encoding=info.encoding, compressed=info.compressed)
        self.report.files.append(fr)
        last_pos = 0

        def progress() -> None:
            nonlocal last_pos
            pos = raw.tell()
            if self.on_progress is not None and pos > last_pos:
                self.on_progress(pos - last_pos)
            last_pos = pos

        pending: deque[Future[_Tokens] | _Ready | OverlongLine] = deque()
        # Small chunks are tokenized in this thread: handing each to a worker costs more than it saves.
        inline = self.workers <= 1 or self.chunk_bytes < _POOL_MIN_CHUNK_BYTES
        next_line = 1  # line numbers are handed out here, in file order
        done_buffers: list[bytearray] = []  # read buffers of resolved chunks, to read into again

        def drain() -> DiagChunk | None:
            nonlocal next_line
            item = pending.popleft()
            if isinstance(item, OverlongLine):
                self._overlong(item, fr, next_line)
                next_line += 1
                return None
            tok = item.result()
            out = self._resolve(tok, fr, file_id, next_line)
            next_line += len(tok.starts)
            # Nothing of the chunk's buffer is referenced beyond this point.
            if isinstance(tok.chunk.data, memoryview) and isinstance(tok.chunk.data.obj, bytearray):
                done_buffers.append(tok.chunk.data.obj)
            return out

        try:
            source = iter_chunks(
                stream,
                info,
                chunk_bytes=self.chunk_bytes,
                max_line_bytes=self.max_line_bytes,
                on_bytes=progress,
                name=name,
                recycle=done_buffers,
            )
            for item in source:
                if isinstance(item, OverlongLine):
                    pending.append(item)
                elif inline:
                    pending.append(_Ready(_tokenize(item)))
                else:
                    pending.append(pool.submit(_tokenize, item))
                while len(pending) > self.workers:
                    if (out := drain()) is not None:
                        yield out
            while pending:
                if (out := drain()) is not None:
                    yield out
        finally:
            for fut in pending:
                if isinstance(fut, Future):
                    fut.cancel()
            stream.close()
            raw.close()
        fr.ends_without_newline = info.ends_without_newline
        fr.bytes_read = last_pos

    def _overlong(self, o: OverlongLine, fr: FileReport, line: int) -> None:
        fr.lines_read += 1
        if isinstance(o, ReadFailure):  # the lines before a corrupt spot are kept; it stands for the rest
            self.report.reject(fr, line, "corrupt", o.message(line - 1), o.head)
            return
        reason = f"line longer than {self.max_line_bytes} bytes ({o.length} bytes)"
        self.report.reject(fr, line, "too long", reason, o.head)

    def parse_lines(self, data: bytes, fr: FileReport, file_id: int, first_line: int) -> DiagChunk:
        """Whole lines of a growing file (newline-terminated), numbered from ``first_line``:
        parsed into this reader's registry, rejections into ``fr`` (the live follower's entry)."""
        return self._resolve(_tokenize(Chunk(data, final=False)), fr, file_id, first_line)

    def _resolve(self, tok: _Tokens, fr: FileReport, file_id: int, first_line: int) -> DiagChunk:
        """Merge a chunk's span dictionaries into the registry; parse or reject the rest."""
        reg = self.registry
        n_lines = len(tok.starts)
        fr.lines_read += n_lines

        reg_lut = np.full(len(tok.reg_dict), -1, np.int32)
        reg_err: dict[int, FieldError] = {}
        for i, span in enumerate(tok.reg_dict):
            got = reg.register_id(span)
            if isinstance(got, FieldError):
                reg_err[i] = got
            else:
                reg_lut[i] = got
        val_cols = np.zeros((4, len(tok.val_dict)), np.int64)
        val_ok = np.ones(len(tok.val_dict), bool)
        val_err: dict[int, FieldError] = {}
        for i, span in enumerate(tok.val_dict):
            got_v = reg.value(span)
            if isinstance(got_v, FieldError):
                val_err[i] = got_v
                val_ok[i] = False
            else:
                val_cols[:, i] = got_v

        rid = reg_lut[tok.reg_idx]
        good = (rid >= 0) & val_ok[tok.val_idx] & tok.time_ok
        vi = tok.val_idx[good]
        rid_g = rid[good]
        time_ns = val_cols[3][vi] + tok.tod_ns[good]
        subsecond = tok.subsecond[good]
        value = val_cols[1][vi]
        data_code = val_cols[0][vi]
        data_kind = val_cols[2][vi]
        lines = tok.fast[good]

        # The rest is blank, off the fast path, or rejected: few lines, Python is fine.
        rest = np.ones(n_lines, bool)
        rest[lines] = False
        rest &= ~tok.blank
        fr.blank += int(tok.blank.sum())
        bad_j = np.flatnonzero(~good)
        bad_fast = dict(zip(tok.fast[bad_j].tolist(), bad_j.tolist(), strict=True))
        last_open = tok.chunk.final and not tok.chunk.ends_with_newline()
        slow: list[tuple[int, int, int, bool, int, int, int]] = []
        for li in np.flatnonzero(rest).tolist():
            raw = bytes(tok.buf[tok.starts[li] : tok.ends[li]])
            j = bad_fast.get(li)
            err: FieldError | None = None
            if j is not None and int(tok.reg_idx[j]) in reg_err:
                err = reg_err[int(tok.reg_idx[j])]
            elif j is not None and int(tok.val_idx[j]) in val_err:
                err = val_err[int(tok.val_idx[j])]
            else:
                parsed = self._slow_line(raw)
                if parsed is None:
                    fr.blank += 1
                    continue
                if isinstance(parsed, FieldError):
                    err = parsed
                else:
                    slow.append((li, *parsed))
                    continue
            category, reason = err.category, err.reason
            if last_open and li == n_lines - 1:
                category, reason = "truncated", f"truncated last line (no newline at end of file): {reason}"
            self.report.reject(fr, first_line + li, category, reason, raw)
        if slow:
            s_lines, s_rid, s_time, s_sub, s_value, s_code, s_kind = (np.array(c) for c in zip(*slow, strict=True))
            lines = np.concatenate([lines, s_lines])
            order = np.argsort(lines, kind="stable")
            lines = lines[order]
            rid_g = np.concatenate([rid_g, s_rid])[order]
            time_ns = np.concatenate([time_ns, s_time])[order]
            subsecond = np.concatenate([subsecond, s_sub])[order]
            value = np.concatenate([value, s_value])[order]
            data_code = np.concatenate([data_code, s_code])[order]
            data_kind = np.concatenate([data_kind, s_kind])[order]
        out = DiagChunk(
            file_id=file_id,
            # Every column is a fresh array already: convert, never copy.
            register_id=rid_g.astype(np.int32, copy=False),
            time_ns=time_ns.astype(np.int64, copy=False),
            subsecond=subsecond.astype(bool, copy=False),
            value=value.astype(np.int64, copy=False),
            data_code=data_code.astype(np.int32, copy=False),
            data_kind=data_kind.astype(np.int8, copy=False),
            line=lines.astype(np.int64, copy=False) + first_line,
        )
        fr.records += len(out)
        reg.count_records(out.register_id)
        return out

    def _slow_line(self, raw: bytes) -> tuple[int, int, bool, int, int, int] | FieldError | None:
        """Parse one line in Python with the same field rules (None: blank).

        Returns (register id, time ns, subsecond, value, data code, kind code).
        """
        if not raw.strip():
            return None
        parts = raw.split(b"\t")
        if len(parts) != len(FIELD_KEYS):
            return FieldError(*_shape_reason(raw, len(parts)))
        rid = self.registry.register_id(b"\t".join(parts[:9]))
        if isinstance(rid, FieldError):
            return rid
        val = self.registry.value(b"\t".join(parts[9:11]))
        if isinstance(val, FieldError):
            return val
        try:
            tod, subsecond = parse_time(parts[11])
        except FieldError as exc:
            return exc
        code, value, kind, day_ns = val
        return rid, day_ns + tod, subsecond, value, code, kind


def _shape_reason(raw: bytes, n_fields: int) -> tuple[str, str]:
    if b"\0" in raw or sum(b < 32 and b not in (9, 13) for b in raw[:256]) > 2:
        return "binary", "binary data, not a text record"
    return "fields", f"expected {len(FIELD_KEYS)} tab-separated Key:Value fields, found {n_fields}"


RECORD_COLUMNS = (
    "time",
    "diag_id",
    "device_id",
    "device",
    "type",
    "gs",
    "counting_head",
    "channel",
    "address",
    "label",
    "label_canonical",
    "data",
    "value",
    "data_kind",
    "subsecond",
    "file",
    "line",
)


def _utf8_name(value: str) -> str:
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        return escape_name(value)
    return value


def _categorical(codes: np.ndarray, values: list[str]) -> pd.Categorical:
    import pandas as pd

    # Arrow strings are UTF-8: a file name that is not (surrogateescape) is stored as shown, ``\xff``.
    cats = pd.Index([_utf8_name(v) for v in values], dtype=pd.StringDtype("pyarrow"))
    return pd.Categorical.from_codes(codes, categories=cats, validate=False)


def chunks_to_frame(chunks: list[DiagChunk], registry: DiagRegistry) -> pd.DataFrame:
    """One DataFrame (the documented record table) from parsed chunks."""
    import pandas as pd

    rid = np.concatenate([c.register_id for c in chunks]) if chunks else np.zeros(0, np.int32)

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(c, name) for c in chunks]) if chunks else np.zeros(0)

    arrays = registry.arrays() if registry.registers else None

    def reg(name: str, dtype: str) -> np.ndarray:
        if arrays is None:
            return np.zeros(0, dtype=dtype)
        return arrays[name][rid]

    file_codes = (
        np.concatenate([np.full(len(c), c.file_id, np.int32) for c in chunks]) if chunks else np.zeros(0, np.int32)
    )
    canon = registry.canonicals.values
    frame = pd.DataFrame(
        {
            "time": pd.to_datetime(cat("time_ns").astype(np.int64), unit="ns"),
            "diag_id": reg("diag_id", "int32"),
            "device_id": reg("device_id", "int32"),
            "device": _categorical(reg("device", "int32"), registry.devices.values),
            "type": _categorical(reg("type", "int32"), registry.types.values),
            "gs": _categorical(reg("gs", "int32"), registry.gs.values),
            "counting_head": _categorical(reg("counting_head", "int32"), registry.heads.values),
            "channel": reg("channel", "int8"),
            "address": reg("address", "int32").astype(np.int16),
            "label": _categorical(reg("label", "int32"), registry.labels.values),
            "label_canonical": _categorical(reg("label_canonical", "int32"), canon),
            "data": _categorical(cat("data_code").astype(np.int32), registry.data.values),
            "value": cat("value").astype(np.int64),
            "data_kind": _categorical(cat("data_kind").astype(np.int32), list(DATA_KINDS)),
            "subsecond": cat("subsecond").astype(bool),
            "file": _categorical(file_codes, registry.files),
            "line": cat("line").astype(np.int64),
        },
        columns=list(RECORD_COLUMNS),
    )
    # Empty labels carry no register name: missing, not the empty string.
    frame["label_canonical"] = (
        frame["label_canonical"].cat.remove_categories([""]) if "" in canon else frame["label_canonical"]
    )
    return frame


def read_diag(paths: Iterable[Path | str], **kwargs: object) -> tuple[pd.DataFrame, ParseReport]:
    """Parse diagnostic files (plain or gzip) into one record table and a report."""
    reader = DiagReader([Path(p) for p in paths], **kwargs)  # type: ignore[arg-type]
    chunks = list(reader.chunks())
    return chunks_to_frame(chunks, reader.registry), reader.report
