"""Fixes written as u-blox UBX and Septentrio SBF, built by the libraries' own generators.

pyubx2's ``UBXMessage`` and pysbf2's ``SBFMessage`` serialise the messages
(scaling, bit fields, checksums), so a test writes what a receiver writes,
not what our reader expects.  A fix becomes one epoch in one of the
*dialects* receivers are configured for:

* ``pvt``: NAV-PVT, NAV-POSECEF, NAV-VELECEF, NAV-TIMEGPS, NAV-EOE (u-blox 8/9);
* ``sol``: NAV-SOL, NAV-TIMEGPS (u-blox 4 to 8);
* ``llh``: NAV-POSLLH, NAV-VELNED, NAV-STATUS, NAV-TIMEUTC (u-blox 5/6 default binary);
* ``hnr``: HNR-PVT (u-blox with sensor fusion);
* ``sbf``: PVTGeodetic, ReceiverTime (Septentrio).
"""

from __future__ import annotations

import math

import pandas as pd
from pynmeagps.nmeahelpers import llh2ecef
from pysbf2 import SBFMessage
from pyubx2 import GET, UBXMessage

GPS_EPOCH = pd.Timestamp("1980-01-06T00:00:00Z")
LEAP_S = 18  # GPS - UTC since 2017-01-01
WEEK_MS = 7 * 86_400_000
DIALECTS = ("pvt", "sol", "llh", "hnr", "sbf")


def gps_time(t: pd.Timestamp, leap_s: int = LEAP_S) -> tuple[int, int, int]:
    """UTC → (GPS week, time of week in whole ms, the sub-ms rest in ns)."""
    ns = (t - GPS_EPOCH).value + leap_s * 1_000_000_000
    week, rest = divmod(ns, WEEK_MS * 1_000_000)
    itow, sub = divmod(rest, 1_000_000)
    return week, itow, sub


def _utc_fields(t: pd.Timestamp) -> dict[str, int]:
    ms = round(t.microsecond / 1000)
    return {"year": t.year, "month": t.month, "day": t.day, "hour": t.hour, "min": t.minute, "nano": ms * 1_000_000}


def ecef_velocity(lat: float, lon: float, speed_mps: float, course_deg: float) -> tuple[float, float, float]:
    """A horizontal velocity (speed, course) at a place → ECEF (m/s)."""
    e = speed_mps * math.sin(math.radians(course_deg))
    n = speed_mps * math.cos(math.radians(course_deg))
    phi, lam = math.radians(lat), math.radians(lon)
    vx = -math.sin(lam) * e - math.sin(phi) * math.cos(lam) * n
    vy = math.cos(lam) * e - math.sin(phi) * math.sin(lam) * n
    vz = math.cos(phi) * n
    return vx, vy, vz


def nav_pvt(
    t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float, *, fix_type: int = 3, fix_ok: int = 1
) -> bytes:
    _, itow, _ = gps_time(t)
    f = _utc_fields(t)
    msg = UBXMessage(
        "NAV", "NAV-PVT", GET, iTOW=itow, second=t.second, validDate=1, validTime=1, fullyResolved=1, fixType=fix_type,
        gnssFixOk=fix_ok, numSV=9, lat=lat, lon=lon, gSpeed=round(speed_mps * 1000), headMot=course_deg, **f,
    )  # fmt: skip
    return bytes(msg.serialize())


def hnr_pvt(
    t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float, *, fix_type: int = 4, fix_ok: int = 1
) -> bytes:
    _, itow, _ = gps_time(t)
    f = _utc_fields(t)
    msg = UBXMessage(
        "HNR", "HNR-PVT", GET, iTOW=itow, second=t.second, validDate=1, validTime=1, fullyResolved=1, gpsFix=fix_type,
        GPSfixOK=fix_ok, WKNSET=1, TOWSET=1, lat=lat, lon=lon, gSpeed=round(speed_mps * 1000), headMot=course_deg, **f,
    )  # fmt: skip
    return bytes(msg.serialize())


def nav_sol(
    t: pd.Timestamp,
    lat: float,
    lon: float,
    speed_mps: float,
    course_deg: float,
    *,
    fix_type: int = 3,
    fix_ok: int = 1,
    leap_s: int = LEAP_S,
) -> bytes:
    week, itow, sub = gps_time(t, leap_s)
    x, y, z = llh2ecef(lat, lon, 20.0)
    vx, vy, vz = ecef_velocity(lat, lon, speed_mps, course_deg)
    msg = UBXMessage(
        "NAV", "NAV-SOL", GET, iTOW=itow, fTOW=sub, week=week, gpsFix=fix_type, gpsfixOK=fix_ok, wknSet=1, towSet=1,
        ecefX=round(x * 100), ecefY=round(y * 100), ecefZ=round(z * 100), ecefVX=round(vx * 100),
        ecefVY=round(vy * 100), ecefVZ=round(vz * 100), numSV=8,
    )  # fmt: skip
    return bytes(msg.serialize())


def nav_posecef(t: pd.Timestamp, lat: float, lon: float) -> bytes:
    _, itow, _ = gps_time(t)
    x, y, z = llh2ecef(lat, lon, 20.0)
    msg = UBXMessage(
        "NAV", "NAV-POSECEF", GET, iTOW=itow, ecefX=round(x * 100), ecefY=round(y * 100), ecefZ=round(z * 100)
    )
    return bytes(msg.serialize())


def nav_velecef(t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float) -> bytes:
    _, itow, _ = gps_time(t)
    vx, vy, vz = ecef_velocity(lat, lon, speed_mps, course_deg)
    msg = UBXMessage(
        "NAV", "NAV-VELECEF", GET, iTOW=itow, ecefVX=round(vx * 100), ecefVY=round(vy * 100), ecefVZ=round(vz * 100)
    )
    return bytes(msg.serialize())


def nav_posllh(t: pd.Timestamp, lat: float, lon: float, *, leap_s: int = LEAP_S) -> bytes:
    _, itow, _ = gps_time(t, leap_s)
    return bytes(UBXMessage("NAV", "NAV-POSLLH", GET, iTOW=itow, lat=lat, lon=lon, hAcc=2500).serialize())


def nav_velned(t: pd.Timestamp, speed_mps: float, course_deg: float, *, leap_s: int = LEAP_S) -> bytes:
    _, itow, _ = gps_time(t, leap_s)
    cm_s = round(speed_mps * 100)
    msg = UBXMessage("NAV", "NAV-VELNED", GET, iTOW=itow, speed=cm_s, gSpeed=cm_s, heading=course_deg)
    return bytes(msg.serialize())


def nav_status(t: pd.Timestamp, *, fix_type: int = 3, fix_ok: int = 1, leap_s: int = LEAP_S) -> bytes:
    _, itow, _ = gps_time(t, leap_s)
    msg = UBXMessage("NAV", "NAV-STATUS", GET, iTOW=itow, gpsFix=fix_type, gpsFixOk=fix_ok, wknSet=1, towSet=1)
    return bytes(msg.serialize())


def nav_timegps(t: pd.Timestamp, *, leap_s: int = LEAP_S, leap_valid: int = 1) -> bytes:
    week, itow, sub = gps_time(t, leap_s)
    msg = UBXMessage(
        "NAV", "NAV-TIMEGPS", GET, iTOW=itow, fTOW=sub, week=week, leapS=leap_s, towValid=1, weekValid=1,
        leapSValid=leap_valid,
    )  # fmt: skip
    return bytes(msg.serialize())


def nav_timeutc(t: pd.Timestamp, *, leap_s: int = LEAP_S) -> bytes:
    _, itow, _ = gps_time(t, leap_s)
    msg = UBXMessage(
        "NAV", "NAV-TIMEUTC", GET, iTOW=itow, sec=t.second, validTOW=1, validWKN=1, validUTC=1, **_utc_fields(t)
    )
    return bytes(msg.serialize())


def nav_eoe(t: pd.Timestamp) -> bytes:
    _, itow, _ = gps_time(t)
    return bytes(UBXMessage("NAV", "NAV-EOE", GET, iTOW=itow).serialize())


def log_retrievepos(t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float) -> bytes:
    msg = UBXMessage(
        "LOG", "LOG-RETRIEVEPOS", GET, entryIndex=1, lat=lat, lon=lon, gSpeed=round(speed_mps * 1000),
        heading=course_deg, fixType=3, year=t.year, month=t.month, day=t.day, hour=t.hour, minute=t.minute,
        second=t.second, numSV=7,
    )  # fmt: skip
    return bytes(msg.serialize())


def sbf_pvt_geodetic(
    t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float, *, mode: int = 1, error: int = 0
) -> bytes:
    week, itow, _ = gps_time(t)
    c = math.radians(course_deg)
    msg = SBFMessage(
        "PVTGeodetic", TOW=itow, WNc=week, Type=mode, Error=error, Latitude=math.radians(lat),
        Longitude=math.radians(lon), Height=20.0, Vn=speed_mps * math.cos(c), Ve=speed_mps * math.sin(c), Vu=0.0,
        COG=course_deg, NrSV=9,
    )  # fmt: skip
    return bytes(msg.serialize())


def sbf_receiver_time(t: pd.Timestamp, *, leap_s: int = LEAP_S) -> bytes:
    week, itow, _ = gps_time(t, leap_s)
    msg = SBFMessage(
        "ReceiverTime", TOW=itow, WNc=week, UTCYear=t.year - 2000, UTCMonth=t.month, UTCDay=t.day, UTCHour=t.hour,
        UTCMin=t.minute, UTCSec=t.second, DeltaLS=leap_s, SyncLevel=7,
    )  # fmt: skip
    return bytes(msg.serialize())


def epoch(dialect: str, t: pd.Timestamp, lat: float, lon: float, speed_mps: float, course_deg: float) -> bytes:
    """One fix as the messages of one epoch in a dialect (see the module docstring)."""
    if dialect == "pvt":
        return (
            nav_pvt(t, lat, lon, speed_mps, course_deg)
            + nav_posecef(t, lat, lon)
            + nav_velecef(t, lat, lon, speed_mps, course_deg)
            + nav_timegps(t)
            + nav_eoe(t)
        )
    if dialect == "sol":
        return nav_sol(t, lat, lon, speed_mps, course_deg) + nav_timegps(t)
    if dialect == "llh":
        return nav_posllh(t, lat, lon) + nav_velned(t, speed_mps, course_deg) + nav_status(t) + nav_timeutc(t)
    if dialect == "hnr":
        return hnr_pvt(t, lat, lon, speed_mps, course_deg)
    if dialect == "sbf":
        return sbf_pvt_geodetic(t, lat, lon, speed_mps, course_deg) + sbf_receiver_time(t)
    raise ValueError(dialect)


def write_fixes(fixes: pd.DataFrame, dialect: str, *, between: bytes = b"") -> bytes:
    """Fixes (time, lat, lon, speed_mps, course_deg) → a capture: one epoch per fix, ``between`` after each."""
    out = []
    for r in fixes.itertuples(index=False):
        out.append(epoch(dialect, r.time, r.lat, r.lon, r.speed_mps, r.course_deg) + between)
    return b"".join(out)
