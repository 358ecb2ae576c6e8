"""Receiver streams → fix rows: NMEA, gpsd JSON and binary packets, classified line by line.

A receiver capture is not one format.  gpsd's regression logs, a u-blox
port, ``gpspipe -w -r``: ``#`` comment headers, NMEA sentences, binary UBX /
RTCM3 / SiRF packets between sentences and inside the same line, gpsd JSON
reports.  Each line (and each packet inside it) is classified on its own:

* NMEA sentences (``$…``/``!…``, optionally after a device tag) are taken
  wherever they appear, also after binary bytes on the same line; decoding
  is :func:`parsers.gnss.nmea.decode_sentence`;
* binary packets (:mod:`parsers.gnss.packets`: UBX, RTCM3, SBF, SiRF) are
  framed by their libraries, across line ends (0x0A is just a byte inside a
  packet); the UBX and SBF messages that carry a position, a velocity, a
  time or a fix status are decoded (:mod:`parsers.gnss.binary`) and merged
  into one row per epoch (:mod:`parsers.gnss.epochs`), every other packet
  is counted by kind in ``report.skipped``; a line wholly inside a packet
  is blank;
* gpsd JSON objects (``{"class":"TPV",…}``): a TPV is a fix (source
  ``gpsd``), other classes are counted in ``report.skipped``;
* binary bytes that are none of these: if a line holds nothing else it is
  rejected with the first offending byte; beside sentences or packets they
  are counted (``unrecognised binary bytes``).

One row per epoch: an RMC and a GGA (and a VTG, and a gpsd TPV) of one
device with the same time are one row, their fields merged (position from
the first that gives one, speed and course likewise; ``valid`` only if
every position-bearing sentence of the epoch says fix, since a receiver
that contradicts itself is doubtful evidence).  A GGA before the device's
first date keeps its time of day and is dated when a date arrives (the next
RMC or ZDA of that device, in the file or a later one).

Line accounting: a line is ``rejected`` if any sentence or JSON object on it
is (the reason names which), else a ``record`` if it gave or joined a row
(a packet's row counts on the line where the packet starts), else
``blank``.  Every byte is a fix's, a counted packet's, a counted
unrecognised byte beside them, or a rejected line's.
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from parsers.gnss import binary, packets
from parsers.gnss.epochs import BinaryEpochs
from parsers.gnss.fix_table import NAT_NS, FixRows, check_roles, merged_sentence
from parsers.gnss.gpsd_json import JsonRowError, gpsd_class, load_object, tpv_fix
from parsers.gnss.lines import open_lines, text_of
from parsers.gnss.nmea import (
    DEVICE_TAG_RE,
    NOISE_SKIPPED,
    DeviceClock,
    Fix,
    SentenceError,
    decode_sentence,
    sentence_after_noise,
    split_sentences,
)
from parsers.gnss.times import parse_time_ns
from parsers.report import FileReport, ParseReport, device_of_file

if TYPE_CHECKING:
    import pandas as pd

UNPRINTABLE_RE = re.compile(rb"[^\t\x20-\x7e]")  # a tab may follow a device tag
# Inside binary data a sentence ends at its checksum, at the next '$'/'!', or at a control byte.
_EMBEDDED_SENTENCE_RE = re.compile(rb"[$!][^$!*\x00-\x1f\x7f-\xff]*(?:\*[0-9A-Fa-f]{2})?")
_ADDRESS_START_RE = re.compile(rb"[$!][A-Z][A-Z0-9]{4},")
_DEVICE_TAG_HELP = "'$' or '!' (optionally after a device tag: 'DEVICE,$…' or 'DEVICE $…'), or a gpsd JSON object"
_WHITESPACE = frozenset(b" \t\r\n")
_POSITION_KINDS = ("RMC", "GGA", "GLL", "GNS", "TPV")
_SOURCES = {packets.UBX: "ubx", packets.SBF: "sbf"}
UNKNOWN_BINARY = "unrecognised binary bytes"


class LookaheadLines:
    """The lines of one file with look-ahead, for packets that run past a line end.

    Items are (line number, raw line with its end, offset to start reading at).
    """

    def __init__(self, lines: Iterator[tuple[int, bytes]]) -> None:
        self._lines = lines
        self.ahead: deque[tuple[int, bytes, int]] = deque()

    def next(self) -> tuple[int, bytes, int] | None:
        if self.ahead:
            return self.ahead.popleft()
        item = next(self._lines, None)
        return None if item is None else (item[0], item[1], 0)

    def peek(self, k: int) -> tuple[int, bytes, int] | None:
        while len(self.ahead) <= k:
            item = next(self._lines, None)
            if item is None:
                return None
            self.ahead.append((item[0], item[1], 0))
        return self.ahead[k]


class StreamParser:
    """Parse receiver streams into fix rows, keeping each device's date and epoch across files."""

    def __init__(
        self, report: ParseReport, roles: Mapping[str, str] | None = None, rows: FixRows | None = None
    ) -> None:
        self.report = report
        self.roles = check_roles(roles)
        self.clocks: dict[str, DeviceClock] = {}
        self.rows = rows if rows is not None else FixRows()
        self.binary = BinaryEpochs()
        self._gpsd_devices: dict[str, str] = {}

    def open_rows(self) -> set[int]:
        """Rows a later line may still change: each device's current epoch, its undated and open binary epochs."""
        out = self.binary.open_rows()
        for clock in self.clocks.values():  # per device: a handful
            if clock.row >= 0:
                out.add(clock.row)
            out.update(r for r, _ in clock.undated or ())
        return out

    def renumber_rows(self, mapping: dict[int, int]) -> None:
        """The rows were renumbered (``mapping``: old → new index); a row not in it has left."""
        for clock in self.clocks.values():
            clock.row = mapping.get(clock.row, -1)
            if clock.undated:
                clock.undated = [(mapping[r], tod) for r, tod in clock.undated if r in mapping] or None
        self.binary.renumber(mapping)

    # ------------------------------------------------------------ files

    def parse_file(self, path: Path) -> None:
        """Parse one file; its rows are appended to :attr:`rows`."""
        fr, lines = open_lines(path, self.report, keep_ends=True)
        self._gpsd_devices = {}
        feed = LookaheadLines(lines)
        while (item := feed.next()) is not None:
            self._line(fr, item, device_of_file(path), feed)

    def _line(self, fr: FileReport, item: tuple[int, bytes, int], stem: str, feed: LookaheadLines) -> None:
        """One line (with its end; ``start`` > 0: the rest of it after a packet that ended there)."""
        number, raw, start = item
        if start == 0 and raw.lstrip(b" \t")[:1] == b"{":
            self._json_line(fr, number, text_of(raw).strip(b" \t"), stem)
        elif start == 0 and not UNPRINTABLE_RE.search(text_of(raw)):
            self._text_line(fr, number, text_of(raw), stem)
        else:
            self._binary_line(fr, number, raw, start, stem, feed)

    # ------------------------------------------------------------ lines

    def _text_line(self, fr: FileReport, number: int, raw: bytes, stem: str) -> None:
        """A line of printable text: a comment, gpsd JSON, or tagged/untagged sentences."""
        text = raw.strip(b" \t")
        if not text or text[:1] == b"#":
            fr.blank += 1
            return
        if text[:1] == b"{":
            self._json_line(fr, number, text, stem)
            return
        device = stem
        if text[:1] not in (b"$", b"!"):
            tag = DEVICE_TAG_RE.match(text)
            at = sentence_after_noise(text) if tag is None else tag.end()
            if at < 0:
                self.report.reject(fr, number, "not nmea", f"not an NMEA sentence: expected {_DEVICE_TAG_HELP}", raw)
                return
            if tag is not None:
                device = tag.group(1).decode("ascii")
            else:
                self.report.skipped[NOISE_SKIPPED] += at
            text = text[at:]
        if b"\t" in text:
            reason = "a tab inside a sentence (a tab may only separate a device tag from its sentence)"
            self.report.reject(fr, number, "binary", reason, raw)
            return
        sentences, noise = split_sentences(text)
        if noise:
            self.report.skipped[NOISE_SKIPPED] += noise
        self._finish_line(fr, number, raw, device, sentences, known=False)

    def _binary_line(
        self, fr: FileReport, number: int, raw: bytes, start: int, stem: str, feed: LookaheadLines
    ) -> None:
        """A line with bytes outside printable ASCII (or the rest of a line after a packet)."""
        data = raw
        pos = start
        sentences: list[bytes] = []
        known = False
        junk_at = -1
        junk_bytes = 0
        packet_rows = 0
        while pos < len(data):
            m = packets.SYNC_RE.search(data, pos)
            gap_end = len(data) if m is None else m.start()
            for i in range(pos, gap_end):
                if data[i] not in _WHITESPACE:
                    junk_bytes += 1
                    if junk_at < 0:
                        junk_at = i
            if m is None:
                break
            at = m.start()
            kind = packets.packet_kind(data[at : at + 2])
            if kind is None:
                if not _ADDRESS_START_RE.match(data, at):
                    # Inside binary data a '$' that opens no sentence address is just a byte.
                    junk_bytes += 1
                    if junk_at < 0:
                        junk_at = at
                    pos = at + 1
                    continue
                sentence = _EMBEDDED_SENTENCE_RE.match(data, at)
                assert sentence is not None  # the pattern matches at least the '$'
                sentences.append(sentence.group())
                pos = sentence.end()
                continue
            framed = self._frame(kind, data, at, feed)
            if framed is None:  # a sync byte that starts no valid packet: junk
                junk_bytes += 1
                if junk_at < 0:
                    junk_at = at
                pos = at + 1
                continue
            known = True
            lines_used, end, packet = framed
            if self._packet(fr, number, stem, kind, packet):
                packet_rows += 1
            else:
                self.report.skipped[f"{kind} packets"] += 1
            if lines_used < 0:
                pos = end
                continue
            # The packet ran on into later lines: those wholly inside it are blank,
            # and the line where it ends is read on from the packet's end.
            for _ in range(lines_used):
                feed.next()
                fr.blank += 1
            number_k, raw_k, _ = feed.ahead[0]
            feed.ahead[0] = (number_k, raw_k, end)
            break
        if junk_bytes and (sentences or known):
            self.report.skipped[UNKNOWN_BINARY] += junk_bytes
        if not sentences and not known and junk_at >= 0:
            reason = (
                f"binary data: byte 0x{data[junk_at]:02x} at column {junk_at + 1}, "
                "and no NMEA sentence or UBX/RTCM3/SBF/SiRF packet on the line"
            )
            self.report.reject(fr, number, "binary", reason, text_of(raw))
            return
        self._finish_line(fr, number, text_of(raw), stem, sentences, known=known, packet_rows=packet_rows)

    def _frame(self, kind: str, data: bytes, at: int, feed: LookaheadLines) -> tuple[int, int, bytes] | None:
        """A valid packet at ``data[at]``: (look-ahead lines wholly inside it, end offset, the packet), else None."""

        def more(k: int) -> bytes | None:
            item = feed.peek(k)
            return None if item is None else item[1]

        window = packets.ByteWindow(data, at, more)
        packet = packets.read_packet(kind, window)
        if packet is None:
            return None
        lines_used, end = window.end_of(len(packet))
        return lines_used, end, packet

    def _packet(self, fr: FileReport, number: int, device: str, kind: str, packet: bytes) -> bool:
        """A valid packet's content: True if it gave or joined a row (else the caller counts it)."""
        try:
            part = binary.decode(kind, packet)
        except binary.Unreadable:
            return False
        if part is None:
            return False
        clock = self.clocks.get(device)
        if clock is None:
            clock = self.clocks[device] = DeviceClock()
        return self.binary.add(
            self.rows,
            clock,
            part,
            device=device,
            role=self.roles.get(device, ""),
            source=_SOURCES[kind],
            file=fr.file,
            line=number,
        )

    def _json_line(self, fr: FileReport, number: int, text: bytes, stem: str) -> None:
        try:
            try:
                line = text.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise JsonRowError("json", f"JSON line is not UTF-8 (byte at column {exc.start + 1})") from None
            obj = load_object(line)
            kind = gpsd_class(obj)
            if kind is None:
                raise JsonRowError("json", 'a JSON object without a gpsd "class" in a receiver stream')
            if kind != "TPV":
                self.report.skipped[f"gpsd {kind} reports"] += 1
                fr.blank += 1
                return
            tpv = tpv_fix(obj)
            try:
                time_ns = NAT_NS if tpv.time is None else parse_time_ns(tpv.time)
            except ValueError as exc:
                raise JsonRowError("time", f"field 'time': {exc}") from None
        except JsonRowError as exc:
            self.report.reject(fr, number, exc.category, exc.reason, text)
            return
        device = stem
        if tpv.device is not None:
            # The first receiver of a file is the file's device; others keep their own name.
            device = self._gpsd_devices.setdefault(
                tpv.device, stem if not self._gpsd_devices else f"{stem}:{tpv.device}"
            )
        fix = Fix("TPV", time_ns, tpv.lat, tpv.lon, tpv.speed_mps, tpv.course_deg, tpv.valid, None, tpv.quality)
        self._emit(fr, number, device, fix, "gpsd")
        fr.records += 1

    def _finish_line(
        self,
        fr: FileReport,
        number: int,
        raw: bytes,
        device: str,
        sentences: list[bytes],
        *,
        known: bool,
        packet_rows: int = 0,
    ) -> None:
        """Decode a line's sentences, add their rows, count the line once."""
        clock = self.clocks.get(device)
        if clock is None:
            clock = self.clocks[device] = DeviceClock()
        errors: list[tuple[int, SentenceError]] = []
        rows = packet_rows
        for k, sentence in enumerate(sentences, start=1):
            try:
                fix = decode_sentence(sentence, clock)
            except SentenceError as exc:
                errors.append((k, exc))
                continue
            if clock.undated and clock.day is not None:
                self._date_rows(clock)
            if fix is None:
                continue
            rows += 1
            self._emit(fr, number, device, fix, "nmea")
        if errors:
            k, first = errors[0]
            where = f"sentence {k} of {len(sentences)} on this line: " if len(sentences) > 1 else ""
            self.report.reject(fr, number, first.category, where + first.reason, raw)
        elif rows:
            fr.records += 1
        else:
            fr.blank += 1

    # ------------------------------------------------------------ epochs

    def _date_rows(self, clock: DeviceClock) -> None:
        """Date the rows that came before the device's first date."""
        for row, tod in clock.undated or ():
            self.rows.time[row] = clock.time_ns(tod)
        clock.undated = None
        if clock.row >= 0:
            clock.last_time_ns = self.rows.time[clock.row]

    def _emit(self, fr: FileReport, number: int, device: str, fix: Fix, source: str) -> None:
        """Add a fix as a row, or merge it into the device's row of the same epoch."""
        clock = self.clocks.get(device)
        if clock is None:
            clock = self.clocks[device] = DeviceClock()
        rows = self.rows
        row = clock.row
        if row >= 0 and fix.sentence not in rows.sentence_at(row).split("+"):
            same_epoch = (
                fix.sentence == "VTG"
                or (fix.time_ns != NAT_NS and rows.time[row] == fix.time_ns)
                or (
                    fix.time_ns == NAT_NS
                    and rows.time[row] == NAT_NS
                    and fix.tod_ns is not None
                    and any(r == row and t == fix.tod_ns for r, t in clock.undated or ())
                )
            )
            if same_epoch:
                self._merge(row, fix, clock)
                return
        if fix.sentence == "VTG" and row >= 0:
            fix.time_ns = rows.time[row]
        index = rows.add(
            time_ns=fix.time_ns,
            device=device,
            role=self.roles.get(device, ""),
            lat=fix.lat,
            lon=fix.lon,
            speed_mps=fix.speed_mps,
            course_deg=fix.course_deg,
            valid=fix.valid,
            source=source,
            sentence=fix.sentence,
            file=fr.file,
            line=number,
            fix_quality=fix.fix_quality,
        )
        if fix.sentence != "VTG":
            clock.row = index
            clock.row_weak = fix.weak_no_fix
            if fix.time_ns != NAT_NS:
                clock.last_time_ns = fix.time_ns
            elif fix.tod_ns is not None:
                if clock.undated is None:
                    clock.undated = []
                clock.undated.append((index, fix.tod_ns))

    def _merge(self, row: int, fix: Fix, clock: DeviceClock) -> None:
        rows = self.rows
        if not math.isnan(fix.lat):
            # The latest position of the epoch, as gpsd reports it (a multiplexer may
            # pass on RMC, GGA and GLL from different sources).
            rows.lat[row], rows.lon[row] = fix.lat, fix.lon
        if math.isnan(rows.speed_mps[row]):
            rows.speed_mps[row] = fix.speed_mps
        if math.isnan(rows.course_deg[row]):
            rows.course_deg[row] = fix.course_deg
        if fix.sentence in _POSITION_KINDS:
            was_valid = bool(rows.valid[row])
            if fix.weak_no_fix and (was_valid or clock.row_weak):
                valid = was_valid  # a 0-satellite GGA does not overrule the epoch's other sentences
            elif clock.row_weak and fix.valid:
                valid, clock.row_weak = True, False
            else:
                valid = was_valid and fix.valid
                clock.row_weak = False
            rows.valid[row] = valid
            prior = rows.quality_at(row)
            if not valid:
                quality = "no_fix"
            elif "dead_reckoning" in (prior, fix.fix_quality):
                quality = "dead_reckoning"
            else:
                quality = "gnss"
            rows.set_quality(row, quality)
        rows.set_sentence(row, merged_sentence(rows.sentence_at(row), fix.sentence))


def parse_stream_files(
    paths: Iterable[Path | str], *, roles: Mapping[str, str] | None = None
) -> tuple[pd.DataFrame, ParseReport]:
    """Parse receiver streams (NMEA, gpsd JSON, binary packets) into one fix table in file order, and a report.

    ``roles`` maps device ids (file stems or line tags) to ``"head"`` or
    ``"eot"``; ValueError for any other role.  InputError for an unreadable
    file.
    """
    report = ParseReport()
    parser = StreamParser(report, roles)
    for path in paths:
        parser.parse_file(Path(path))
    report.check()
    return parser.rows.frame(release=True), report


parse_nmea = parse_stream_files  # the name the NMEA-only reader had
