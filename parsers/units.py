"""Time units of every table, parsers and console alike: a time is an int64 of ns since the epoch, UTC."""

from __future__ import annotations

import numpy as np

NS = 1_000_000_000  # nanoseconds per second
NS_PER_DAY = 86_400 * NS
NO_TIME = int(np.iinfo(np.int64).min)  # no time known: before every time
ALL_TIME = int(np.iinfo(np.int64).max)  # after every time: a bound that closes nothing
