"""Binary message parts → one fix row per epoch, as the NMEA path merges an epoch's sentences.

A u-blox receiver writes an epoch as several messages with the same GPS
time of week (iTOW): NAV-SOL, NAV-POSECEF, NAV-VELECEF, NAV-TIMEGPS … or
NAV-PVT and its companions.  Each part (:mod:`parsers.gnss.binary`) joins
the row of its device's epoch, made by the epoch's first part that has a
position, a velocity or a fix status (a time alone makes no row: it is
kept for the epoch's row and counted as a packet).  Within an epoch:

* position: the latest latitude/longitude given as such; a position
  converted from ECEF only where no such one came; the high-rate output's
  (HNR-PVT) before any other, so that a 10 Hz track does not jump to the
  1 Hz solution at whole seconds;
* speed and course: likewise, the latest ground speed given as such (the
  high-rate output's first), else one from an ECEF velocity (at the
  epoch's position, once it has one);
* time: a UTC time the receiver gives (NAV-PVT, HNR-PVT, NAV-TIMEUTC …),
  else the GPS week and time of week less the leap-second count: the one
  the receiver gave (NAV-TIMEGPS, NAV-TIMELS, or GPS - UTC from an epoch
  with both), or the one it last gave; before it gave any, the published
  count for that date (pynmeagps's table of IERS Bulletin C), replaced by
  the receiver's as soon as it gives one, in the epochs still open.  A
  message with a time of week but no week takes the week the receiver last
  gave, or that its last UTC time was in (the week turns when the time of
  week wraps);
* valid: every part of the epoch that gives a fix status says fix, and the
  row has a position; without any fix status the row is no fix with an
  unknown quality (``""``): doubtful evidence is no fix;
* ``sentence``: the names of the messages merged, in the fix table's order
  (``NAV-SOL+NAV-POSECEF+NAV-VELECEF+NAV-TIMEGPS``).

High-rate output comes late: a u-blox with sensor fusion writes HNR-PVT
ten or more times a second and the NAV-PVT of a whole second after the
HNR-PVTs that followed it.  So the epochs of the last
:data:`OPEN_WINDOW_MS` of time of week stay open (each device's last
:data:`MAX_OPEN` at most) and a late part joins its epoch's row.

An NMEA row of the same device at the same time is the same epoch (a
receiver writing both): the parts join it.  Logged fixes (LOG-BATCH,
LOG-RETRIEVEPOS) are rows of their own.
"""

from __future__ import annotations

import datetime as dt
import math
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Final

from pynmeagps.nmeahelpers import leapsecond

from parsers.gnss.binary import FROM_ECEF, GIVEN, GPS_EPOCH_NS, WEEK_MS, WEEK_NS, Part, ground_velocity
from parsers.gnss.fix_table import NAT_NS, FixRows
from parsers.gnss.nmea import DeviceClock
from parsers.units import NS

OPEN_WINDOW_MS: Final = 2000
MAX_OPEN: Final = 64
_MS_NS = 1_000_000
# Ranks of what gave a row's time: none, GPS time less a leap-second count, the receiver's UTC.
_NO_TIME, _GPS_TIME, _UTC_TIME = 0, 1, 2
_BINARY_SOURCES = ("ubx", "sbf")


@dataclass(slots=True)
class _Epoch:
    """One open epoch of a device: its row (-1 while none) and how its fields were given."""

    row: int = -1
    time_rank: int = _NO_TIME
    time_ns: int = NAT_NS
    gps_ns: int | None = None  # GPS time of the epoch (to be re-dated when a leap-second count arrives)
    position_rank: int = -1  # how the row's position and speed were given (gnss_binary's ranks; -1: not yet)
    speed_rank: int = -1
    ecef_velocity: tuple[float, float, float] | None = None  # waiting for a position
    status_seen: bool = False
    fix: bool = True  # every fix status so far says fix
    dead_reckoning: bool = False


@dataclass(slots=True)
class BinaryClock:
    """What a device's binary messages said about time, and its open epochs by time of week."""

    leap_s: int | None = None  # the receiver's last leap-second count
    week: int | None = None
    week_itow_ms: int = 0  # the time of week the week was given at
    epochs: OrderedDict[int, _Epoch] = field(default_factory=OrderedDict)

    def week_at(self, itow_ms: int) -> int | None:
        """The GPS week of a time of week, from the last week given (a wrap since: the next week)."""
        if self.week is None:
            return None
        if itow_ms < self.week_itow_ms - WEEK_MS // 2:
            return self.week + 1
        if itow_ms > self.week_itow_ms + WEEK_MS // 2:
            return self.week - 1
        return self.week


def _contradicts(ep: _Epoch, rank: int, time_ns: int, gps_ns: int | None) -> bool:
    """Whether a part's time says it is not of the epoch that has its time of week."""
    if rank == _UTC_TIME and ep.time_rank == _UTC_TIME:
        return time_ns != ep.time_ns
    return gps_ns is not None and ep.gps_ns is not None and abs(gps_ns - ep.gps_ns) > NS // 2


def _round_ms(ns: int) -> int:
    return (ns + _MS_NS // 2) // _MS_NS * _MS_NS


def _published_leap_s(gps_ns: int) -> int:
    """GPS - UTC at a GPS time, from the published table (pynmeagps's, IERS Bulletin C)."""
    return int(leapsecond(dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=gps_ns // 1000)))


class BinaryEpochs:
    """Merges binary message parts into fix rows, per device (one per stream parser)."""

    def __init__(self) -> None:
        self.clocks: dict[str, BinaryClock] = {}

    def open_rows(self) -> set[int]:
        """Rows a later part may still change (the open epochs')."""
        return {ep.row for bc in self.clocks.values() for ep in bc.epochs.values() if ep.row >= 0}

    def renumber(self, mapping: dict[int, int]) -> None:
        """Rows were renumbered (``mapping``: old → new); a row not in it has left."""
        for bc in self.clocks.values():
            for ep in bc.epochs.values():
                if ep.row >= 0:
                    ep.row = mapping.get(ep.row, -1)

    def add(
        self,
        rows: FixRows,
        clock: DeviceClock,
        part: Part,
        *,
        device: str,
        role: str,
        source: str,
        file: str,
        line: int,
    ) -> bool:
        """Add one part: True if it gave or joined a row."""
        bc = self.clocks.get(device)
        if bc is None:
            bc = self.clocks[device] = BinaryClock()
        if part.standalone:
            self._new_row(rows, _Epoch(), part, self._part_time(bc, part), device, role, source, file, line)
            return True
        if part.gps_week is not None and part.itow_ms is not None:
            bc.week, bc.week_itow_ms = part.gps_week, part.itow_ms
        elif part.utc_ns is not None and part.itow_ms is not None:
            # A UTC time and a time of week: the week they are in (to time the epochs that give only the latter).
            leap = part.leap_s if part.leap_s is not None else bc.leap_s
            utc_as_gps_ns = part.utc_ns + (leap if leap is not None else _published_leap_s(part.utc_ns)) * NS
            bc.week = round((utc_as_gps_ns - GPS_EPOCH_NS - part.itow_ms * _MS_NS) / WEEK_NS)
            bc.week_itow_ms = part.itow_ms
        if part.leap_s is not None:
            changed = part.leap_s != bc.leap_s
            bc.leap_s = part.leap_s
            if changed:
                self._redate(rows, bc)
        if part.itow_ms is None:
            return False
        ep = self._epoch(rows, clock, bc, part)
        rank, time_ns, gps_ns = self._part_time(bc, part)
        if gps_ns is not None and ep.gps_ns is None:
            ep.gps_ns = gps_ns
        if rank > ep.time_rank:
            ep.time_rank, ep.time_ns = rank, time_ns
            if ep.row >= 0:
                rows.time[ep.row] = time_ns
        if ep.row < 0:
            if not part.makes_row:
                return False  # a time alone: kept for the epoch's row
            self._new_row(rows, ep, part, (ep.time_rank, ep.time_ns, None), device, role, source, file, line)
            clock.row = ep.row
            clock.row_weak = False
        else:
            self._merge(rows, ep, part)
        if ep.time_ns != NAT_NS and ep.row == clock.row:
            clock.last_time_ns = ep.time_ns
        return True

    # ------------------------------------------------------------ epochs

    def _epoch(self, rows: FixRows, clock: DeviceClock, bc: BinaryClock, part: Part) -> _Epoch:
        """The open epoch of the part's time of week (an NMEA row of the same time, or a new one)."""
        assert part.itow_ms is not None
        itow = part.itow_ms
        rank, time_ns, gps_ns = self._part_time(bc, part)
        ep = bc.epochs.get(itow)
        if ep is not None and not _contradicts(ep, rank, time_ns, gps_ns):
            return ep
        if ep is not None:
            del bc.epochs[itow]  # the same time of week, another time: another epoch (a week later, another run)
        ep = _Epoch()
        row = clock.row
        if time_ns != NAT_NS and row >= 0 and rows.time[row] == time_ns and rows.source_at(row) not in _BINARY_SOURCES:
            # An NMEA (or gpsd) row of this device at this time: the same epoch.
            ep.row, ep.time_rank, ep.time_ns = row, _UTC_TIME, time_ns
            ep.position_rank = GIVEN if not math.isnan(rows.lat[row]) else -1
            ep.speed_rank = GIVEN if not math.isnan(rows.speed_mps[row]) else -1
            ep.status_seen, ep.fix = True, bool(rows.valid[row])
            ep.dead_reckoning = rows.quality_at(row) == "dead_reckoning"
        bc.epochs[itow] = ep
        # Close the epochs that fell out of the window (time of week wraps at the week's end).
        while bc.epochs:
            oldest = next(iter(bc.epochs))
            age = (itow - oldest) % WEEK_MS
            if len(bc.epochs) <= MAX_OPEN and age <= OPEN_WINDOW_MS:
                break
            del bc.epochs[oldest]
        return ep

    def _part_time(self, bc: BinaryClock, part: Part) -> tuple[int, int, int | None]:
        """(rank, UTC ns, GPS ns or None) of the time a part gives."""
        if part.utc_ns is not None:
            return _UTC_TIME, part.utc_ns, None
        if part.itow_ms is None:
            return _NO_TIME, NAT_NS, None
        week = part.gps_week if part.gps_week is not None else bc.week_at(part.itow_ms)
        if week is None:
            return _NO_TIME, NAT_NS, None
        tow_ns = part.gps_tow_ns if part.gps_tow_ns is not None else part.itow_ms * _MS_NS
        gps_ns = GPS_EPOCH_NS + week * WEEK_NS + tow_ns
        return _GPS_TIME, self._utc_of(bc, gps_ns), gps_ns

    @staticmethod
    def _utc_of(bc: BinaryClock, gps_ns: int) -> int:
        leap = bc.leap_s if bc.leap_s is not None else _published_leap_s(gps_ns)
        return _round_ms(gps_ns - leap * NS)

    def _redate(self, rows: FixRows, bc: BinaryClock) -> None:
        """A (new) leap-second count: the open epochs timed by GPS time take it."""
        for ep in bc.epochs.values():
            if ep.time_rank == _GPS_TIME and ep.gps_ns is not None:
                ep.time_ns = self._utc_of(bc, ep.gps_ns)
                if ep.row >= 0:
                    rows.time[ep.row] = ep.time_ns

    # ------------------------------------------------------------ rows

    def _new_row(
        self,
        rows: FixRows,
        ep: _Epoch,
        part: Part,
        timed: tuple[int, int, int | None],
        device: str,
        role: str,
        source: str,
        file: str,
        line: int,
    ) -> None:
        ep.time_rank, ep.time_ns = timed[0], timed[1]
        ep.row = rows.add(
            time_ns=ep.time_ns,
            device=device,
            role=role,
            lat=math.nan,
            lon=math.nan,
            speed_mps=math.nan,
            course_deg=math.nan,
            valid=False,
            source=source,
            sentence="",
            file=file,
            line=line,
        )
        self._merge(rows, ep, part)

    def _merge(self, rows: FixRows, ep: _Epoch, part: Part) -> None:
        row = ep.row
        # The latest position (speed) of the best rank the epoch has had.
        if not math.isnan(part.lat) and part.position_rank >= ep.position_rank:
            rows.lat[row], rows.lon[row] = part.lat, part.lon
            ep.position_rank = part.position_rank
        if not math.isnan(part.speed_mps) and part.speed_rank >= ep.speed_rank:
            rows.speed_mps[row], rows.course_deg[row] = part.speed_mps, part.course_deg
            ep.speed_rank = part.speed_rank
        if part.ecef_velocity is not None:
            ep.ecef_velocity = part.ecef_velocity
        if ep.ecef_velocity is not None and not math.isnan(rows.lat[row]):
            if ep.speed_rank <= FROM_ECEF:
                speed, course = ground_velocity(rows.lat[row], rows.lon[row], *ep.ecef_velocity)
                rows.speed_mps[row], rows.course_deg[row] = speed, course
                ep.speed_rank = FROM_ECEF
            ep.ecef_velocity = None
        if part.status is not None:
            fix, dead_reckoning = part.status
            ep.fix = ep.fix and fix
            ep.dead_reckoning = ep.dead_reckoning or dead_reckoning
            ep.status_seen = True
        valid = ep.status_seen and ep.fix and not math.isnan(rows.lat[row])
        rows.valid[row] = valid
        if not ep.status_seen:
            quality = ""
        elif not valid:
            quality = "no_fix"
        else:
            quality = "dead_reckoning" if ep.dead_reckoning else "gnss"
        rows.set_quality(row, quality)
        rows.add_sentence(row, part.kind)
