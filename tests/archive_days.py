"""A few days of history for the archive's trend tests: sample logs copied onto later dates, the analog values drifting.

Not a test module: ``tests/test_archive_trends.py`` and the HTML check use it.
"""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

from tests.conftest import SAMPLES

DAYS = 4
DRIFT_PER_DAY = 25  # analog counts lost per day: a sensor slowly leaving its band
_DATE = re.compile(r"Date:(\d{4}-\d{2}-\d{2})")
_ANALOG = re.compile(r"(Label:Analogwer[^\t]*\tData:)(\d+)")


def write_days(out: Path, days: int = DAYS) -> list[Path]:
    """The health and detection samples once a day (day k shifted by k days); the crossing samples as they are."""
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for k in range(days):
        for name in ("ws4_health.log", "osong_ws4_0932_detection.log"):
            text = (SAMPLES / name).read_text(encoding="utf-8", errors="surrogateescape")

            def shift(m: re.Match[str], k: int = k) -> str:
                return "Date:" + str(dt.date.fromisoformat(m.group(1)) + dt.timedelta(days=k))

            text = _DATE.sub(shift, text)
            text = _ANALOG.sub(lambda m, k=k: m.group(1) + str(int(m.group(2)) - DRIFT_PER_DAY * k), text)
            path = out / f"day{k}_{name}"
            path.write_text(text, encoding="utf-8", errors="surrogateescape")
            written.append(path)
    for name in ("crossing_example.csv", "gnss_devices.csv"):
        target = out / name
        target.write_bytes((SAMPLES / name).read_bytes())
        written.append(target)
    return written
