"""Timestamps as the log wrote them: naive local time, ISO 8601."""

from __future__ import annotations

import datetime as dt

NS = 1_000_000_000  # nanoseconds per second: every time in the console is an int of ns

_EPOCH = dt.datetime(1970, 1, 1)


def iso(ns: int | None) -> str | None:
    """ns since the epoch (naive) → ``2015-10-31T09:32:24`` (fraction only when present)."""
    if ns is None:
        return None
    ns = int(ns)
    whole, frac = divmod(ns, NS)
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
    whole, frac = divmod(ns, NS)
    text = (_EPOCH + dt.timedelta(seconds=whole)).isoformat(sep=" ")
    return text + f".{frac // 1_000_000:03d}" if frac else text


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
