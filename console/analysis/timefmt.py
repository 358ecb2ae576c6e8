"""Timestamps as the log wrote them: naive local time, ISO 8601."""

from __future__ import annotations

import datetime as dt

_EPOCH = dt.datetime(1970, 1, 1)


def iso(ns: int | None) -> str | None:
    """ns since the epoch (naive) → ``2015-10-31T09:32:24`` (fraction only when present)."""
    if ns is None:
        return None
    ns = int(ns)
    whole, frac = divmod(ns, 1_000_000_000)
    t = _EPOCH + dt.timedelta(seconds=whole)
    text = t.isoformat()
    if frac:
        text += f".{frac:09d}".rstrip("0")
    return text


def display(ns: int | None) -> str:
    """For tables: ``2015-10-31 09:32:24`` or ``… 09:32:24.560`` (milliseconds, fixed width)."""
    if ns is None:
        return "–"
    ns = int(ns)
    whole, frac = divmod(ns, 1_000_000_000)
    text = (_EPOCH + dt.timedelta(seconds=whole)).isoformat(sep=" ")
    return text + f".{frac // 1_000_000:03d}" if frac else text
