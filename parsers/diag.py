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
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa

from parsers.labels import canonical_label, decode_label
from parsers.report import FileReport, ParseReport, escape_text
from parsers.sources import (
    DEFAULT_CHUNK_BYTES,
    DEFAULT_MAX_LINE_BYTES,
    Chunk,
    OverlongLine,
    iter_chunks,
    open_input,
)

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
N_TABS = len(FIELD_KEYS) - 1
REGISTER_FIELDS = FIELD_KEYS[:9]

# Arrow's binary-view layout stores spans of up to 12 bytes inline; every
# valid span here is longer, so shorter ones are rejected before viewing.
_VIEW_INLINE_MAX = 12
_PAD = 32  # bytes after a chunk so fixed-width loads never run off its end
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


@dataclass(frozen=True)
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
    return RegisterKey(
        diag_id=_digits(diag, "Diag_id", "digits"),
        device_id=_digits(dev_id, "ID", "a numeric device id"),
        device=device_name,
        type=_text(typ, "Type"),
        gs=_text(gs, "GS"),
        counting_head=counting_head,
        channel=channel,
        address=_digits(adr, "Adr", "a numeric register address"),
        label=label_text,
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
    return (day - _EPOCH).days * 86400 * _NS


def parse_value_span(span: bytes) -> tuple[str, int, str, int]:
    """Fields 10–11 (Data, Date) → (data text, value, kind, day in ns)."""
    data, date = _split_fields(span, ("Data", "Date"), 10)
    text, value, kind = decode_data(data)
    return text, value, kind, decode_date(date)


def describe_time(raw: bytes) -> str:
    """Why a Time field was refused (only called for refused lines)."""
    name, sep, value = raw.partition(b":")
    if not sep or name.strip() != b"Time":
        return f"field 12: expected 'Time:…', found '{escape_text(raw, 40)}'"
    text = value.decode("utf-8", errors="replace")
    m = re.fullmatch(r"(\d{2}):(\d{2}):(\d{2})(\.\d{1,9})?", text)
    if not m:
        return f"Time: expected HH:MM:SS or HH:MM:SS.fff, found '{escape_text(value, 40)}'"
    return f"Time: impossible time '{text}'"


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
        rid = self._register_ids[span] = len(self.registers)
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
        """(data code, value, kind code, day ns) for a value span."""
        found = self._values.get(span)
        if found is not None:
            return found
        try:
            text, value, kind, day_ns = parse_value_span(span)
            result: tuple[int, int, int, int] | FieldError = (
                self.data.code(text),
                value,
                DATA_KINDS.index(kind),
                day_ns,
            )
        except FieldError as exc:
            result = exc
        except ValueError:
            result = FieldError("fields", "expected 12 tab-separated Key:Value fields")
        if len(self._values) >= _VALUE_CACHE_MAX:
            self._values.clear()  # bounded: a cache, not a store
        self._values[span] = result
        return result

    def arrays(self) -> dict[str, np.ndarray]:
        """Per-register lookup arrays (indexed by register_id)."""
        if self._arrays_len != len(self.registers):
            regs = self.registers
            self._arrays = {
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
            self._arrays_len = len(regs)
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


@dataclass
class _Tokens:
    """A chunk cut into spans (thread-pool output, before dictionary merging)."""

    chunk: Chunk
    buf: bytes
    starts: np.ndarray
    ends: np.ndarray
    blank: np.ndarray
    shaped: np.ndarray  # line indices with 12 fields
    reg_idx: np.ndarray
    reg_dict: list[bytes]
    val_idx: np.ndarray
    val_dict: list[bytes]
    tod_ns: np.ndarray
    subsecond: np.ndarray
    time_ok: np.ndarray
    time_starts: np.ndarray


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
    return enc.indices.to_numpy(zero_copy_only=False), enc.dictionary.to_pylist()


def _tokenize(chunk: Chunk) -> _Tokens:
    """Cut a chunk into lines and spans: numpy and Arrow only, no per-line Python."""
    data = chunk.data if chunk.data.endswith(b"\n") else chunk.data + b"\n"
    size = len(data)
    buf = data + b"\0" * _PAD
    arr = np.frombuffer(buf, np.uint8)
    # Unaligned 4- and 8-byte loads at any offset (little-endian), for view
    # prefixes and for reading "HH:MM:SS" as one word.
    u4 = np.ndarray(shape=(size + _PAD - 8,), dtype="<u4", buffer=buf, strides=(1,))
    u8 = np.ndarray(shape=(size + _PAD - 8,), dtype="<u8", buffer=buf, strides=(1,))
    body = arr[:size]

    sep = np.flatnonzero(body < 11)
    sep_val = body[sep]
    if (sep_val < 9).any():  # other control bytes: not separators
        keep = sep_val >= 9
        sep, sep_val = sep[keep], sep_val[keep]
    is_nl = sep_val == 10
    nl = sep[is_nl]
    nl_i = np.flatnonzero(is_nl)
    prev_i = np.empty_like(nl_i)
    prev_i[:1] = -1
    prev_i[1:] = nl_i[:-1]
    n_tabs = nl_i - prev_i - 1
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

    shaped = np.flatnonzero(n_tabs == N_TABS)
    base = prev_i[shaped] + 1
    t8, t10 = sep[base + 8], sep[base + 10]
    st, en = starts[shaped], ends[shaped]
    # Trailing-blank trimming may have moved a line end before its last tab.
    reg_len = t8 - st
    val_len = t10 - t8 - 1
    viewable = (reg_len > _VIEW_INLINE_MAX) & (val_len > _VIEW_INLINE_MAX) & (en > t10)
    if not viewable.all():
        shaped, t8, t10, st, en = shaped[viewable], t8[viewable], t10[viewable], st[viewable], en[viewable]
        reg_len, val_len = reg_len[viewable], val_len[viewable]
    view_buf = pa.py_buffer(buf)
    reg_idx, reg_dict = _encode(view_buf, u4, st, reg_len)
    val_idx, val_dict = _encode(view_buf, u4, t8 + 1, val_len)

    # Time: "Time:HH:MM:SS" plus an optional ".f" of 1-9 digits.
    ts = t10 + 1
    tlen = en - ts
    w_key = u8[ts]
    w_hms = u8[ts + 5]
    ok = (w_key & np.uint64(0xFF_FFFF_FFFF)) == np.uint64(_TIME_KEY)
    ok &= (tlen == 13) | ((tlen >= 15) & (tlen <= 23))
    digits = []
    for k in (0, 1, 3, 4, 6, 7):
        b = ((w_hms >> np.uint64(8 * k)) & np.uint64(0xFF)).astype(np.int64) - 48
        ok &= (b >= 0) & (b <= 9)
        digits.append(b)
    for k in (2, 5):
        ok &= ((w_hms >> np.uint64(8 * k)) & np.uint64(0xFF)) == np.uint64(ord(":"))
    hh = digits[0] * 10 + digits[1]
    mm = digits[2] * 10 + digits[3]
    ss = digits[4] * 10 + digits[5]
    ok &= (hh < 24) & (mm < 60) & (ss < 60)
    tod = ((hh * 60 + mm) * 60 + ss) * _NS
    n_frac = np.where((tlen >= 15) & (tlen <= 23), tlen - 14, 0)
    subsecond = n_frac > 0
    if subsecond.any():
        ok &= ~subsecond | (arr[ts + 13] == ord("."))
        frac = np.zeros(len(ts), np.int64)
        for k in range(int(n_frac.max())):
            has = n_frac > k
            b = arr[ts + 14 + k].astype(np.int64) - 48
            ok &= ~has | ((b >= 0) & (b <= 9))
            frac = np.where(has, frac * 10 + b, frac)
        tod += frac * _POW10[9 - np.minimum(n_frac, 9)]
    return _Tokens(
        chunk=chunk,
        buf=data,
        starts=starts,
        ends=ends,
        blank=blank,
        shaped=shaped,
        reg_idx=reg_idx,
        reg_dict=reg_dict,
        val_idx=val_idx,
        val_dict=val_dict,
        tod_ns=tod,
        subsecond=subsecond,
        time_ok=ok,
        time_starts=ts,
    )


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

        def overlong(o: OverlongLine) -> None:
            fr.lines_read += 1
            self.report.reject(
                fr,
                o.line,
                "too long",
                f"line longer than {self.max_line_bytes} bytes ({o.length} bytes)",
                o.head,
            )

        pending: deque[Future[_Tokens]] = deque()
        try:
            source = iter_chunks(
                stream,
                info,
                chunk_bytes=self.chunk_bytes,
                max_line_bytes=self.max_line_bytes,
                on_overlong=overlong,
                on_bytes=progress,
                name=name,
            )
            for chunk in source:
                pending.append(pool.submit(_tokenize, chunk))
                if len(pending) > self.workers:
                    yield self._resolve(pending.popleft().result(), fr, file_id)
            while pending:
                yield self._resolve(pending.popleft().result(), fr, file_id)
        finally:
            for fut in pending:
                fut.cancel()
            stream.close()
            raw.close()
        fr.ends_without_newline = info.ends_without_newline
        fr.bytes_read = last_pos

    def _resolve(self, tok: _Tokens, fr: FileReport, file_id: int) -> DiagChunk:
        """Merge a chunk's span dictionaries into the registry; reject bad lines."""
        reg = self.registry
        n_lines = len(tok.starts)
        fr.lines_read += n_lines
        first_line = tok.chunk.first_line

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
        lines = tok.shaped[good]
        vi = tok.val_idx[good]
        out = DiagChunk(
            file_id=file_id,
            register_id=rid[good],
            time_ns=val_cols[3][vi] + tok.tod_ns[good],
            subsecond=tok.subsecond[good],
            value=val_cols[1][vi],
            data_code=val_cols[0][vi].astype(np.int32),
            data_kind=val_cols[2][vi].astype(np.int8),
            line=lines.astype(np.int64) + first_line,
        )
        fr.records += len(out)
        reg.count_records(out.register_id)

        # Everything else is blank or rejected: few lines, so Python is fine here.
        accounted = np.zeros(n_lines, bool)
        accounted[lines] = True
        blank = tok.blank & ~accounted
        fr.blank += int(blank.sum())
        accounted |= blank
        last_line_open = tok.chunk.final and not tok.chunk.data.endswith(b"\n")
        bad_shaped = ~good
        shaped_pos = {int(li): j for j, li in enumerate(tok.shaped[bad_shaped])}
        bad_reg = tok.reg_idx[bad_shaped]
        bad_val = tok.val_idx[bad_shaped]
        bad_ts = tok.time_starts[bad_shaped]
        for li in np.flatnonzero(~accounted):
            raw = tok.buf[tok.starts[li] : tok.ends[li]]
            j = shaped_pos.get(int(li))
            if j is None:
                if not raw.strip():
                    fr.blank += 1
                    continue
                category, reason = _shape_reason(raw)
            elif int(bad_reg[j]) in reg_err:
                e = reg_err[int(bad_reg[j])]
                category, reason = e.category, e.reason
            elif int(bad_val[j]) in val_err:
                e = val_err[int(bad_val[j])]
                category, reason = e.category, e.reason
            else:
                category, reason = "Time", describe_time(tok.buf[bad_ts[j] : tok.ends[li]])
            if last_line_open and li == n_lines - 1:
                category, reason = "truncated", f"truncated last line (no newline at end of file): {reason}"
            self.report.reject(fr, first_line + int(li), category, reason, raw)

        return out


def _shape_reason(raw: bytes) -> tuple[str, str]:
    if b"\0" in raw or sum(b < 32 and b not in (9, 13) for b in raw[:256]) > 2:
        return "binary", "binary data, not a text record"
    n = raw.count(b"\t") + 1
    if n == len(FIELD_KEYS):
        return "fields", "field too short to be a record (empty fields?)"
    return "fields", f"expected {len(FIELD_KEYS)} tab-separated Key:Value fields, found {n}"


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


def _categorical(codes: np.ndarray, values: list[str]) -> pd.Categorical:
    cats = pd.Index(values, dtype=pd.StringDtype("pyarrow"))
    return pd.Categorical.from_codes(codes, categories=cats, validate=False)


def chunks_to_frame(chunks: list[DiagChunk], registry: DiagRegistry) -> pd.DataFrame:
    """One DataFrame (the documented record table) from parsed chunks."""
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
