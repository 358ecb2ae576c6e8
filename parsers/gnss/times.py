"""Dates and times as GNSS exports write them → int64 ns since the epoch, UTC."""

from __future__ import annotations

import datetime as dt
import re

from parsers.units import NS

_EPOCH = dt.date(1970, 1, 1)
# Years a datetime64[ns] holds (1677-09-21 … 2262-04-11), whole years only.
FIRST_YEAR, LAST_YEAR = 1678, 2261

# ISO 8601, and its date with slashes (GPSBabel's unicsv and spreadsheets write 2026/03/02): year first, so
# never ambiguous, and one separator throughout.
_ISO_RE = re.compile(
    r"(\d{4})([-/])(\d{2})\2(\d{2})[T ](\d{2}):(\d{2}):(\d{2})(?:[.,](\d{1,9}))?\s*(Z|[+-]\d{2}(?::?\d{2})?)?",
    re.IGNORECASE,
)
_DMY_RE = re.compile(r"(\d{1,2})/(\d{1,2})/(\d{4})[T ](\d{2}):(\d{2}):(\d{2})(?:[.,](\d{1,9}))?")


# Seconds since 1970 as a number (gpsd's gpscsv --cvt-isotime, JSON exports): 9 or 10 digits before the point,
# 1973 to 2286.  Fewer digits is no date (a GPS time of week, a time of day in seconds): refused, not guessed.
_EPOCH_S_RE = re.compile(r"\+?(\d{9,10})(?:\.(\d{1,9}))?")


def parse_epoch_s_ns(text: str) -> int | None:
    """``1772438400.25`` (seconds since 1970, UTC) → ns since the epoch; None when the text is not such a number.
    ValueError when it is one but its year is beyond what a time holds here."""
    m = _EPOCH_S_RE.fullmatch(text.strip())
    if m is None:
        return None
    whole, frac = m.groups()
    ns = int(whole) * NS + (int(frac.ljust(9, "0")) if frac else 0)
    year = (_EPOCH + dt.timedelta(seconds=int(whole))).year
    if year > LAST_YEAR:
        raise ValueError(f"'{text.strip()}': {year} as seconds since 1970 is beyond {LAST_YEAR}")
    return ns


def parse_time_ns(text: str, utc_offset_h: float = 0.0) -> int:
    """ISO 8601 date and time (``Z``/offset → UTC; no zone: local time at ``utc_offset_h``, default UTC), the
    same with ``YYYY/MM/DD``, or ``DD/MM/YYYY HH:MM:SS`` → ns since the epoch.  ValueError with the reason
    otherwise."""
    s = text.strip()
    m = _ISO_RE.fullmatch(s)
    zone = None
    if m:
        year, _, month, day, hh, mm, ss, frac, zone = m.groups()
    else:
        d = _DMY_RE.fullmatch(s)
        if d is None:
            raise ValueError(f"'{s}' is not a date and time (expected e.g. 2026-01-19 17:06:41 or …T17:06:41Z)")
        day, month, year, hh, mm, ss, frac = d.groups()
    try:
        days = (dt.date(int(year), int(month), int(day)) - _EPOCH).days
    except ValueError:
        raise ValueError(f"'{s}': no such date") from None
    if not FIRST_YEAR <= int(year) <= LAST_YEAR:
        raise ValueError(f"'{s}': year {int(year)} is outside {FIRST_YEAR}-{LAST_YEAR}")
    h, mi, sec = int(hh), int(mm), int(ss)
    if h > 23 or mi > 59 or sec > 60:
        raise ValueError(f"'{s}': no such time of day")
    ns = ((days * 24 + h) * 60 + mi) * 60 * NS + sec * NS + (int(frac.ljust(9, "0")) if frac else 0)
    if zone is None:
        offset_s = round(utc_offset_h * 3600)
    elif zone.upper() == "Z":
        offset_s = 0
    else:
        digits = zone[1:].replace(":", "")
        offset_s = (int(digits[:2]) * 3600 + int(digits[2:4] or 0) * 60) * (1 if zone[0] == "+" else -1)
    return ns - offset_s * NS
