"""Times for people and for JSON.

Every time in the console is an int of ns since the epoch.  Sources with a
zone (NMEA, gpsd, device CSVs with ``Z`` or an offset) are converted to UTC
when parsed; sources without one (the diagnostic logs, centre tables without
``--utc-offset``) are read as UTC too, so one scale holds for all.

* :func:`iso` — JSON: ISO 8601 / RFC 3339 in UTC with ``Z``, milliseconds
  always (``2026-03-02T08:00:13.250Z``, ``…T08:00:13.000Z``): fixed width,
  so the strings sort as the times do; micro- or nanoseconds only where the
  time has them (``…13.250125Z``), so nothing measured is cut off.
* :func:`display` — tables: ``2015-10-31 09:32:24`` (``.560`` when present).
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING

from parsers.units import NS, NS_PER_DAY

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import ArrayLike

_EPOCH = dt.datetime(1970, 1, 1)


def fraction_text(frac_ns: int) -> str:
    """Nanoseconds of a second → ``.250``, ``.250125`` or ``.250125001`` (groups of three)."""
    digits = f"{frac_ns:09d}"
    if digits[6:] != "000":
        return "." + digits
    if digits[3:6] != "000":
        return "." + digits[:6]
    return "." + digits[:3]


def exact_ns(ns: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """(epoch ns as int64, which are present): integer columns exactly, float columns
    with NaN as absent (float64 would round epoch ns to 256 ns, so ints stay ints)."""
    import numpy as np  # deferred: a query's few times use iso() alone, which spares numpy's import (~0.1 s)

    if np.asarray(ns).dtype.kind in "iu":
        ints = np.asarray(ns, np.int64)
        return ints, np.ones(len(ints), bool)
    vals = np.asarray(ns, dtype=float)
    ok = ~np.isnan(vals)
    return np.where(ok, vals, 0).astype(np.int64), ok


def iso(ns: int | None) -> str | None:
    """ns since the epoch → ``2015-10-31T09:32:24.000Z`` (UTC, milliseconds at least)."""
    if ns is None:
        return None
    whole, frac = divmod(int(ns), NS)
    return (_EPOCH + dt.timedelta(seconds=whole)).isoformat() + fraction_text(frac) + "Z"


def iso_array(ns: np.ndarray) -> np.ndarray:
    """:func:`iso` over an array of ns (float with NaN for none → None), vectorized."""
    import numpy as np  # deferred: see exact_ns

    vals = np.asarray(ns)
    ok = ~np.isnan(vals) if vals.dtype.kind == "f" else np.ones(len(vals), dtype=bool)
    ints = np.where(ok, vals, 0).astype(np.int64)
    text = np.datetime_as_string(ints.astype("datetime64[ns]"), unit="ns")  # …T09:32:24.250125000
    frac = ints % NS
    # Casting to a shorter string type cuts the digits off: ms, µs or ns as the time needs.
    cut = np.where(frac % 1_000_000 == 0, text.astype("U23"), np.where(frac % 1_000 == 0, text.astype("U26"), text))
    out = np.strings.add(cut, "Z").astype(object)
    out[~ok] = None
    return out


def display(ns: int | None) -> str:
    """For tables: ``2015-10-31 09:32:24`` or ``… 09:32:24.560`` (milliseconds, fixed width)."""
    if ns is None:
        return "–"
    ns = int(ns)
    whole, frac = divmod(ns, NS)
    text = (_EPOCH + dt.timedelta(seconds=whole)).isoformat(sep=" ")
    return text + f".{frac // 1_000_000:03d}" if frac else text


def time_of_day(ns: int, day0_index: int) -> str:
    """For a table whose date is said once: ``09:32:24``, and ``09:32:24+1`` on the day after day ``day0_index``
    (days since the epoch: ``ns // NS_PER_DAY`` of the table's first time)."""
    later = int(ns) // NS_PER_DAY - day0_index
    return display(ns)[11:19] + (f"+{later}" if later else "")


_DURATION_UNITS = {"s": 1, "m": 60, "h": 3600, "d": 86400}


def parse_duration(text: str) -> float:
    """``90s``, ``30m``, ``2h``, ``1h30m``, or a bare number of seconds → seconds (ValueError otherwise)."""
    import re

    t = text.strip().lower()
    if re.fullmatch(r"\d+(\.\d+)?", t):
        return float(t)
    parts = re.findall(r"(\d+(?:\.\d+)?)([smhd])", t)
    if not parts or "".join(n + u for n, u in parts) != t:
        raise ValueError(f"expected a duration like 90s, 30m, 2h or 1h30m, found {text!r}")
    return sum(float(n) * _DURATION_UNITS[u] for n, u in parts)


def parse_time(text: str) -> dt.datetime:
    """``2026-03-02``, ``2026-03-02T10:00``, ``2026-03-02 10:00:05``: naive, as the logs write time."""
    try:
        t = dt.datetime.fromisoformat(text.strip())
    except ValueError:
        raise ValueError(f"expected an ISO date or time (2026-03-02 or 2026-03-02T10:00), found {text!r}") from None
    return t.replace(tzinfo=None) if t.tzinfo is None else t.astimezone(dt.UTC).replace(tzinfo=None)


def time_ns(t: dt.datetime) -> int:
    """A naive UTC time (:func:`parse_time`) → ns since the epoch; ValueError where int64 ns cannot hold it."""
    delta = t - _EPOCH
    ns = (delta.days * 86_400 + delta.seconds) * NS + delta.microseconds * 1_000
    if not -(2**63) <= ns < 2**63:
        raise ValueError(f"{t.isoformat()} is outside the times a log can hold (1677 to 2262)")
    return ns
