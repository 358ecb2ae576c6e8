"""NMEA 0183 sentences → decoded fixes (:class:`Fix`), one sentence at a time.

The fix table they become is defined in ``parsers.gnss.fix_table``; reading
files, binary packets between sentences, gpsd JSON and the merging of one
epoch's sentences into one row are ``parsers.gnss.stream``.

Which NMEA sentences become rows
--------------------------------
Any talker (``GP``, ``GN``, ``GL``, ``GA``, ``GB``, ``GQ``, ``IN`` …):

* ``RMC``: date + time, position, speed (knots × 1852/3600 → m/s, exact),
  course; valid when the status is ``A`` (and an NMEA 4.1 mode is not
  ``N``) and the position is present;
* ``GGA``: time, position; valid for quality 1–6 (7 is a manually entered
  position, 8 a simulator: not real fixes; 6 is dead reckoning, marked
  ``fix_quality = "dead_reckoning"``), except a satellite fix (1–5) from 0
  satellites used, a stale flag that gpsd reports as no fix too (a weak
  verdict: an RMC of the same epoch that says ``A`` overrules it).  GGA
  carries no date: it takes the date of the device's most recent RMC or ZDA
  (a day is added when the time of day has wrapped past midnight since);
  before any date, ``parsers.gnss.stream`` dates it when the next RMC or ZDA
  arrives.  An RMC without a date does the same;
* ``GLL``: position and time of day; valid when the status is ``A`` and the
  mode is not ``N`` (``E``: dead reckoning);
* ``GNS``: time, position, one mode letter per constellation; valid when one
  of them is a fix (A, D, P, R, F, E; only E: dead reckoning);
* ``VTG``: speed and course only, no time: it joins the row of the device's
  epoch (``parsers.gnss.stream``).  Knots are used, else km/h.  The
  pre-NMEA 2.0 form without unit fields (``$GPVTG,054.7,034.4,005.5,010.2``)
  is read too.

Line accounting (``parsers.report``, done by ``parsers.gnss.stream``)
--------------------------------------------------------------------
* ``records``: lines that gave or joined at least one row (no-fix rows included);
* ``blank``: nothing to parse: blank lines, ``#`` comments, and well-formed
  sentences that carry no fix (GSA, GSV, ZDA, TXT, AIS ``!AIVDM``,
  proprietary ``$P…``, any other type).  ZDA still sets the device's date;
* ``rejected``: anything else, with the reason: a line that does not start
  with ``$`` or ``!`` (after an optional device tag), control or non-ASCII
  bytes (binary junk), a wrong or malformed checksum, a malformed address
  field, too few fields (a truncated sentence), a field that does not decode,
  or an error raised by pynmeagps (its message is kept).

Checksums: a ``*HH`` checksum, when present, must match (gpsd drops such
sentences too).  A sentence without one is accepted, since NMEA makes the
checksum optional, but then it must have its complete field count (RMC 11,
GGA 14, GLL 6, GNS 12, VTG 8 or 4 fields after the address): a line cut off short is
otherwise indistinguishable from a sentence sent without a checksum.  (gpsd
itself dropped every checksum-less line of the captures in
``shared/data/nmea``, so the comparison with gpsd does not cover them.)

Sentences run together on one line (a receiver that lost a line end, or cut
a sentence short and started the next: ``…*1E$GPRMC,…``, ``…,270,$GPRMC,…``)
are split before every ``$`` and ``!`` (reserved delimiters that never occur
inside a sentence) and each is parsed, as gpsd does.  Such a line counts
once: rejected if any of its sentences was (the reason says which), else a
record if any gave a row, else blank; the rows of its good sentences are kept
either way, so ``len(fixes)`` can differ from ``records``.

Devices: one file per device (the device id is the file name stem), or
interleaved lines, each prefixed with a device tag: ``DEVICE`` followed by
one comma or by spaces/tabs, then the ``$`` or ``!`` of the sentence, e.g.
``head1 $GPRMC,…`` or ``eot7,$GNRMC,…``.  A tag is 1–64 letters, digits,
``_``, ``.`` or ``-``, starting with a letter or digit.  Untagged lines of a
file belong to the device named by its stem.  Roles come from the ``roles``
mapping (device → ``"head"``/``"eot"``), default ``""``.

Why pynmeagps: it is maintained (regular releases, NMEA 4.1+ fields,
proprietary sentences) and typed.  We use its tables of talkers and sentence
types (an unknown one is rejected with its message) and its field helpers
(``time2utc``, ``date2utc``, ``dmm2ddd``), not ``NMEAReader.parse``: that
builds a whole message object per sentence and cost three quarters of the
parse time (150 000 lines: 12.0 s → 4.7 s of CPU).  pynmea2, the older
alternative, sees few releases and decodes fields lazily, as strings.
Neither decides what a *fix* is, nor checks field counts or malformed
numbers (pynmeagps turns an undecodable latitude into ``""``), so those
checks are done here, as is the checksum, before anything else, so that the
reason is specific and sentences without one can be accepted.
"""

from __future__ import annotations

import datetime as dt
import math
import re
from dataclasses import dataclass
from typing import Any

from pynmeagps import NMEA_MSGIDS, NMEA_TALKERS
from pynmeagps.nmeahelpers import date2utc, dmm2ddd, time2utc

from parsers.gnss.fix_table import NAT_NS
from parsers.units import NS, NS_PER_DAY

__all__ = [
    "DeviceClock",
    "Fix",
    "SentenceError",
    "decode_sentence",
    "nmea_checksum",
    "sentence_after_noise",
    "split_sentences",
]

KNOT_MPS = 1852 / 3600  # 1 international knot = 1852 m per hour, exactly
KMH_MPS = 1000 / 3600

_EPOCH = dt.date(1970, 1, 1)

# Payload fields (after the address) a complete sentence has, and the fewest
# a checksummed sentence may have (the fields read here).
_FULL_FIELDS = {"RMC": 11, "GGA": 14, "VTG": 8, "GLL": 6, "GNS": 12}
_MIN_FIELDS = {"RMC": 9, "GGA": 7, "VTG": 8, "GLL": 6, "GNS": 6}
# GNS mode characters (one per constellation) that mean a position fix; E is estimated (dead reckoning).
_GNS_FIX_MODES = frozenset("ADPRFE")
_VALID_GGA_QUALITY = range(1, 7)
_DEAD_RECKONING = 6

DEVICE_TAG_RE = re.compile(rb"([A-Za-z0-9][A-Za-z0-9_.-]{0,63})(?:,|[ \t]+)(?=[$!])")
_UNPRINTABLE_RE = re.compile(rb"[^\t\x20-\x7e]")  # a tab may follow a device tag
_SENTENCE_START_RE = re.compile(rb"(?=[$!])")
# A sentence's start in a line that begins with noise: a marker, an address (talker and type, or a
# proprietary P…) and its first comma.
_SENTENCE_AFTER_NOISE_RE = re.compile(rb"[$!][A-Z][A-Z0-9]{4,},")
NOISE_SKIPPED = "bytes of noise before a sentence"
_CHECKSUM_RE = re.compile(rb"\*([0-9A-Fa-f]{2})")
_ADDRESS_RE = re.compile(r"[A-Z][A-Z0-9][A-Z0-9]{3}")
_NUMBER_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_DEVICE_TAG_HELP = "'$' or '!' (optionally after a device tag: 'DEVICE,$…' or 'DEVICE $…')"


def split_sentences(text: bytes) -> tuple[list[bytes], int]:
    """A printable line from its first '$' or '!' → its sentences, and the bytes of noise among them.

    A start marker that another follows opens no sentence: gpsd's ST Teseo LIV4F capture writes every
    sentence as ``$$GNRMC,…``, and gpsd reads them.  Such a lone marker is one byte of noise, unless the
    line has nothing else (then it is the line's one sentence, rejected with its reason).
    """
    pieces = [s for s in _SENTENCE_START_RE.split(text) if s]
    kept = [p for p in pieces if len(p) > 1]
    if not kept:
        return pieces, 0
    return kept, len(pieces) - len(kept)


def sentence_after_noise(text: bytes) -> int:
    """Where a sentence starts in a line of printable text that begins with something else, or -1.

    gpsd reads a valid sentence after junk; so do we (the junk is counted as skipped noise).
    """
    m = _SENTENCE_AFTER_NOISE_RE.search(text)
    return -1 if m is None else m.start()


class SentenceError(Exception):
    """A sentence that cannot be used: ``category`` for the counts, ``reason`` for people."""

    def __init__(self, category: str, reason: str) -> None:
        super().__init__(reason)
        self.category = category
        self.reason = reason


# ------------------------------------------------------------------ decoding


@dataclass(slots=True)
class DeviceClock:
    """What a device said about the date, and which row holds its current epoch.

    Slots and no per-record objects: one of these per device, however many
    devices a file interleaves.
    """

    day: dt.date | None = None
    day_tod_ns: int | None = None  # time of day of the sentence that gave the date
    last_time_ns: int = NAT_NS  # time of the latest RMC/GGA row, for VTG
    row: int = -1  # index of the device's latest RMC/GGA/TPV row (the epoch a sentence may join)
    row_weak: bool = False  # that row is "no fix" only by a weak sign (Fix.weak_no_fix)
    # Rows whose time of day came before any date (a GGA before the first RMC):
    # (row index, time of day in ns), dated as soon as a date arrives.
    undated: list[tuple[int, int]] | None = None

    def set_date(self, day: dt.date, tod_ns: int | None) -> None:
        self.day = day
        self.day_tod_ns = tod_ns

    def time_ns(self, tod_ns: int | None) -> int:
        """A time of day → ns since the epoch on the device's current date (NaT if unknown)."""
        if tod_ns is None or self.day is None:
            return NAT_NS
        day = self.day
        if self.day_tod_ns is not None:
            # Past midnight since the date was given: the next day (and the reverse).
            if tod_ns < self.day_tod_ns - NS_PER_DAY // 2:
                day += dt.timedelta(days=1)
            elif tod_ns > self.day_tod_ns + NS_PER_DAY // 2:
                day -= dt.timedelta(days=1)
        return (day - _EPOCH).days * NS_PER_DAY + tod_ns


@dataclass
class Fix:
    """One decoded fix sentence."""

    sentence: str
    time_ns: int
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    valid: bool
    tod_ns: int | None = None  # the time of day the sentence gave (for dating it later)
    fix_quality: str = ""  # parsers.gnss.fix_table.FIX_QUALITIES
    weak_no_fix: bool = False  # no fix only by a weak sign (a GGA fix quality from 0 satellites)


def nmea_checksum(body: bytes) -> int:
    """XOR of the bytes between ``$``/``!`` and ``*``."""
    total = 0
    for byte in body:
        total ^= byte
    return total


def _tod_ns(value: Any, raw: str) -> int | None:
    if raw == "":
        return None
    if not isinstance(value, dt.time):
        raise SentenceError("field", f"time field '{raw}' is not hhmmss[.ss]")
    return ((value.hour * 60 + value.minute) * 60 + value.second) * NS + value.microsecond * 1000


def _date(value: Any, raw: str, what: str = "date field") -> dt.date | None:
    if raw == "":
        return None
    if not isinstance(value, dt.date):
        raise SentenceError("field", f"{what} '{raw}' is not ddmmyy")
    return value


def _coordinate(value: Any, raw: str, hemisphere: str, axis: str) -> float:
    """pynmeagps's signed degrees, checked against the raw field; NaN when empty."""
    if raw == "":
        return math.nan
    name, limit, signs = ("latitude", 90.0, "NS") if axis == "lat" else ("longitude", 180.0, "EW")
    # dmm2ddd reads its degrees with float(): 'nan34.5' gives NaN, which would pass for an empty field.
    if not isinstance(value, float) or math.isnan(value):
        raise SentenceError("field", f"{name} field '{raw[:24]}' is not (d)ddmm.mmmm")
    if hemisphere not in signs:
        raise SentenceError("field", f"{name} hemisphere '{hemisphere}' is not {signs[0]} or {signs[1]}")
    if abs(value) > limit:
        raise SentenceError("field", f"{name} {value:.6f}° is out of range ±{limit:g}°")
    return value


def _decimal(raw: str, what: str, *, minimum: float | None = None) -> float:
    if raw == "":
        return math.nan
    if not _NUMBER_RE.fullmatch(raw):
        raise SentenceError("field", f"{what} field '{raw}' is not a number")
    value = float(raw)
    if not math.isfinite(value):  # hundreds of digits: float() gives inf, which no JSON can hold
        raise SentenceError("field", f"{what} field '{raw[:12]}…' of {len(raw)} characters: expected a finite number")
    if minimum is not None and value < minimum:
        raise SentenceError("field", f"{what} field '{raw}' is below {minimum:g}")
    return value


# Where the time, the latitude (then N/S, longitude, E/W) and the date sit in each sentence we decode.
_LAYOUT: dict[str, tuple[int | None, int | None, int | None]] = {
    "RMC": (0, 2, 8),
    "GGA": (0, 1, None),
    "GLL": (4, 0, None),
    "GNS": (0, 1, None),
    "ZDA": (0, None, None),
    "VTG": (None, None, None),
}


@dataclass(slots=True)
class _Decoded:
    """The fields pynmeagps's helpers decoded ("" where the raw field did not decode)."""

    time: Any = ""
    date: Any = ""
    lat: Any = ""
    lon: Any = ""


def _library_parse(address: str, payload: list[str]) -> _Decoded:
    """pynmeagps's verdict on the address and its decoding of time, date and position.

    The talker and sentence type are checked against pynmeagps's own tables
    (what ``NMEAReader.parse(validate=VALMSGID)`` checks) and the fields are
    decoded by its helpers (``time2utc``, ``date2utc``, ``dmm2ddd``): the
    library's semantics, without building a whole message object per sentence,
    which cost three quarters of the parse time.
    """
    talker, kind = address[:2], address[2:]
    if talker not in NMEA_TALKERS:
        raise SentenceError("library", f"pynmeagps could not parse {address}: unknown talker {talker}")
    if kind not in NMEA_MSGIDS:
        raise SentenceError("library", f"pynmeagps does not know sentence {address}")
    at_time, at_lat, at_date = _LAYOUT[kind]
    out = _Decoded()
    try:
        if at_time is not None:
            out.time = time2utc(payload[at_time])
        if at_date is not None:
            out.date = date2utc(payload[at_date])
        if at_lat is not None:
            lat, lon = dmm2ddd(payload[at_lat]), dmm2ddd(payload[at_lat + 2])
            out.lat = -lat if isinstance(lat, float) and payload[at_lat + 1] == "S" else lat
            out.lon = -lon if isinstance(lon, float) and payload[at_lat + 3] == "W" else lon
    except Exception as exc:  # the library must never crash the parse
        raise SentenceError("library", f"pynmeagps could not parse {address}: {exc}") from None
    return out


def _position(msg: _Decoded, payload: list[str], at: int) -> tuple[float, float]:
    lat = _coordinate(msg.lat, payload[at], payload[at + 1], "lat")
    lon = _coordinate(msg.lon, payload[at + 2], payload[at + 3], "lon")
    if math.isnan(lat) or math.isnan(lon):
        return math.nan, math.nan
    return lat, lon


def _rmc(address: str, payload: list[str], clock: DeviceClock) -> Fix:
    msg = _library_parse(address, payload)
    tod = _tod_ns(msg.time, payload[0])
    day = _date(msg.date, payload[8])
    status = payload[1]
    if status not in ("A", "V", ""):
        raise SentenceError("field", f"status field '{status}' is not A (valid) or V (no fix)")
    lat, lon = _position(msg, payload, 2)
    speed_kn = _decimal(payload[6], "speed (knots)", minimum=0.0)
    course = _decimal(payload[7], "course")
    if day is not None:
        clock.set_date(day, tod)
    time_ns = clock.time_ns(tod)
    mode = payload[11] if len(payload) > 11 else ""
    valid = status == "A" and mode != "N" and not math.isnan(lat)
    # NMEA 4.1 mode E: estimated (dead reckoning).
    quality = "no_fix" if not valid else "dead_reckoning" if mode == "E" else "gnss"
    return Fix("RMC", time_ns, lat, lon, speed_kn * KNOT_MPS, course, valid, tod, quality)


def _gga(address: str, payload: list[str], clock: DeviceClock) -> Fix:
    msg = _library_parse(address, payload)
    tod = _tod_ns(msg.time, payload[0])
    lat, lon = _position(msg, payload, 1)
    quality_raw = payload[5]
    if quality_raw and not (quality_raw.isdigit() and len(quality_raw) <= 2):
        raise SentenceError("field", f"quality field '{quality_raw[:12]}' is not a number 0-8")
    quality = int(quality_raw) if quality_raw else 0
    used_raw = payload[6]
    if used_raw and not (used_raw.isdigit() and len(used_raw) <= 3):
        raise SentenceError("field", f"satellites-used field '{used_raw[:12]}' is not a number of 1-3 digits")
    # A satellite fix from no satellites is a receiver's stale flag (gpsd says no fix too).
    no_satellites = used_raw != "" and int(used_raw) == 0 and quality != _DEAD_RECKONING
    valid = quality in _VALID_GGA_QUALITY and not no_satellites and not math.isnan(lat)
    fix_quality = "no_fix" if not valid else "dead_reckoning" if quality == _DEAD_RECKONING else "gnss"
    fix = Fix("GGA", clock.time_ns(tod), lat, lon, math.nan, math.nan, valid, tod, fix_quality)
    # Only the satellite count says "no fix": a weak verdict that an RMC of the same epoch may overrule.
    fix.weak_no_fix = no_satellites and quality in _VALID_GGA_QUALITY and not math.isnan(lat)
    return fix


def _vtg(address: str, payload: list[str], clock: DeviceClock) -> Fix:
    if len(payload) == 4:  # before NMEA 2.0: course T, course M, knots, km/h, no unit fields
        payload = [payload[0], "T", payload[1], "M", payload[2], "N", payload[3], "K"]
    for at, unit in ((1, "T"), (3, "M"), (5, "N"), (7, "K")):
        if payload[at] not in (unit, ""):
            raise SentenceError("field", f"VTG unit field {at + 1} is '{payload[at]}', expected '{unit}'")
    _library_parse(address, payload)  # the library's own verdict on the sentence
    course = _decimal(payload[0], "course (true)")
    knots = _decimal(payload[4], "speed (knots)", minimum=0.0)
    kmh = _decimal(payload[6], "speed (km/h)", minimum=0.0)
    speed = knots * KNOT_MPS if not math.isnan(knots) else kmh * KMH_MPS
    return Fix("VTG", clock.last_time_ns, math.nan, math.nan, speed, course, False)


def _zda(address: str, payload: list[str], clock: DeviceClock) -> None:
    if len(payload) < 4 or not all(payload[:4]):
        return  # no date yet (a receiver without a fix sends empty fields)
    msg = _library_parse(address, payload)
    tod = _tod_ns(msg.time, payload[0])
    day_raw, month_raw, year_raw = payload[1], payload[2], payload[3]
    if not (day_raw.isdigit() and month_raw.isdigit() and year_raw.isdigit()):
        raise SentenceError("field", f"ZDA date '{day_raw[:12]}/{month_raw[:12]}/{year_raw[:12]}' is not a date")
    # The range is checked on the text first: a year of 2^31 or more overflows dt.date (OverflowError).
    if len(year_raw) > 9 or not 1980 <= int(year_raw) <= 2200:
        # GPS time began in 1980; later years would overflow ns timestamps.
        raise SentenceError("field", f"ZDA year {year_raw[:12]} is outside 1980-2200")
    try:
        day = dt.date(int(year_raw), int(month_raw), int(day_raw))
    except (ValueError, OverflowError):  # a day or month of 2^31 or more overflows too
        raise SentenceError("field", f"ZDA date '{day_raw[:12]}/{month_raw[:12]}/{year_raw}' is not a date") from None
    clock.set_date(day, tod)


def _gll(address: str, payload: list[str], clock: DeviceClock) -> Fix:
    msg = _library_parse(address, payload)
    lat, lon = _position(msg, payload, 0)
    tod = _tod_ns(msg.time, payload[4])
    status = payload[5]
    if status not in ("A", "V", ""):
        raise SentenceError("field", f"status field '{status}' is not A (valid) or V (no fix)")
    mode = payload[6] if len(payload) > 6 else ""
    valid = status == "A" and mode != "N" and not math.isnan(lat)
    quality = "no_fix" if not valid else "dead_reckoning" if mode == "E" else "gnss"
    return Fix("GLL", clock.time_ns(tod), lat, lon, math.nan, math.nan, valid, tod, quality)


def _gns(address: str, payload: list[str], clock: DeviceClock) -> Fix:
    msg = _library_parse(address, payload)
    tod = _tod_ns(msg.time, payload[0])
    lat, lon = _position(msg, payload, 1)
    modes = payload[5]
    if not modes.isalpha() and modes != "":
        raise SentenceError("field", f"mode field '{modes}' is not mode letters (N, A, D, P, R, F, E, M, S)")
    fixing = {m for m in modes if m in _GNS_FIX_MODES}
    valid = bool(fixing) and not math.isnan(lat)
    quality = "no_fix" if not valid else "dead_reckoning" if fixing == {"E"} else "gnss"
    return Fix("GNS", clock.time_ns(tod), lat, lon, math.nan, math.nan, valid, tod, quality)


_DECODERS = {"RMC": _rmc, "GGA": _gga, "VTG": _vtg, "GLL": _gll, "GNS": _gns}


def decode_sentence(sentence: bytes, clock: DeviceClock) -> Fix | None:
    """One sentence (``$…`` or ``!…``, printable ASCII, no line end) → a fix, or None if it carries none.

    Raises :class:`SentenceError` with the reason when it cannot be used.
    """
    star = sentence.find(b"*")
    has_checksum = star >= 0
    if has_checksum:
        tail = sentence[star:]
        got = _CHECKSUM_RE.fullmatch(tail)
        if got is None:
            raise SentenceError("checksum", f"checksum field '{tail[:12].decode()}' is not '*' and two hex digits")
        body = sentence[1:star]
        expected = nmea_checksum(body)
        if int(got.group(1), 16) != expected:
            raise SentenceError(
                "checksum",
                f"checksum mismatch: the sentence says *{got.group(1).decode()}, its content gives *{expected:02X}",
            )
    else:
        body = sentence[1:]
    if sentence[:1] == b"!":
        return None  # AIS and other encapsulated sentences: no fix for us
    address, *payload = body.decode("ascii").split(",")
    if address.startswith("P"):
        return None  # proprietary
    if not _ADDRESS_RE.fullmatch(address):
        raise SentenceError(
            "address", f"address field '{address[:12]}' is not a talker and a sentence type (e.g. GPRMC)"
        )
    kind = address[2:]
    if kind == "ZDA":
        _zda(address, payload, clock)
        return None
    decoder = _DECODERS.get(kind)
    if decoder is None:
        return None
    needed = _MIN_FIELDS[kind] if has_checksum else _FULL_FIELDS[kind]
    old_vtg = kind == "VTG" and len(payload) == 4  # the pre-2.0 form is complete with 4 fields
    if len(payload) < needed and not old_vtg:
        cut = " and no checksum: a truncated sentence" if not has_checksum else ""
        raise SentenceError("truncated", f"{address}: {len(payload)} fields{cut}; expected at least {needed}")
    fix = decoder(address, payload, clock)
    if kind != "VTG" and fix.time_ns != NAT_NS:
        clock.last_time_ns = fix.time_ns
    return fix
