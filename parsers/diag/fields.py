"""Fields of a Frauscher-style diagnostic record: validated and decoded, one distinct span at a time.

The reader (:mod:`parsers.diag.read`) cuts each line into a register span (fields
1-9), a value span (10-11) and the time; these functions give each span's
meaning, or a :class:`FieldError` saying what was wrong.  They run once per
*distinct* span, so they are plain Python.
"""

from __future__ import annotations

import datetime as dt
import re
import sys
from dataclasses import dataclass

from parsers.diag.labels import canonical_label, decode_label
from parsers.report import escape_text
from parsers.units import NS, NS_PER_DAY

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

    def __reduce__(self) -> tuple[type[FieldError], tuple[str, str]]:
        # Kept in a registry's caches, which the archive saves with the pipeline's state.
        return (FieldError, (self.category, self.reason))


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


def split_fields(span: bytes, keys: tuple[str, ...], first_index: int) -> list[bytes]:
    """The values of tab-separated ``key:value`` fields named ``keys`` in order; FieldError naming the
    field (numbered from ``first_index``) that is not the one expected."""
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
    diag, dev_id, device, typ, gs, head, ch, adr, label = split_fields(span, REGISTER_FIELDS, 1)
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
    return (day - _EPOCH).days * NS_PER_DAY


# The fraction after a point or a comma (ISO 8601 allows both; exports in a German locale write the comma).
_TIME_RE = re.compile(r"(\d{2}):(\d{2}):(\d{2})(?:[.,](\d{1,9}))?")


def parse_time(raw: bytes) -> tuple[int, bool]:
    """``Time:09:32:24[.125]`` (or ``,125``) → (ns since midnight, has a fraction).

    The per-line reference for the vectorized time parse in :func:`~parsers.diag.tokens_numpy.tokenize_numpy`
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
    return ((hh * 60 + mm) * 60 + ss) * NS + (int(frac.ljust(9, "0")) if frac else 0), bool(frac)
