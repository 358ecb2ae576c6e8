"""Binary packets that receivers interleave with NMEA: recognised, checked, skipped.

A receiver port often carries u-blox UBX, RTCM3 corrections or SiRF binary
between (and inside the lines of) NMEA sentences.  We read none of their
content; we frame them so that their bytes are neither mistaken for junk nor
allowed to hide the sentences around them, and count them by kind.

One packet is also read: u-blox UBX-NAV-PVT (class 0x01, id 0x07), the
navigation solution every u-blox receiver since generation 8 sends once per
epoch: :func:`nav_pvt` (time, position, ground speed, heading of motion, fix
type).  Its time is the UTC date and time fields plus ``nano``, rounded to
the millisecond (the epoch's nominal time, as gpsd reports it; ``nano``
carries the receiver clock's offset from it).

Framing (all three carry a length and a checksum, so a false sync byte in
other binary data is refused, and the scan moves on by one byte):

* UBX: ``B5 62``, class, id, little-endian 16-bit payload length, payload,
  8-bit Fletcher checksum (CK_A, CK_B) over class … payload;
* RTCM3: ``D3``, 6 reserved zero bits and a 10-bit length, payload,
  CRC-24Q over header and payload;
* SiRF: ``A0 A2``, big-endian 15-bit payload length, payload, 15-bit sum
  of the payload bytes, ``B0 B3``.
"""

from __future__ import annotations

import datetime as dt
import re
import struct
from dataclasses import dataclass
from typing import Final

UBX: Final = "UBX"
RTCM3: Final = "RTCM3"
SIRF: Final = "SiRF"

# Longest packet we frame: a UBX length field may claim 64 KiB; real
# navigation packets are far shorter, and a bound keeps the look-ahead small.
MAX_PACKET_BYTES: Final = 8192

# Where a packet or a sentence may start.
SYNC_RE = re.compile(rb"[$!]|\xb5\x62|\xd3[\x00-\x03]|\xa0\xa2")


def _crc24q_table() -> list[int]:
    table = []
    for i in range(256):
        crc = i << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB
        table.append(crc & 0xFFFFFF)
    return table


_CRC24Q = _crc24q_table()


def crc24q(data: bytes | memoryview) -> int:
    """RTCM3's CRC-24Q."""
    crc = 0
    for byte in data:
        crc = ((crc << 8) & 0xFFFFFF) ^ _CRC24Q[(crc >> 16) ^ byte]
    return crc


def ubx_checksum(body: bytes | memoryview) -> tuple[int, int]:
    """UBX's 8-bit Fletcher checksum over class, id, length and payload."""
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return a, b


def packet_kind(head: bytes) -> str | None:
    """The kind a sync at the start of ``head`` announces, or None (``$``/``!`` are NMEA, not packets)."""
    if head[:2] == b"\xb5\x62":
        return UBX
    if head[:2] == b"\xa0\xa2":
        return SIRF
    if head[:1] == b"\xd3":
        return RTCM3
    return None


def header_bytes(kind: str) -> int:
    """Bytes needed before :func:`packet_length` can tell the length."""
    return {UBX: 6, RTCM3: 3, SIRF: 4}[kind]


def packet_length(kind: str, head: bytes) -> int | None:
    """Total packet length from its header, or None if the header is impossible."""
    if kind == UBX:
        total = 8 + (head[4] | head[5] << 8)
    elif kind == RTCM3:
        if head[1] & 0xFC:
            return None
        total = 6 + ((head[1] & 0x03) << 8 | head[2])
    else:
        total = 8 + ((head[2] & 0x7F) << 8 | head[3])
    return total if total <= MAX_PACKET_BYTES else None


def packet_is_valid(kind: str, packet: bytes) -> bool:
    """True when a whole packet's checksum (and SiRF's end bytes) hold."""
    if kind == UBX:
        return ubx_checksum(packet[2:-2]) == (packet[-2], packet[-1])
    if kind == RTCM3:
        return crc24q(packet[:-3]) == int.from_bytes(packet[-3:], "big")
    payload = packet[4:-4]
    checksum = (packet[-4] << 8 | packet[-3]) & 0x7FFF
    return packet[-2:] == b"\xb0\xb3" and sum(payload) & 0x7FFF == checksum


def ubx_packet(msg_class: int, msg_id: int, payload: bytes) -> bytes:
    """A framed UBX packet (for tests and the simulator)."""
    body = bytes([msg_class, msg_id, len(payload) & 0xFF, len(payload) >> 8]) + payload
    a, b = ubx_checksum(body)
    return b"\xb5\x62" + body + bytes([a, b])


def rtcm3_packet(payload: bytes) -> bytes:
    """A framed RTCM3 packet (for tests and the simulator)."""
    head = bytes([0xD3, len(payload) >> 8 & 0x03, len(payload) & 0xFF]) + payload
    return head + crc24q(head).to_bytes(3, "big")


def sirf_packet(payload: bytes) -> bytes:
    """A framed SiRF binary packet (for tests and the simulator)."""
    checksum = sum(payload) & 0x7FFF
    return b"\xa0\xa2" + len(payload).to_bytes(2, "big") + payload + checksum.to_bytes(2, "big") + b"\xb0\xb3"


NAV_PVT_CLASS_ID: Final = (0x01, 0x07)
_PVT_HEAD = struct.Struct("<IHBBBBBBIiBBBBii")  # iTOW … lat, the first 32 bytes
_PVT_MOTION = struct.Struct("<ii")  # gSpeed (mm/s), headMot (1e-5 deg), at offset 60
_EPOCH = dt.datetime(1970, 1, 1)
_MS_NS = 1_000_000


@dataclass(frozen=True)
class NavPvt:
    """What a UBX-NAV-PVT says (time in ns since the epoch, None when the receiver marks it not valid)."""

    time_ns: int | None
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    fix_type: int  # 0 no fix, 1 dead reckoning only, 2 2D, 3 3D, 4 GNSS + dead reckoning, 5 time only
    fix_ok: bool  # flags.gnssFixOK: the fix is within the receiver's accuracy masks


def nav_pvt(packet: bytes) -> NavPvt | None:
    """A valid UBX packet → its NAV-PVT contents, or None if it is another message, too short, or impossible."""
    if (packet[2], packet[3]) != NAV_PVT_CLASS_ID or len(packet) < 8 + 84:
        return None
    payload = packet[6:-2]
    _, year, month, day, hour, minute, sec, valid, _, nano, fix_type, flags, _, _, lon, lat = _PVT_HEAD.unpack_from(
        payload, 0
    )
    speed_mm_s, heading = _PVT_MOTION.unpack_from(payload, 60)
    if abs(lat) > 900_000_000 or abs(lon) > 1_800_000_000 or speed_mm_s < 0 or fix_type > 5:
        return None  # a checksum that holds over impossible values: not a navigation solution we can use
    time_ns = None
    if valid & 0x03 == 0x03 and 1980 <= year <= 2200:  # validDate and validTime, a year int64 ns can hold
        try:
            whole = dt.datetime(year, month, day, hour, minute, min(sec, 59)) - _EPOCH
        except ValueError:
            whole = None
        if whole is not None:
            ns = (whole.days * 86_400 + whole.seconds + (sec == 60)) * 1_000_000_000 + nano
            time_ns = (ns + _MS_NS // 2) // _MS_NS * _MS_NS
    return NavPvt(time_ns, lat * 1e-7, lon * 1e-7, speed_mm_s / 1000, heading * 1e-5, fix_type, bool(flags & 0x01))
