"""The passages array as JSON text, built with numpy byte arithmetic.

Writes, byte for byte, what ``frame_json.passages_json_text`` gets from
pandas' ``DataFrame.to_json(orient="records", force_ascii=True,
double_precision=10)``, without pandas and without a Python loop per
passage: every value becomes a fixed-width row of bytes (padding is the
0 byte), the rows of a batch of passages are laid side by side with the
keys, and dropping the 0 bytes leaves the JSON text.

Numbers follow pandas' encoder (ultrajson's ``Buffer_AppendDoubleUnchecked``):
a float is its whole part, a point and at most ten decimals, rounded half to
even-ish as the encoder does, trailing zeros dropped (``17.0``, ``6.105``).
Values outside what this covers (text that would need escaping, floats the
encoder writes in exponent form, infinities) return None: the caller then
uses pandas.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np

from console.analysis.head_table import Heads, heads_at
from console.analysis.passages.buckets import Columns, squeeze_rows
from console.analysis.timefmt import exact_ns
from parsers.units import NS_PER_DAY

try:
    from console.analysis.passages import compiled_json
except ImportError:  # built without a C compiler: the numpy path alone
    compiled_json = None  # type: ignore[assignment]

_PRECISION = 10
_POW10_FRAC = float(10**_PRECISION)
_SAFE = frozenset(chr(c) for c in range(0x20, 0x7F)) - {'"', "\\", "/"}
_NULL = np.frombuffer(b"null", np.uint8)
# Rows × axle slots per batch of the per-axle lists: bounds the scratch memory.
_BATCH_ROWS = 8192
_BATCH_CELLS = 1 << 18


@dataclass(frozen=True)
class _Style:
    """How a passage object is laid out: its brace, separators and closing, its per-axle list's, and
    how floats are written."""

    first: str
    sep: str
    colon: str
    close: str
    list_open: str
    list_sep: str
    list_close: str
    python_floats: bool = False

    def floats(self, values: np.ndarray) -> np.ndarray | None:
        return _python_floats(values) if self.python_floats else _floats(values)


def _indented_style(depth: int) -> _Style:
    """An object ``depth`` levels deep as ``json.dumps(indent=1)`` writes it, floats as Python writes them."""

    def pad(d: int) -> str:
        return "\n" + " " * d

    return _Style(
        "{" + pad(depth + 1),
        "," + pad(depth + 1),
        ": ",
        pad(depth) + "}",
        "[" + pad(depth + 2),
        "," + pad(depth + 2),
        pad(depth + 1) + "]",
        python_floats=True,
    )


def _const(text: str, n: int) -> np.ndarray:
    return np.broadcast_to(np.frombuffer(text.encode("ascii"), np.uint8), (n, len(text)))


@cache
def _quad_tables() -> np.ndarray:
    """The four decimal digits of 0…9999 as one 4-byte word each, in three tables: every digit (0); leading
    zeros as 0 bytes, a zero's last digit kept (1); nothing at all, the 0 bytes of a zero (2)."""
    digits = (np.arange(10_000)[:, None] // np.array([1000, 100, 10, 1]) % 10).astype(np.uint8)
    lead = np.cumsum(digits != 0, axis=1) == 0
    lead[:, -1] = False
    blanked = np.where(lead, 0, digits + ord("0")).astype(np.uint8)
    tables = np.stack([digits + ord("0"), blanked, np.zeros_like(digits)])
    return np.ascontiguousarray(tables).view(np.uint32).reshape(3 * 10_000)


def _digits(u: np.ndarray, width: int | None = None, keep_leading: bool = False) -> np.ndarray:
    """Decimal digits of unsigned ints, right-aligned in ``width`` bytes (default: as many as the largest needs).

    Leading zeros are 0 bytes (a zero keeps its last digit) unless
    ``keep_leading``.
    """
    u = np.asarray(u, np.uint64)
    if width is None:
        width = len(str(int(u.max()))) if len(u) else 1
    # Four digits at a time, each group looked up as one word: a division by one number (numpy's fast path)
    # per group, not one by a different power of ten per digit.
    n, groups = len(u), -(-width // 4)
    words = np.empty((n, groups), np.uint32)
    quad = np.empty((groups, n), np.intp)
    high = u
    ten_k = np.uint64(10_000)
    for j in range(groups - 1, -1, -1):
        low = high // ten_k
        quad[j] = high - low * ten_k
        high = low
    seen = np.zeros(n, bool)
    quads = _quad_tables()
    for j in range(groups):
        table = quad[j]
        if not keep_leading:
            # Before the first group with a digit other than 0: nothing; that group without its leading zeros.
            nonzero = table != 0
            last = j == groups - 1
            table = table + np.where(seen, 0, np.where(nonzero | last, 10_000, 20_000))
            seen |= nonzero
        words[:, j] = quads[table]
    return words.view(np.uint8).reshape(n, 4 * groups)[:, 4 * groups - width :]


_COMPACT = _Style("{", ",", ":", "}", "[", ",", "]")


def _with_null(tokens: np.ndarray, null: np.ndarray) -> np.ndarray:
    if null.any():
        pad = max(0, len(_NULL) - tokens.shape[1])
        tokens = np.pad(tokens, ((0, 0), (0, pad))) if pad else tokens.copy()
        tokens[null] = 0
        tokens[null, : len(_NULL)] = _NULL
    return tokens


def _ints(values: np.ndarray, null: np.ndarray | None = None) -> np.ndarray | None:
    v = np.asarray(values, np.int64)
    if len(v) and v.min() == np.iinfo(np.int64).min:
        return None
    neg = v < 0
    sign = np.where(neg, ord("-"), 0).astype(np.uint8)[:, None]
    out = np.concatenate([sign, _digits(np.abs(v).astype(np.uint64))], axis=1)
    return _with_null(out, null) if null is not None else out


def _floats(values: np.ndarray) -> np.ndarray | None:
    """ultrajson's fixed-point form with ten decimals; NaN as null."""
    found = _float_tokens(values)
    return None if found is None else found[0]


def _floats_covered(v: np.ndarray) -> bool:
    """Whether every float is written in fixed point (not the encoder's exponent form, nor an error)."""
    a = np.abs(np.where(np.isnan(v), 0.0, v))
    return not (np.isinf(a).any() or ((a > 1e16 - 1) | ((a != 0) & (a < 1e-15))).any())


def _float_tokens(values: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_floats`, and how many decimals each value is written with."""
    v = np.asarray(values, np.float64)
    if not _floats_covered(v):
        return None  # the encoder's exponent form (or an error): not covered here
    nan = np.isnan(v)
    a = np.abs(np.where(nan, 0.0, v))
    neg = v < 0
    whole = a.astype(np.uint64)
    tmp = (a - whole.astype(np.float64)) * _POW10_FRAC
    frac = tmp.astype(np.uint64)
    diff = tmp - frac.astype(np.float64)
    odd = (frac & np.uint64(1)) == 1
    frac = frac + ((diff > 0.5) | ((diff == 0.5) & ((frac == 0) | odd))).astype(np.uint64)
    roll = frac >= np.uint64(10**_PRECISION)
    frac[roll] = 0
    whole = whole + roll.astype(np.uint64)
    # Decimals: ten digits with leading zeros; trailing zeros go (none at all
    # is ".0").  Trailing zero digits common to every value are not computed.
    shift = 0
    while shift < _PRECISION - 1 and not (frac % np.uint64(10 ** (shift + 1))).any():
        shift += 1
    width = _PRECISION - shift
    digits = frac // np.uint64(10**shift)
    fd = _digits(digits, width, keep_leading=True)
    # The decimals kept: the width less the value's trailing zeros (all of them in a zero).
    kept = np.full(len(v), width, np.intp)
    for k in range(1, width + 1):
        p10 = np.uint64(10**k)
        kept -= digits - digits // p10 * p10 == 0
    fd = np.where(np.arange(width)[None, :] < kept[:, None], fd, np.uint8(0))
    fd[:, 0] = np.where(frac == 0, ord("0"), fd[:, 0])
    n = len(v)
    out = np.concatenate(
        [
            np.where(neg, ord("-"), 0).astype(np.uint8)[:, None],
            _digits(whole),
            np.full((n, 1), ord("."), np.uint8),
            fd,
        ],
        axis=1,
    )
    return _with_null(out, nan), np.maximum(kept, 1)


def _python_floats(values: np.ndarray) -> np.ndarray | None:
    """The floats as ``json.dumps`` writes what ``json.loads`` read from :func:`_floats`' text (Python's
    shortest repr: ``1e-06`` where pandas writes ``0.000001``); NaN as null."""
    found = _float_tokens(values)
    if found is None:
        return None
    tokens, decimals = found  # decimals written: the bytes after the point (NaN: any, it is null)
    v = np.asarray(values, np.float64)
    nan = np.isnan(v)
    a = np.abs(np.where(nan, 0.0, v))
    # Where a float's spacing is below the last decimal written, no shorter decimal reads back as the same
    # float, so the repr is the text as written (Python writes 1e-4 <= |v| < 1e16 without an exponent).
    # The others (exponents, floats too coarse for ten decimals): repr of what json reads, once per value.
    same = nan | (a == 0) | ((a >= 1e-4) & (np.spacing(a) * 10.0 ** np.maximum(decimals, 0) < 0.25))
    other = np.flatnonzero(~same)
    if len(other):
        uniq, first, which = np.unique(v[other], return_index=True, return_inverse=True)
        texts = []
        for row in tokens[other[first]]:
            texts.append(repr(float(row[row != 0].tobytes().decode("ascii"))).encode("ascii"))
        width = max(tokens.shape[1], max(len(t) for t in texts))
        table = np.zeros((len(uniq), width), np.uint8)
        for i, t in enumerate(texts):
            table[i, : len(t)] = np.frombuffer(t, np.uint8)
        tokens = np.pad(tokens, ((0, 0), (0, width - tokens.shape[1])))  # a copy, wider where a repr is
        tokens[other] = table[which.reshape(-1)]
    return tokens


def _json_strings(values: Sequence[str | None]) -> list[bytes] | None:
    """Each of a small set of texts as a JSON string (None: null); None if one would need escaping (left to
    pandas' encoder)."""
    encoded = []
    for s in values:
        if s is None:
            encoded.append(b"null")
        elif set(s) <= _SAFE:
            encoded.append(b'"' + s.encode("ascii") + b'"')
        else:
            return None
    return encoded


def _texts(codes: np.ndarray, values: Sequence[str | None]) -> np.ndarray | None:
    """JSON strings from a small set (codes into values; None is null)."""
    encoded = _json_strings(values)
    if encoded is None:
        return None
    width = max(len(e) for e in encoded)
    table = np.zeros((len(encoded), width), np.uint8)
    for i, e in enumerate(encoded):
        table[i, : len(e)] = np.frombuffer(e, np.uint8)
    return table[codes]


def _iso(ns: np.ndarray) -> np.ndarray | None:
    """``frame_json.iso_strings`` as quoted bytes (UTC, ``Z``, ms at least, µs/ns where present); null for NaN."""
    ints, ok = exact_ns(ns)
    n = len(ints)
    days, tod = np.divmod(ints, NS_PER_DAY)
    # A log spans few days: their dates as text once each, the times by arithmetic.
    uniq, which = np.unique(days, return_inverse=True)
    dates = np.datetime_as_string(uniq.astype("datetime64[D]"))
    if len(dates) and (np.strings.str_len(dates) != 10).any():
        return None  # not YYYY-MM-DD
    date_bytes = dates.astype("S10").view(np.uint8).reshape(len(uniq), 10)[which]
    secs, frac = np.divmod(tod, 10**9)
    hms = _digits((secs // 3600 * 10_000 + secs // 60 % 60 * 100 + secs % 60).astype(np.uint64), 6, keep_leading=True)
    fd = _digits(frac.astype(np.uint64), 9, keep_leading=True)
    # Milliseconds always; micro- and nanoseconds only where the time has them (timefmt.iso).
    keep = np.where(frac % 1_000_000 == 0, 3, np.where(frac % 1_000 == 0, 6, 9))
    fd[np.arange(9)[None, :] >= keep[:, None]] = 0

    def char(c: str) -> np.ndarray:
        return np.full((n, 1), ord(c), np.uint8)

    point = char(".")
    out = np.concatenate(
        [
            char('"'),
            date_bytes,
            char("T"),
            hms[:, 0:2],
            char(":"),
            hms[:, 2:4],
            char(":"),
            hms[:, 4:6],
            point,
            fd,
            char("Z"),
            char('"'),
        ],
        axis=1,
    )
    return _with_null(out, ~ok)


def _bools(values: np.ndarray) -> np.ndarray:
    table = np.zeros((2, 5), np.uint8)
    table[0] = np.frombuffer(b"false", np.uint8)
    table[1, :4] = np.frombuffer(b"true", np.uint8)
    return table[np.asarray(values, bool).astype(np.intp)]


def _choice(texts: tuple[str, str], pick: np.ndarray) -> np.ndarray:
    """Per row, ``texts[1]`` where ``pick`` else ``texts[0]``, as bytes (padded with 0 bytes)."""
    width = max(len(t) for t in texts)
    table = np.zeros((2, width), np.uint8)
    for i, t in enumerate(texts):
        table[i, : len(t)] = np.frombuffer(t.encode("ascii"), np.uint8)
    return table[np.asarray(pick, np.intp)]


def _axle_lists(
    speeds: np.ndarray, start: np.ndarray, stop: np.ndarray, style: _Style | None = None
) -> np.ndarray | None:
    """Per row, ``[v,v,...]`` of its speeds ``speeds[start:stop]``, or null when empty."""
    style = style or _COMPACT
    n = len(start)
    count = stop - start
    width = int(count.max()) if n else 0
    if width == 0:
        return _const("null", n).copy()
    lo, hi = int(start.min()), int(stop.max())
    tok = style.floats(np.round(speeds[lo:hi], 3))
    if tok is None:
        return None
    # Each token then its separator: a comma, or the closing bracket after a row's last.
    is_last = np.zeros(hi - lo, bool)
    is_last[(stop[count > 0] - 1) - lo] = True
    tok = np.concatenate([tok, _choice((style.list_sep, style.list_close), is_last)], axis=1)
    tok = np.concatenate([tok, np.zeros((1, tok.shape[1]), np.uint8)])  # row -1: empty slot
    slot = np.arange(width)
    idx = np.where(slot < count[:, None], start[:, None] - lo + slot, -1)
    body = tok[idx].reshape(n, width * tok.shape[1])
    out = np.concatenate([_choice(("", style.list_open), count > 0), body], axis=1)
    return _with_null(out, count == 0)


def _batch(
    cols: Columns, heads: Heads, lo: int, hi: int, first: bool, opening: str = "{", sep: str = ","
) -> bytes | None:
    rows = _rows(cols, heads, lo, hi, opening)
    if rows is None:
        return None
    seps = np.full((hi - lo, 1), ord(sep), np.uint8)
    if first:
        seps[0] = 0
    return squeeze_rows(np.concatenate([seps, rows], axis=1))[0]


# Field kinds of a passage object (and of compiled_json.encode_objects).
_K_INT, _K_FLOAT, _K_TEXT, _K_ISO, _K_BOOL, _K_AXLES = range(6)


def _fields(c: Columns, heads: Heads) -> list[tuple[str, int, tuple]]:
    """The ``--json`` fields of passages ``c``, in order, for either encoder: (key, kind, values).

    Values per kind: ints (and where null, or None); floats, rounded as written; text codes and the texts;
    times in ns; bools; each row's start and stop into the per-axle speeds (given apart, unsliced)."""
    from console.analysis.counting.wheels import DIRECTION_12, DIRECTION_21
    from console.analysis.passages.buckets import AXLES_UNKNOWN_REASONS, axles_unknown_codes

    # Only these passages' heads: a log may have a million heads and many batches.
    used, head_code = np.unique(c["head"], return_inverse=True)
    head_dev, head_names = heads_at(heads, used)
    n_det = np.asarray(c["records_in_detection_second"], float)
    unknown = axles_unknown_codes(c["detections_sys1"], c["detections_sys2"])

    def rounded(name: str, decimals: int) -> tuple[np.ndarray]:
        return (np.round(np.asarray(c[name], float), decimals),)

    return [
        ("device_id", _K_INT, (head_dev[head_code], None)),
        ("counting_head", _K_TEXT, (head_code, head_names)),
        ("start", _K_ISO, (c["start_ns"],)),
        ("end", _K_ISO, (c["end_ns"],)),
        ("duration_s", _K_FLOAT, rounded("duration_s", 6)),
        ("records", _K_INT, (c["records"], None)),
        ("axles", _K_INT, (c["axles"], None)),
        ("axles_unknown_reason", _K_TEXT, (unknown, AXLES_UNKNOWN_REASONS)),
        ("detections_sys1", _K_INT, (c["detections_sys1"], None)),
        ("detections_sys2", _K_INT, (c["detections_sys2"], None)),
        ("direction", _K_TEXT, (c["direction"], [None, DIRECTION_12, DIRECTION_21, "mixed"])),
        ("detection_second", _K_ISO, (c["detection_second_ns"],)),
        ("records_in_detection_second", _K_INT, (np.nan_to_num(n_det).astype(np.int64), np.isnan(n_det))),
        ("speed_kmh_per_second_method", _K_FLOAT, rounded("speed_kmh_per_second_method", 3)),
        ("speed_kmh_whole_train", _K_FLOAT, rounded("speed_kmh_whole_train", 3)),
        ("speed_kmh_whole_train_min", _K_FLOAT, rounded("speed_kmh_whole_train_min", 3)),
        ("speed_kmh_whole_train_max", _K_FLOAT, rounded("speed_kmh_whole_train_max", 3)),
        ("whole_train_basis", _K_TEXT, (c["whole_train_basis"], [None, "detections", "records"])),
        ("whole_train_duration_s", _K_FLOAT, rounded("whole_train_duration_s", 6)),
        ("speed_kmh_per_axle", _K_AXLES, (c["axle_speeds_start"], c["axle_speeds_stop"])),
        ("speed_kmh_per_axle_mean", _K_FLOAT, rounded("speed_kmh_per_axle_mean", 3)),
        ("subsecond", _K_BOOL, (c["subsecond"],)),
        ("time_resolution_s", _K_FLOAT, (c["time_resolution_s"],)),
        ("kind", _K_TEXT, (c["kind"], ["train", "damping", "status"])),
    ]


def _rows(
    cols: Columns,
    heads: Heads,
    lo: int,
    hi: int,
    opening: str | None = None,
    style: _Style | None = None,
    after: str = "",
) -> np.ndarray | None:
    """Passages ``lo:hi`` as one row of bytes each: its JSON object, padded with 0 bytes (None: not covered).

    ``opening``: what comes before the first key (default the style's brace); ``after``: what follows the
    closing brace.
    """
    c = {k: v[lo:hi] for k, v in cols.items() if k != "axle_speeds_kmh"}
    n = hi - lo
    style = style or _COMPACT
    speeds = cols["axle_speeds_kmh"]
    tokens_of: dict[int, Callable[..., np.ndarray | None]] = {
        _K_INT: _ints,
        _K_FLOAT: style.floats,
        _K_TEXT: _texts,
        _K_ISO: _iso,
        _K_BOOL: _bools,
        _K_AXLES: lambda start, stop: _axle_lists(speeds, start, stop, style),
    }
    blocks = []
    for i, (key, kind, values) in enumerate(_fields(c, heads)):
        tokens = tokens_of[kind](*values)
        if tokens is None:
            return None
        before = (style.first if opening is None else opening) if i == 0 else style.sep
        blocks += [_const(f'{before}"{key}"{style.colon}', n), tokens]
    blocks.append(_const(style.close + after, n))
    return np.concatenate(blocks, axis=1)


def indented_objects(cols: Columns, heads: Heads, depth: int) -> Iterator[bytes] | None:
    """The passages as ``json.dumps(json.loads(text), indent=1)`` lays out the array of
    :func:`encode_passages` ``depth`` levels deep (the report's JSON), without the brackets: each object
    after a comma (the first without), a newline and its indent; in pieces of a batch of passages.

    None if not covered; checked for every batch before the first is given.
    """
    style = _indented_style(depth + 1)
    # Each object opens with its separator, the comma included (one pass over the bytes, not two).
    opening = ",\n" + " " * (depth + 1) + style.first
    blobs: list[bytes] = []
    for lo, hi in _batches(cols):
        rows = _rows(cols, heads, lo, hi, opening, style)
        if rows is None:
            return None
        if lo == 0:
            rows[0, 0] = 0  # the first object's comma: dropped with the padding
        blobs.append(squeeze_rows(rows)[0])
    return iter(blobs)


def _batches(cols: Columns) -> list[tuple[int, int]]:
    """Row ranges to encode at a time: fewer rows per batch where trains have many axles."""
    n = len(cols["head"])
    count = cols["axle_speeds_stop"] - cols["axle_speeds_start"]
    batches = []
    lo = 0
    while lo < n:
        hi = min(n, lo + _BATCH_ROWS)
        while hi - lo > 1 and (hi - lo) * int(count[lo:hi].max()) > _BATCH_CELLS:
            hi = lo + (hi - lo) // 2
        batches.append((lo, hi))
        lo = hi
    return batches


def _encode_objects_numpy(cols: Columns, heads: Heads, after: str = "") -> tuple[bytes, np.ndarray] | None:
    """Each passage as one JSON object (the ``--json`` fields), each followed by ``after`` and then the next,
    and each one's length in bytes (``after`` included); None if not covered (see :func:`encode_passages`)."""
    texts: list[bytes] = []
    lengths: list[np.ndarray] = []
    for lo, hi in _batches(cols):
        rows = _rows(cols, heads, lo, hi, after=after)
        if rows is None:
            return None
        text, length = squeeze_rows(rows)
        texts.append(text)
        lengths.append(length)
    return b"".join(texts), (np.concatenate(lengths) if lengths else np.zeros(0, np.int64)).astype(np.int64)


def _text_table(values: Sequence[str | None]) -> tuple[bytes, np.ndarray] | None:
    """:func:`_texts`' table for the compiled encoder: the JSON strings back to back and their offsets."""
    encoded = _json_strings(values)
    if encoded is None:
        return None
    offsets = np.zeros(len(encoded) + 1, np.int64)
    offsets[1:] = np.cumsum([len(e) for e in encoded])
    return b"".join(encoded), offsets


def _encode_objects_compiled(cols: Columns, heads: Heads, after: str = "") -> tuple[bytes, np.ndarray] | None:
    """:func:`_encode_objects_numpy`'s bytes, formatted by ``compiled_json.c`` without the GIL; the checks
    of what is covered done here first, over whole columns or once per distinct text."""
    assert compiled_json is not None
    n = len(cols["head"])
    if n == 0:
        return b"", np.zeros(0, np.int64)
    fields: list[tuple[object, ...]] = []
    for i, (name, kind, values) in enumerate(_fields(cols, heads)):
        key = (("{" if i == 0 else ",") + f'"{name}":').encode("ascii")
        if kind == _K_INT:
            v, null = np.ascontiguousarray(values[0], np.int64), values[1]
            if v.min() == np.iinfo(np.int64).min:
                return None
            fields.append((kind, key, v, None if null is None else np.ascontiguousarray(null, np.uint8)))
        elif kind == _K_FLOAT:
            v = np.ascontiguousarray(values[0], np.float64)
            if not _floats_covered(v):
                return None
            fields.append((kind, key, v))
        elif kind == _K_TEXT:
            codes, texts = np.ascontiguousarray(values[0], np.int64), values[1]
            table = _text_table(texts)
            if table is None or codes.min() < 0 or codes.max() >= len(texts):
                return None
            fields.append((kind, key, codes, table[0], table[1]))
        elif kind == _K_ISO:
            ints_ns, ok = exact_ns(values[0])
            fields.append((kind, key, np.ascontiguousarray(ints_ns), np.ascontiguousarray(ok, np.uint8)))
        elif kind == _K_BOOL:
            fields.append((kind, key, np.ascontiguousarray(values[0], bool).view(np.uint8)))
        else:
            start, stop = (np.ascontiguousarray(v, np.int64) for v in values)
            speeds = np.round(np.asarray(cols["axle_speeds_kmh"], np.float64), 3)
            # The numpy path checks the speeds from each batch's first start to its last stop.
            for lo, hi in _batches(cols):
                if int((stop[lo:hi] - start[lo:hi]).max()) > 0:
                    a, b = int(start[lo:hi].min()), int(stop[lo:hi].max())
                    if not _floats_covered(speeds[a:b]):
                        return None
            fields.append((kind, key, np.ascontiguousarray(speeds), start, stop))
    text, lengths = compiled_json.encode_objects(n, fields, ("}" + after).encode("ascii"))
    return bytes(text), np.frombuffer(lengths, np.int64)


# The compiled encoder where it was built, unless TRACKSIDE_PURE=1 asks for the numpy path (the reference:
# tests/test_json_compiled.py checks both alike).
_COMPILED = compiled_json is not None and not os.environ.get("TRACKSIDE_PURE")
encode_objects = _encode_objects_compiled if _COMPILED else _encode_objects_numpy


def encode_passages(cols: Columns, heads: Heads, workers: int = 2, lines_of_type: str | None = None) -> str | None:
    """The passages (``passage_columns.passage_columns`` columns) as a JSON array, or None if not covered.

    With ``lines_of_type``, JSON lines instead: one object per passage, each
    beginning with ``"type"`` set to it and ending with a newline.  Batches
    of passages are encoded on ``workers`` threads (numpy releases the GIL)
    and joined in order.
    """
    opening, sep = ("{", ",") if lines_of_type is None else ('{"type":"' + lines_of_type + '",', "\n")
    if lines_of_type is not None and not set(lines_of_type) <= _SAFE:
        return None
    n = len(cols["head"])
    if lines_of_type is not None and n == 0:
        return ""
    batches = _batches(cols)

    def encode(batch: tuple[int, int]) -> bytes | None:
        return _batch(cols, heads, batch[0], batch[1], batch[0] == 0 and lines_of_type is None, opening, sep)

    if workers > 1 and len(batches) > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers) as pool:
            texts = list(pool.map(encode, batches))
    else:
        texts = [encode(b) for b in batches]
    if any(t is None for t in texts):
        return None
    body = b"".join(t for t in texts if t is not None).decode("ascii")
    return body[1:] + "\n" if lines_of_type is not None else "[" + body + "]"
