"""Binary packets that receivers interleave with NMEA: framed and checked by their maintained libraries.

A receiver port often carries u-blox UBX, RTCM3 corrections, Septentrio SBF
or SiRF binary between (and inside the lines of) NMEA sentences.  Each
packet is framed here so that its bytes are neither mistaken for junk nor
allowed to hide the sentences around them; what a packet *says* is read by
:mod:`parsers.gnss.binary`.

Framing is the libraries' own, one packet at a time, from a sync the line
scanner found (:data:`SYNC_RE`):

* UBX (``B5 62``) and RTCM3 (``D3``): pyubx2's ``UBXReader``, the reader of
  mixed NMEA / UBX / RTCM3 streams, reads the frame; the UBX checksum is
  pyubx2's (``isvalid_checksum``), the RTCM3 CRC-24Q pyrtcm's
  (``calc_crc24q``);
* SBF (``$@``): pysbf2's ``SBFReader`` reads the block; its CRC is pysbf2's
  (``crc2bytes``), and the length must be a multiple of 4 (SBF's rule);
* SiRF (``A0 A2``): no maintained Python library reads SiRF binary, so its
  framing stays here: big-endian 15-bit payload length, payload, 15-bit sum
  of the payload bytes, ``B0 B3``.

The readers are given one packet's worth of bytes at most (a
:class:`ByteWindow`, :data:`MAX_PACKET_BYTES`), never the stream: left to
themselves they would resynchronise by skipping bytes, and a false sync
byte whose length field claims a long packet would swallow the sentences
after it.  Here a sync that starts no valid packet is refused and the
scanner moves on by one byte (``parsers.gnss.stream``).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Final

from pyrtcm import calc_crc24q, crc2bytes
from pysbf2 import SBF_PROTOCOL, SBFReader
from pysbf2.sbfhelpers import crc2bytes as sbf_crc
from pyubx2 import ERR_RAISE, PARSE_NONE, RTCM3_PROTOCOL, UBX_PROTOCOL, UBXReader
from pyubx2.ubxhelpers import calc_checksum, isvalid_checksum

UBX: Final = "UBX"
RTCM3: Final = "RTCM3"
SIRF: Final = "SiRF"
SBF: Final = "SBF"

# Longest packet we frame: a UBX length field may claim 64 KiB; real
# navigation packets are far shorter, and a bound keeps the look-ahead small.
MAX_PACKET_BYTES: Final = 8192

# Where a packet or a sentence may start ('$@' is SBF, any other '$' or '!' a sentence).
SYNC_RE = re.compile(rb"\$@|[$!]|\xb5\x62|\xd3[\x00-\x03]|\xa0\xa2")


def packet_kind(head: bytes) -> str | None:
    """The kind a sync at the start of ``head`` announces, or None (``$``/``!`` are NMEA, not packets)."""
    if head[:2] == b"\xb5\x62":
        return UBX
    if head[:2] == b"\xa0\xa2":
        return SIRF
    if head[:2] == b"$@":
        return SBF
    if head[:1] == b"\xd3":
        return RTCM3
    return None


def _no_more(k: int) -> bytes | None:
    return None


class ByteWindow:
    """A file-like view of the bytes from ``data[at]`` on, continued by later chunks as a reader asks.

    ``more(k)`` gives the k-th chunk after ``data`` (the next lines of the
    file), or None when there is none (yet).  A read past ``limit`` bytes
    gives nothing: a longer packet is refused, not read.  :attr:`ran_out` tells that a read
    wanted bytes past the chunks at hand (a packet still arriving).
    """

    def __init__(
        self, data: bytes, at: int = 0, more: Callable[[int], bytes | None] = _no_more, limit: int = MAX_PACKET_BYTES
    ) -> None:
        self._data = data
        self._at = at
        self._more = more
        self._limit = limit
        self._extra = bytearray()
        self._chunks = 0
        self._chunk_ends: list[int] = []  # where each chunk taken ends, counted from data[at]
        self._pos = 0  # bytes read so far
        self.ran_out = False

    def read(self, size: int = -1) -> bytes:
        if size <= 0 or self._pos + size > self._limit:
            # A negative length field (pysbf2 reads length - 8) reads nothing, and so does a packet
            # longer than the limit: refused at once, without waiting for bytes it will never need.
            return b""
        want = size
        start = self._at + self._pos
        in_data = len(self._data) - self._at
        while in_data + len(self._extra) < self._pos + want:
            chunk = self._more(self._chunks)
            if chunk is None:
                self.ran_out = True
                break
            self._chunks += 1
            self._extra += chunk
            self._chunk_ends.append(in_data + len(self._extra))
        end = self._pos + want
        if end <= in_data:
            out = self._data[start : start + want]
        else:
            head = self._data[start:] if self._pos < in_data else b""
            out = head + bytes(self._extra[max(0, self._pos - in_data) : end - in_data])
        self._pos += len(out)
        return out

    def readline(self) -> bytes:
        return b""  # sentences are read by the line scanner, never through a packet reader

    def end_of(self, size: int) -> tuple[int, int]:
        """Where the first ``size`` bytes read end: (-1, offset in ``data``) when inside it, else (k, offset
        in the k-th later chunk, which may be its length: the chunks before it lie wholly inside)."""
        in_data = len(self._data) - self._at
        if size <= in_data:
            return -1, self._at + size
        start = in_data
        for k, end in enumerate(self._chunk_ends):
            if size <= end:
                return k, size - start
            start = end
        raise ValueError(f"{size} bytes were not read")


def _read_ubx_or_rtcm3(window: ByteWindow) -> bytes | None:
    reader = UBXReader(window, protfilter=UBX_PROTOCOL | RTCM3_PROTOCOL, quitonerror=ERR_RAISE, parsing=PARSE_NONE)
    raw, _ = reader.read()
    return raw if isinstance(raw, bytes) else None


def _read_sbf(window: ByteWindow) -> bytes | None:
    raw, _ = SBFReader(window, protfilter=SBF_PROTOCOL, quitonerror=ERR_RAISE, parsing=False).read()
    return raw if isinstance(raw, bytes) else None


def _read_sirf(window: ByteWindow) -> bytes | None:
    head = window.read(4)
    if len(head) < 4 or head[:2] != b"\xa0\xa2":
        return None
    rest = window.read(((head[2] & 0x7F) << 8 | head[3]) + 4)
    packet = head + rest
    payload = packet[4:-4]
    if len(rest) < 4 or packet[-2:] != b"\xb0\xb3":
        return None
    return packet if sum(payload) & 0x7FFF == (packet[-4] << 8 | packet[-3]) & 0x7FFF else None


def read_packet(kind: str, window: ByteWindow) -> bytes | None:
    """The whole, valid packet of ``kind`` at the window's start, or None if it is not one.

    Not one: a length past the window's end or limit, a checksum or CRC that
    does not hold, a header the library refuses.
    """
    try:
        if kind == SIRF:
            return _read_sirf(window)
        raw = _read_sbf(window) if kind == SBF else _read_ubx_or_rtcm3(window)
    except Exception:  # a library's refusal (truncated, unknown header, bad length): not a packet
        return None
    if raw is None:
        return None
    if kind == UBX:
        return raw if raw[:2] == b"\xb5\x62" and isvalid_checksum(raw) else None
    if kind == RTCM3:
        return raw if raw[:1] == b"\xd3" and calc_crc24q(raw) == 0 else None
    # SBF: the block length counts the 8-byte header and is a multiple of 4; the CRC covers ID … end.
    length = int.from_bytes(raw[6:8], "little")
    return raw if length >= 8 and length % 4 == 0 and sbf_crc(raw[4:]) == raw[2:4] else None


def ubx_packet(msg_class: int, msg_id: int, payload: bytes) -> bytes:
    """A framed UBX packet with any payload (for tests and the simulator)."""
    body = bytes([msg_class, msg_id, len(payload) & 0xFF, len(payload) >> 8]) + payload
    return b"\xb5\x62" + body + calc_checksum(body)


def rtcm3_packet(payload: bytes) -> bytes:
    """A framed RTCM3 packet with any payload (for tests and the simulator)."""
    head = bytes([0xD3, len(payload) >> 8 & 0x03, len(payload) & 0xFF]) + payload
    return head + crc2bytes(head)


def sirf_packet(payload: bytes) -> bytes:
    """A framed SiRF binary packet (for tests and the simulator)."""
    checksum = sum(payload) & 0x7FFF
    return b"\xa0\xa2" + len(payload).to_bytes(2, "big") + payload + checksum.to_bytes(2, "big") + b"\xb0\xb3"
