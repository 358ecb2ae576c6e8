"""Frauscher-style diagnostic records → a columnar table.

A record is one line of twelve tab-separated ``Key:Value`` fields (spaces for the tabs are read too, off the
fast path: a record copied from an e-mail or a PDF)::

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

import contextlib
import os
import re
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from parsers.diag.fields import (
    DATA_KINDS,
    FIELD_KEYS,
    FieldError,
    parse_time,
)
from parsers.diag.registry import DiagRegistry
from parsers.report import FileReport, ParseReport, escape_name
from parsers.sources import (
    DEFAULT_CHUNK_BYTES,
    DEFAULT_MAX_LINE_BYTES,
    Chunk,
    OverlongLine,
    ReadFailure,
    iter_chunks,
    open_input,
)
from parsers.units import NS

try:
    from parsers.diag import compiled_tokens
except ImportError:  # built without a C compiler: the numpy tokenizer
    compiled_tokens = None  # type: ignore[assignment]

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

# Re-exported: the record's fields and the registry are part of this module's interface.
__all__ = ["DiagChunk", "DiagReader", "chunks_to_frame", "read_diag"]

# Arrow's binary-view layout stores spans of up to 12 bytes inline; every
# valid span here is longer, so shorter ones are rejected before viewing.
_VIEW_INLINE_MAX = 12
_VIEW = np.dtype([("len", "<i4"), ("prefix", "<u4"), ("buf", "<i4"), ("off", "<i4")])
_TIME_KEY = int.from_bytes(b"Time:", "little")
_POW10 = np.array([10**k for k in range(10)], dtype=np.int64)


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
    import pyarrow as pa  # only the numpy tokenizer uses Arrow: the compiled one's start-up does not load it

    v = np.empty(len(starts), _VIEW)
    v["len"] = lens
    v["prefix"] = u4[starts]
    v["buf"] = 0
    v["off"] = starts
    return pa.Array.from_buffers(pa.binary_view(), len(starts), [None, pa.py_buffer(v), view_buf])


def _call_function(name: str, args: list[pa.Array]) -> Any:
    """An Arrow compute function by name.  ``Array.dictionary_encode()`` would import ``pyarrow.compute``
    (its Python wrappers and their docstrings: about a tenth of a second at every start); the function
    registry itself is in the compiled ``pyarrow._compute``."""
    try:
        from pyarrow._compute import call_function
    except ImportError:  # a pyarrow that moved it: the public module
        from pyarrow.compute import call_function
    return call_function(name, args)


def _encode(
    view_buf: pa.Buffer, u4: np.ndarray, starts: np.ndarray, lens: np.ndarray
) -> tuple[np.ndarray, list[bytes]]:
    if len(starts) == 0:
        return np.zeros(0, np.int32), []
    enc = _call_function("dictionary_encode", [_views(view_buf, u4, starts, lens)])
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
    rows: np.ndarray | None = None  # the rows still searched (None: all); most find their tab in the first word
    for k in range(1, words + 1):
        base = (window_end if rows is None else window_end[rows]) - 8 * k
        mask = _tab_bytes(u8[base])
        hit = mask != 0
        if hit.any():
            # Set bits sit at 8j+7 and are sparse, so float log2 finds the top one exactly.
            top = (np.log2(mask[hit].astype(np.float64)).astype(np.int64) - 7) // 8
            found[hit if rows is None else rows[hit]] = base[hit] + top
        miss = ~hit
        if not miss.any():
            break
        rows = np.flatnonzero(miss) if rows is None else rows[miss]
    return found


_DIGIT_BYTES = np.uint64(0x3030303030303030)
# Per count of fraction digits k (0-8): the top k bytes of the line's last 8, where those digits are.
_FRACTION_BYTES = np.array([(1 << 64) - (1 << (8 * (8 - k))) if k else 0 for k in range(9)], np.uint64)


def _fraction_digits(
    arr: np.ndarray, u8: np.ndarray, en: np.ndarray, n_frac: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The value of the ``n_frac`` (0-9) digits that end each line, and whether they are all digits.

    The last 8 bytes of a line are one little-endian word, so its digits are its top bytes; the bytes
    before them are masked to 0 (leading zeros) and all 8 are combined in three multiply-shift steps
    (pairs, then fours, then eights), with no loop per digit.  A ninth digit is read on its own.
    """
    x = (u8[en - 8] ^ _DIGIT_BYTES) & _FRACTION_BYTES[np.minimum(n_frac, 8)]
    # A byte that is 10 or more (or has its top bit set) after the XOR was not a digit; masked bytes are 0.
    ok = (((x + _HMS_DIGIT_LIMIT) | x) & _HIGH_BITS) == 0
    x = ((x * np.uint64(10)) + (x >> np.uint64(8))) & np.uint64(0x00FF00FF00FF00FF)
    x = ((x * np.uint64(100)) + (x >> np.uint64(16))) & np.uint64(0x0000FFFF0000FFFF)
    x = (x * np.uint64(10000)) + (x >> np.uint64(32))
    value = (x & np.uint64(0xFFFFFFFF)).astype(np.int64)
    nine = n_frac == 9
    if nine.any():
        first = arr[en[nine] - 9].astype(np.int64) - 48
        ok[nine] &= (first >= 0) & (first <= 9)
        value[nine] += first * 10**8
    return value, ok


# A valid record is never shorter than this; shorter lines take the slow path,
# which also keeps the backward byte windows inside the line.
_MIN_FAST_LINE = 64


def _chunk_bytes(chunk: Chunk) -> memoryview | bytes:
    """The chunk's data, ending with a newline (a last line without one gets it)."""
    return chunk.data if chunk.ends_with_newline() else bytes(chunk.data) + b"\n"


def _tokenize_compiled(chunk: Chunk) -> _Tokens:
    """:func:`_tokenize_numpy`'s cut, in one compiled pass without the GIL (``compiled_tokens.c``)."""
    assert compiled_tokens is not None
    data = _chunk_bytes(chunk)
    n_fast, starts, ends, blank, fast, reg_idx, reg_dict, val_idx, val_dict, tod, subsecond, time_ok = (
        compiled_tokens.tokenize(data)
    )
    return _Tokens(
        chunk=chunk,
        buf=data,
        starts=np.frombuffer(starts, np.intp),
        ends=np.frombuffer(ends, np.intp),
        blank=np.frombuffer(blank, np.bool_),
        fast=np.frombuffer(fast, np.intp)[:n_fast],
        reg_idx=np.frombuffer(reg_idx, np.intp)[:n_fast],
        reg_dict=reg_dict,
        val_idx=np.frombuffer(val_idx, np.intp)[:n_fast],
        val_dict=val_dict,
        tod_ns=np.frombuffer(tod, np.int64)[:n_fast],
        subsecond=np.frombuffer(subsecond, np.bool_)[:n_fast],
        time_ok=np.frombuffer(time_ok, np.bool_)[:n_fast],
    )


def _tokenize_numpy(chunk: Chunk) -> _Tokens:
    """Cut a chunk into lines and spans: numpy and Arrow only, no per-line Python.

    Only newlines are scanned for.  In a record the last three tabs stand
    before Time (at most 24 bytes from the end), before Date (exactly 16
    bytes earlier: ``Date:YYYY-MM-DD``) and before Data (a short field);
    they are found with 8-byte loads.  The tab count of the rest is checked
    when each distinct register span is parsed.
    """
    data = _chunk_bytes(chunk)
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
        last = arr[ends - 1]
        trail = (ends > starts) & ((last == 13) | (last == 32))
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
    import pyarrow as pa

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
    tod = ((hh * 60 + mm) * 60 + ss) * NS
    n_frac = np.where((tlen >= 15) & (tlen <= 23), tlen - 14, 0)
    subsecond = n_frac > 0
    if subsecond.any():
        point = arr[np.minimum(ts + 13, size - 1)]
        time_ok &= ~subsecond | (point == ord(".")) | (point == ord(","))  # a decimal comma: German exports
        frac, frac_ok = _fraction_digits(arr, u8, en, n_frac)
        time_ok &= frac_ok
        tod += frac * _POW10[9 - n_frac]
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


def _gather_compiled(tok: _Tokens, reg_lut: np.ndarray, val_cols: np.ndarray, val_ok: np.ndarray) -> _Gathered:
    """:func:`_gather_numpy`'s columns in one compiled pass without the GIL (``compiled_tokens.c``)."""
    assert compiled_tokens is not None
    n_good, *cols, bad = compiled_tokens.gather_records(
        reg_lut,
        tok.reg_idx,
        tok.val_idx,
        np.ascontiguousarray(val_cols),
        val_ok,
        tok.time_ok,
        tok.tod_ns,
        tok.subsecond,
        tok.fast,
    )
    got: list[np.ndarray] = [np.frombuffer(c, t)[:n_good] for c, t in zip(cols, _GATHERED_TYPES, strict=True)]
    return (*got, np.frombuffer(bad, np.intp)[: len(tok.fast) - n_good])  # type: ignore[return-value]


def _gather_numpy(tok: _Tokens, reg_lut: np.ndarray, val_cols: np.ndarray, val_ok: np.ndarray) -> _Gathered:
    """The record columns of a chunk's good fast lines (register and value spans valid, time read), and the
    positions of the other fast lines."""
    rid = reg_lut[tok.reg_idx]
    good = (rid >= 0) & val_ok[tok.val_idx] & tok.time_ok
    if good.all():  # the usual chunk: no selection to copy (the token arrays are this chunk's alone)
        vi, rid_g, tod_ns, subsecond, lines = tok.val_idx, rid, tok.tod_ns, tok.subsecond, tok.fast
    else:
        vi, rid_g, tod_ns = tok.val_idx[good], rid[good], tok.tod_ns[good]
        subsecond, lines = tok.subsecond[good], tok.fast[good]
    time_ns = val_cols[3][vi] + tod_ns
    value = val_cols[1][vi]
    # Narrowed per distinct value span, before the gather: no conversion per record.
    data_code = val_cols[0].astype(np.int32)[vi]
    data_kind = val_cols[2].astype(np.int8)[vi]
    return rid_g, time_ns, value, data_code, data_kind, subsecond, lines, np.flatnonzero(~good)


# register id, time ns, value, data code, data kind, subsecond, line (per good fast line); bad fast lines.
_Gathered = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
_GATHERED_TYPES = (np.int32, np.int64, np.int64, np.int32, np.int8, np.bool_, np.intp)

# The compiled tokenizer where it was built (``pip install`` with a C compiler), unless TRACKSIDE_PURE=1 asks
# for the numpy one: both give the same tokens (tests/test_diag_compiled.py).
_COMPILED = compiled_tokens is not None and not os.environ.get("TRACKSIDE_PURE")
_tokenize: Callable[[Chunk], _Tokens] = _tokenize_compiled if _COMPILED else _tokenize_numpy
_gather = _gather_compiled if _COMPILED else _gather_numpy


def compiled_tokenizer() -> bool:
    """Whether the compiled tokenizer is in use."""
    return _tokenize is _tokenize_compiled


# Below this chunk size the thread pool's hand-over costs more than tokenizing in the reading thread.
_POOL_MIN_CHUNK_BYTES = 256 << 10


@dataclass
class _Ready:
    """A chunk tokenized in the reading thread, queued like a worker's future."""

    tokens: _Tokens

    def result(self) -> _Tokens:
        return self.tokens


class _ReadAhead:
    """The items of an iterator, each fetched on a thread of its own while the one before is used."""

    def __init__(self, items: Iterator[Chunk | OverlongLine]) -> None:
        self._items = items
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trackside-read")
        self._next: Future[Chunk | OverlongLine | None] | None = self._pool.submit(self._fetch)

    def _fetch(self) -> Chunk | OverlongLine | None:
        return next(self._items, None)

    def __iter__(self) -> Iterator[Chunk | OverlongLine]:
        while self._next is not None:
            item = self._next.result()
            if item is None:
                self._next = None
                return
            self._next = self._pool.submit(self._fetch)
            yield item

    def close(self) -> None:
        """Wait for the read in flight (its result or error dropped), then stop the thread."""
        if self._next is not None:
            self._next.cancel()
            with contextlib.suppress(BaseException):
                self._next.result()
            self._next = None
        self._pool.shutdown()


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

        source = iter_chunks(
            stream,
            info,
            chunk_bytes=self.chunk_bytes,
            max_line_bytes=self.max_line_bytes,
            on_bytes=progress,
            name=name,
            recycle=done_buffers,
        )
        # The next chunk is read on a thread of its own while this thread resolves the last one: the read
        # (a copy from the kernel or the decompressor) releases the GIL.
        ahead = _ReadAhead(source) if not inline else None
        try:
            for item in ahead if ahead is not None else source:
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
            if ahead is not None:
                ahead.close()  # no read in flight when the stream closes
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

        reg_lut, reg_err = reg.register_ids(tok.reg_dict)
        val_cols, val_err = reg.values(tok.val_dict)
        val_ok = np.ones(len(tok.val_dict), bool)
        val_ok[list(val_err)] = False

        rid_g, time_ns, value, data_code, data_kind, subsecond, lines, bad_j = _gather(tok, reg_lut, val_cols, val_ok)

        # The rest is blank, off the fast path, or rejected: few lines, Python is fine.
        n_blank = int(tok.blank.sum())
        fr.blank += n_blank
        rest_lines: list[int] = []
        if len(lines) + n_blank < n_lines:  # else every line is a record or blank (fast lines are never blank)
            rest = np.ones(n_lines, bool)
            rest[lines] = False
            rest &= ~tok.blank
            rest_lines = np.flatnonzero(rest).tolist()
        bad_fast = dict(zip(tok.fast[bad_j].tolist(), bad_j.tolist(), strict=True))
        last_open = tok.chunk.final and not tok.chunk.ends_with_newline()
        slow: list[tuple[int, int, int, bool, int, int, int]] = []
        for li in rest_lines:
            raw = bytes(tok.buf[tok.starts[li] : tok.ends[li]])
            j = bad_fast.get(li)
            if j is not None and b" " in raw and _spaced_fields(raw) is not None:
                j = None  # spaces for some of its tabs: the fast path cut it wrong, the slow one reads it
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
            spaced = _spaced_fields(raw)
            if spaced is None:
                return FieldError(*_shape_reason(raw, len(parts)))
            parts = spaced
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


# A record whose tabs became spaces (copied from an e-mail, a PDF, a terminal): its fields are cut before each
# key instead.  The keys are fixed and in order; a label keeps its inner spaces ("Label:Software V").
_SPACED_FIELDS = re.compile(("[ \t]+(?=(?:" + "|".join(FIELD_KEYS[1:]) + "):)").encode())


def _spaced_fields(raw: bytes) -> list[bytes] | None:
    """A record's twelve fields when spaces stand for its tabs; None when it is no such record."""
    parts = _SPACED_FIELDS.split(raw.strip())
    if len(parts) != len(FIELD_KEYS):
        return None
    if any(part.partition(b":")[0] != key.encode() for part, key in zip(parts, FIELD_KEYS, strict=True)):
        return None
    return parts


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


def _present_heads(codes: np.ndarray, registry: DiagRegistry) -> pd.Categorical:
    """The head column with only the heads its records name as categories (in the registry's order)."""
    import pandas as pd

    codes = np.asarray(codes).ravel()
    present = np.unique(codes[codes >= 0])
    at = np.where(codes >= 0, np.searchsorted(present, codes), -1).astype(np.int32)  # -1: no head, as given
    cats = pd.Index([_utf8_name(v) for v in registry.heads.take(present)], dtype=pd.StringDtype("pyarrow"))
    return pd.Categorical.from_codes(at, categories=cats, validate=False)


def chunks_to_frame(chunks: list[DiagChunk], registry: DiagRegistry, all_heads: bool = True) -> pd.DataFrame:
    """One DataFrame (the documented record table) from parsed chunks.

    ``all_heads``: the head column's categories are every head of the registry; without, only the heads
    the chunks' records name (a few registers kept from a log that names a million heads)."""
    import pandas as pd

    rid = np.concatenate([c.register_id for c in chunks]) if chunks else np.zeros(0, np.int32)

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(c, name) for c in chunks]) if chunks else np.zeros(0)

    arrays = registry.arrays() if registry.n_registers else None

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
            # All head names, not kept as a list by the registry (a log may name a million heads).
            "counting_head": _categorical(
                reg("counting_head", "int32"), registry.heads.take(np.arange(len(registry.heads)))
            )
            if all_heads
            else _present_heads(reg("counting_head", "int32"), registry),
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
