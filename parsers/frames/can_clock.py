"""Wall-clock times of CAN logs: ASC ``date``/``Begin Triggerblock`` lines, BLF headers, the range of frame times."""

from __future__ import annotations

import datetime as dt

from parsers.units import NS

_EPOCH = dt.datetime(1970, 1, 1)
# Frame times outside these years are not times (and would overflow 64-bit nanoseconds).
TIME_MIN_NS = (dt.datetime(1900, 1, 1) - _EPOCH) // dt.timedelta(microseconds=1) * 1000
TIME_MAX_NS = (dt.datetime(2200, 1, 1) - _EPOCH) // dt.timedelta(microseconds=1) * 1000
_MONTHS = {
    **{m: i for i, m in enumerate(("Jan", "Feb", "Mar", "Apr", "May", "Jun"), 1)},
    **{m: i for i, m in enumerate(("Jul", "Aug", "Sep", "Oct", "Nov", "Dec"), 7)},
    "Mär": 3,
    "Mai": 5,
    "Okt": 10,
    "Dez": 12,
}
_ASC_DATE_FORMATS = ("%m %d %I:%M:%S.%f %p %Y", "%m %d %I:%M:%S %p %Y", "%m %d %H:%M:%S.%f %Y", "%m %d %H:%M:%S %Y")


def wall_ns(t: dt.datetime) -> int:
    delta = t - _EPOCH
    return (delta.days * 86400 + delta.seconds) * NS + delta.microseconds * 1000


def asc_wall_clock_ns(when: str) -> int | None:
    """An ASC ``date``/``Begin Triggerblock`` time (``Sun Jun 06 10:15:02.125 2021``
    without its weekday) → ns since 1970 of that wall-clock time, or None.

    The same formats python-can's ASC reader accepts, read as naive wall
    clock: the recording PC's local time, not converted by this machine's zone.
    """
    text = when.strip()
    for name, number in _MONTHS.items():
        text = text.replace(name, f"{number:02d}")
    for fmt in _ASC_DATE_FORMATS:
        try:
            t = dt.datetime.strptime(text, fmt)
        except ValueError:
            continue
        return wall_ns(t)
    return None
