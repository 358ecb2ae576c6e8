"""What binary navigation messages say: UBX and SBF packets → parts of an epoch's fix.

A framed packet (:mod:`parsers.gnss.packets`) is decoded by its library —
pyubx2's ``UBXReader.parse`` for UBX, pysbf2's ``SBFReader.parse`` for SBF —
and the messages that carry a position, a velocity, a time or a fix status
become a :class:`Part`.  ``parsers.gnss.epochs`` merges the parts of one
epoch (one GPS time of week) into one fix row.

UBX messages read (their names are kept in the row's ``sentence``):

* ``NAV-PVT``, ``HNR-PVT`` (high-rate, sensor-fused), ``NAV-PVAT``: UTC
  date and time, latitude/longitude, ground speed, heading of motion, fix
  type and the gnssFixOK flag;
* ``NAV-SOL``: GPS week and time of week, ECEF position and velocity, fix
  type and gpsFixOK (u-blox 4 to 8);
* ``NAV-POSLLH``, ``NAV-HPPOSLLH``: latitude/longitude;
  ``NAV-POSECEF``: ECEF position; ``NAV-VELNED``: ground speed and heading;
  ``NAV-VELECEF``: ECEF velocity; ``NAV-STATUS``: fix type and gpsFixOK;
* ``NAV-TIMEGPS``: GPS week, time of week and the leap-second count;
  ``NAV-TIMEUTC``: UTC; ``NAV-TIMELS``: the current leap-second count;
* ``LOG-BATCH``, ``LOG-RETRIEVEPOS``: fixes the receiver logged and hands
  out later: each is a row of its own, never merged into a live epoch.

SBF blocks read: ``PVTGeodetic``, ``PVTCartesian`` (a fix; SBF time stamps
are GPS week and time of week), ``ReceiverTime`` and ``GPSUtc`` (the
leap-second count).

Units and conventions:

* ECEF positions become latitude/longitude with pynmeagps's ``ecef2llh``
  (WGS84, Olson's method); an ECEF velocity becomes ground speed and course
  by rotating it into the local east/north/up frame at the epoch's position;
* a u-blox fix type is 0 no fix, 1 dead reckoning only, 2 2D, 3 3D, 4 GNSS
  with dead reckoning, 5 time only: a row is a fix (``valid``) when the
  message's fix-OK flag is set and the type is 1-4 (1: ``dead_reckoning``);
  a time-only fix (a surveyed-in timing receiver) is no position fix;
* UTC times are the UTC fields plus the nanoseconds, rounded to the
  millisecond: the epoch's nominal time (the nanoseconds carry the
  receiver clock's offset from it), as gpsd reports it.  GPS times are week
  and time of week plus the fractional part, turned into UTC with the
  leap-second count (``parsers.gnss.epochs``);
* a message whose checksum holds but whose values are impossible (latitude
  past ±90°, negative speed, an unknown fix type) says nothing we can use:
  it is counted as a packet, not read.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from typing import Any, Final

from pynmeagps.nmeahelpers import ecef2llh
from pysbf2 import SBFReader
from pyubx2 import UBX_MSGIDS, UBXReader

from parsers.gnss import packets
from parsers.gnss.fix_table import UBX_KINDS
from parsers.units import NS_PER_DAY

GPS_EPOCH_NS: Final = 315_964_800 * 1_000_000_000  # 1980-01-06T00:00:00Z
WEEK_NS: Final = 7 * NS_PER_DAY
WEEK_MS: Final = 7 * 86_400 * 1000
_MS_NS = 1_000_000
_EPOCH = dt.datetime(1970, 1, 1)
_SBF_DNU = -2e10  # SBF's "do not use" for floating-point fields
MAX_LEAP_S: Final = 60  # a bound on GPS - UTC no receiver will reach for decades (leap seconds end by 2035)

# The UBX messages read here (those a fix table row can name), by the (class, id) pyubx2's table gives each name.
UBX_READ: Final = {(key[0], key[1]): name for key, name in UBX_MSGIDS.items() if name in UBX_KINDS}
# SBF block numbers read.
SBF_READ: Final = {4007: "PVTGeodetic", 4006: "PVTCartesian", 5914: "ReceiverTime", 5894: "GPSUtc"}
# SBF PVT modes that are a position fix: standalone, DGPS, RTK fixed/float, SBAS, moving-base RTK, PPP
# (3, a fixed location the user entered, is none).
_SBF_FIX_MODES = frozenset({1, 2, 4, 5, 6, 7, 8, 10})
# Ranks of a position or speed within an epoch: converted from ECEF, given as such, from the high-rate
# (sensor-fused) output, which keeps a 10 Hz track free of the 1 Hz solution's jumps at whole seconds.
FROM_ECEF, GIVEN, HIGH_RATE = 0, 1, 2


@dataclass(slots=True)
class Part:
    """What one message says about its epoch (NaN / None where it says nothing)."""

    kind: str  # the message name, as kept in the row's ``sentence``
    itow_ms: int | None = None  # the epoch: GPS time of week, ms
    utc_ns: int | None = None  # the epoch's UTC time (ns since 1970, ms-rounded)
    gps_week: int | None = None
    gps_tow_ns: int | None = None  # GPS time of week with its fractional part
    leap_s: int | None = None  # GPS - UTC, as the receiver gives it
    lat: float = math.nan
    lon: float = math.nan
    # How the position and speed were given, for the epoch's choice: HIGH_RATE, GIVEN, or FROM_ECEF (converted).
    position_rank: int = 1
    speed_mps: float = math.nan
    course_deg: float = math.nan
    speed_rank: int = 1
    ecef_velocity: tuple[float, float, float] | None = None  # m/s, turned into ground speed at the epoch's position
    status: tuple[bool, bool] | None = None  # (a position fix, dead reckoning only), when the message says
    standalone: bool = False  # a logged fix: a row of its own

    @property
    def makes_row(self) -> bool:
        """A position, a velocity or a fix status: enough for a row (time alone joins one)."""
        return (
            not math.isnan(self.lat)
            or not math.isnan(self.speed_mps)
            or self.ecef_velocity is not None
            or self.status is not None
        )


class Unreadable(Exception):
    """A valid packet of a kind we read whose content the library cannot decode, or that is impossible."""


def _utc_ns(year: int, month: int, day: int, hour: int, minute: int, sec: int, nano: int) -> int | None:
    """UTC fields → ns since 1970, rounded to the millisecond; None if they are no date (or out of range)."""
    if not 1980 <= year <= 2200:  # GPS time began in 1980; int64 ns ends in 2262
        return None
    try:
        whole = dt.datetime(year, month, day, hour, minute, min(sec, 59)) - _EPOCH
    except ValueError:
        return None
    ns = (whole.days * 86_400 + whole.seconds + (sec == 60)) * 1_000_000_000 + nano
    return (ns + _MS_NS // 2) // _MS_NS * _MS_NS


def plausible_leap(leap_s: int | None) -> int | None:
    """A leap-second count as given, or None if no receiver could mean it (GPS - UTC was 0 in 1980, 18 since 2017)."""
    return leap_s if leap_s is not None and 0 <= leap_s <= MAX_LEAP_S else None


def _leap_from(itow_ms: int, utc_ns_exact: int) -> int | None:
    """GPS - UTC in s, from an epoch's GPS time of week and its exact UTC time (the week cancels)."""
    utc_tow_ns = (utc_ns_exact - GPS_EPOCH_NS) % WEEK_NS
    return plausible_leap(round(((itow_ms * _MS_NS - utc_tow_ns) % WEEK_NS) / 1e9))


def ground_velocity(lat: float, lon: float, vx: float, vy: float, vz: float) -> tuple[float, float]:
    """An ECEF velocity (m/s) at a position → (ground speed m/s, course ° true)."""
    phi, lam = math.radians(lat), math.radians(lon)
    east = -math.sin(lam) * vx + math.cos(lam) * vy
    north = -math.sin(phi) * math.cos(lam) * vx - math.sin(phi) * math.sin(lam) * vy + math.cos(phi) * vz
    return math.hypot(east, north), math.degrees(math.atan2(east, north)) % 360.0


def _from_ecef(x_m: float, y_m: float, z_m: float) -> tuple[float, float]:
    """ECEF (m) → (lat, lon) degrees; NaN for a position that is no place on Earth (a receiver's zeros)."""
    if math.hypot(x_m, y_m, z_m) < 6_000_000 or math.hypot(x_m, y_m, z_m) > 7_000_000:
        return math.nan, math.nan  # not near the Earth's surface (no fix: zeros)
    lat, lon, _ = ecef2llh(x_m, y_m, z_m)
    return float(lat), float(lon)


def _fix_status(fix_ok: Any, fix_type: Any) -> tuple[bool, bool]:
    return bool(fix_ok) and 1 <= fix_type <= 4, fix_type == 1


def _check(lat: float, lon: float, speed_mps: float, fix_type: int) -> None:
    if abs(lat) > 90 or abs(lon) > 180 or speed_mps < 0 or fix_type > 5:
        raise Unreadable("impossible values")


def _pvt_like(msg: Any, kind: str, *, sec: str, nano: str, fix_ok: str, fix_type: str, heading: str) -> Part:
    """NAV-PVT, HNR-PVT, NAV-PVAT and LOG-BATCH: one shape under different field names."""
    lat, lon, speed = msg.lat, msg.lon, msg.gSpeed / 1000
    ftype = getattr(msg, fix_type)
    _check(lat, lon, speed, ftype)
    part = Part(kind, itow_ms=msg.iTOW, speed_mps=speed, course_deg=getattr(msg, heading) % 360.0)
    if kind == "HNR-PVT":
        part.position_rank = part.speed_rank = HIGH_RATE
    if not getattr(msg, "invalidLlh", 0):
        part.lat, part.lon = lat, lon
    part.status = _fix_status(getattr(msg, fix_ok), ftype)
    if msg.validDate and msg.validTime:
        exact = _utc_ns(msg.year, msg.month, msg.day, msg.hour, msg.min, getattr(msg, sec), 0)
        if exact is not None:
            exact += getattr(msg, nano)
            part.utc_ns = (exact + _MS_NS // 2) // _MS_NS * _MS_NS
            if getattr(msg, "fullyResolved", 0):  # the UTC of this epoch is exact: GPS - UTC follows
                part.leap_s = _leap_from(msg.iTOW, exact)
    return part


def _ubx_part(msg: Any, kind: str) -> Part:
    if kind == "NAV-PVT":
        return _pvt_like(
            msg, kind, sec="second", nano="nano", fix_ok="gnssFixOk", fix_type="fixType", heading="headMot"
        )
    if kind == "HNR-PVT":
        return _pvt_like(msg, kind, sec="second", nano="nano", fix_ok="GPSfixOK", fix_type="gpsFix", heading="headMot")
    if kind == "NAV-PVAT":
        return _pvt_like(
            msg, kind, sec="sec", nano="nano", fix_ok="gnssFixOK", fix_type="fixType", heading="motHeading"
        )
    if kind == "LOG-BATCH":
        part = _pvt_like(
            msg, kind, sec="sec", nano="fracSec", fix_ok="gnssFixOK", fix_type="fixType", heading="headMot"
        )
        part.standalone, part.leap_s = True, None
        return part
    if kind == "LOG-RETRIEVEPOS":
        speed = msg.gSpeed / 1000
        _check(msg.lat, msg.lon, speed, msg.fixType)
        # No fix-OK flag here: the receiver logs only fixes that passed its masks.
        part = Part(kind, lat=msg.lat, lon=msg.lon, speed_mps=speed, course_deg=msg.heading % 360.0, standalone=True)
        part.status = _fix_status(True, msg.fixType)
        part.utc_ns = _utc_ns(msg.year, msg.month, msg.day, msg.hour, msg.minute, msg.second, 0)
        return part
    part = Part(kind, itow_ms=msg.iTOW)
    if kind == "NAV-SOL":
        if msg.wknSet:
            part.gps_week = msg.week
        if msg.towSet:
            part.gps_tow_ns = msg.iTOW * _MS_NS + msg.fTOW
        part.lat, part.lon = _from_ecef(msg.ecefX / 100, msg.ecefY / 100, msg.ecefZ / 100)
        part.position_rank = part.speed_rank = FROM_ECEF
        if not math.isnan(part.lat):
            part.speed_mps, part.course_deg = ground_velocity(
                part.lat, part.lon, msg.ecefVX / 100, msg.ecefVY / 100, msg.ecefVZ / 100
            )
        if msg.gpsFix > 5:
            raise Unreadable("impossible fix type")
        part.status = _fix_status(msg.gpsfixOK, msg.gpsFix)
    elif kind in ("NAV-POSLLH", "NAV-HPPOSLLH"):
        _check(msg.lat, msg.lon, 0.0, 0)
        if not getattr(msg, "invalidLlh", 0):
            part.lat, part.lon = msg.lat, msg.lon
    elif kind == "NAV-POSECEF":
        part.lat, part.lon = _from_ecef(msg.ecefX / 100, msg.ecefY / 100, msg.ecefZ / 100)
        part.position_rank = FROM_ECEF
    elif kind == "NAV-VELNED":
        part.speed_mps, part.course_deg = msg.gSpeed / 100, msg.heading % 360.0
    elif kind == "NAV-VELECEF":
        part.ecef_velocity = (msg.ecefVX / 100, msg.ecefVY / 100, msg.ecefVZ / 100)
    elif kind == "NAV-STATUS":
        if msg.gpsFix > 5:
            raise Unreadable("impossible fix type")
        part.status = _fix_status(msg.gpsFixOk, msg.gpsFix)
    elif kind == "NAV-TIMEGPS":
        if msg.weekValid:
            part.gps_week = msg.week
        if msg.towValid:
            part.gps_tow_ns = msg.iTOW * _MS_NS + msg.fTOW
        if msg.leapSValid:
            part.leap_s = plausible_leap(msg.leapS)
    elif kind == "NAV-TIMEUTC":
        if msg.validUTC:  # UTC is known (the receiver has its leap-second count)
            exact = _utc_ns(msg.year, msg.month, msg.day, msg.hour, msg.min, msg.sec, 0)
            if exact is not None:
                exact += msg.nano
                part.utc_ns = (exact + _MS_NS // 2) // _MS_NS * _MS_NS
                part.leap_s = _leap_from(msg.iTOW, exact)
    elif kind == "NAV-TIMELS" and msg.validCurrLs:
        part.leap_s = plausible_leap(msg.currLs)
    return part


def _sbf_valid(value: float) -> bool:
    return value > _SBF_DNU / 2 and math.isfinite(value)


def _sbf_part(msg: Any, kind: str) -> Part:
    part = Part(kind, itow_ms=msg.TOW, gps_week=msg.WNc, gps_tow_ns=msg.TOW * _MS_NS)
    if msg.TOW == 0xFFFFFFFF or msg.WNc == 0xFFFF:  # no time yet
        return Part(kind)
    if kind in ("PVTGeodetic", "PVTCartesian"):
        mode = msg.Type
        if kind == "PVTGeodetic":
            lat, lon = msg.Latitude, msg.Longitude
            if _sbf_valid(lat) and _sbf_valid(lon):
                part.lat, part.lon = math.degrees(lat), math.degrees(lon)
                _check(part.lat, part.lon, 0.0, 0)
            if _sbf_valid(msg.Vn) and _sbf_valid(msg.Ve):
                part.speed_mps = math.hypot(msg.Vn, msg.Ve)
                part.course_deg = msg.COG % 360.0 if _sbf_valid(msg.COG) else math.nan
        else:
            if _sbf_valid(msg.X) and _sbf_valid(msg.Y) and _sbf_valid(msg.Z):
                part.lat, part.lon = _from_ecef(msg.X, msg.Y, msg.Z)
                part.position_rank = FROM_ECEF
            if _sbf_valid(msg.Vx) and _sbf_valid(msg.Vy) and _sbf_valid(msg.Vz):
                part.ecef_velocity = (msg.Vx, msg.Vy, msg.Vz)
        part.status = (msg.Error == 0 and mode in _SBF_FIX_MODES, False)
    elif kind == "ReceiverTime":
        # Its UTC fields are whole seconds (the block's time stamp has the milliseconds): only GPS - UTC is read.
        part.leap_s = plausible_leap(msg.DeltaLS)  # -128: not known
    elif kind == "GPSUtc":
        part.leap_s = plausible_leap(msg.DEL_t_LS)
    return part


def binary_kind(kind: str, raw: bytes) -> str | None:
    """The message name of a framed packet we read, else None (a packet we only count)."""
    if kind == packets.UBX:
        return UBX_READ.get((raw[2], raw[3]))
    if kind == packets.SBF:
        return SBF_READ.get(int.from_bytes(raw[4:6], "little") & 0x1FFF)
    return None


def decode(kind: str, raw: bytes) -> Part | None:
    """A framed, valid packet → the :class:`Part` it gives, or None if it is of a kind we do not read.

    :class:`Unreadable` if it is of a kind we read but its content cannot be
    decoded or is impossible.
    """
    name = binary_kind(kind, raw)
    if name is None:
        return None
    try:
        if kind == packets.UBX:
            return _ubx_part(UBXReader.parse(raw), name)
        return _sbf_part(SBFReader.parse(raw), name)
    except Unreadable:
        raise
    except Exception as exc:  # the library must never crash the parse; a payload it refuses is counted
        raise Unreadable(f"{type(exc).__name__}: {exc}") from None
