"""The GNSS device stream's rows (``gnss_devices.csv``), said once: what the file holds is what the console gets.

The run writes the fixes the radio delivered as a network server's device
stream; the simulator's station console is handed the same fixes with the
values that file holds (:func:`as_written`), so ``trackside crossing`` on the
file and the console decide on the same numbers.
"""

from __future__ import annotations

import dataclasses

from console.analysis.timefmt import iso
from console.sim.line_values import SentFix

DEVICE_STREAM_HEADER = "time,device,role,lat,lon,speed,course"


def unit_name(f: SentFix) -> str:
    """The unit as the written files name it: <train>-<role> (nmea/<train>-<role>.nmea, the device column)."""
    return f"{f.train}-{f.role}"


def _cells(f: SentFix) -> tuple[str, str, str, str, str, str, str]:
    t = iso(f.t_ns) or ""  # UTC with its Z
    return t, unit_name(f), f.role, f"{f.lat:.7f}", f"{f.lon:.7f}", f"{f.speed_mps:.2f}", f"{f.course_deg:.1f}"


def device_stream_row(f: SentFix) -> str:
    return ",".join(_cells(f))


def as_written(f: SentFix) -> SentFix:
    """The fix with the values its row holds (7 decimals of a degree, cm/s, tenths of a degree)."""
    _, _, _, lat, lon, speed, course = _cells(f)
    return dataclasses.replace(f, lat=float(lat), lon=float(lon), speed_mps=float(speed), course_deg=float(course))
