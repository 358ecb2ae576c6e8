"""Time units of every table, parsers and console alike: a time is an int64 of ns since the epoch, UTC."""

from __future__ import annotations

NS = 1_000_000_000  # nanoseconds per second
NS_PER_DAY = 86_400 * NS
NO_TIME = -(1 << 63)  # no time known: before every time (int64's least; no numpy import for two constants)
ALL_TIME = (1 << 63) - 1  # after every time: a bound that closes nothing (int64's greatest)
