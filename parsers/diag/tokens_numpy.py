"""The numpy tokenizer of diagnostic records: numpy and Arrow only, no Python loop per line.

The reference for the compiled tokenizer (:func:`parsers.diag.tokens.tokenize_compiled`, which cuts alike):
numpy finds a chunk's newlines, 8-byte loads its last three tabs, Arrow dictionary-encodes the register and
value spans as binary views of the chunk (no copy), and byte arithmetic on 8-byte words (SWAR) reads the time.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from parsers.diag.tokens import Tokens, chunk_bytes
from parsers.sources import Chunk
from parsers.units import NS

if TYPE_CHECKING:
    import pyarrow as pa

# Arrow's binary-view layout stores spans of up to 12 bytes inline; every
# valid span here is longer, so shorter ones are rejected before viewing.
_VIEW_INLINE_MAX = 12
_VIEW = np.dtype([("len", "<i4"), ("prefix", "<u4"), ("buf", "<i4"), ("off", "<i4")])
_TIME_KEY = int.from_bytes(b"Time:", "little")
_POW10 = np.array([10**k for k in range(10)], dtype=np.int64)


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


def tokenize_numpy(chunk: Chunk) -> Tokens:
    """Cut a chunk into lines and spans: numpy and Arrow only, no per-line Python.

    Only newlines are scanned for.  In a record the last three tabs stand
    before Time (at most 24 bytes from the end), before Date (exactly 16
    bytes earlier: ``Date:YYYY-MM-DD``) and before Data (a short field);
    they are found with 8-byte loads.  The tab count of the rest is checked
    when each distinct register span is parsed.
    """
    data = chunk_bytes(chunk)
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
    return Tokens(
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
