"""Write ws4_subsecond.log: WS4 records with millisecond times and known truths.

Each wheel's Sys1 → Sys2 delay is a whole number of milliseconds, so the
per-axle speed 0.13 m / delay is exact in the file (see README.md here).

    python sample_logs/make_ws4_subsecond.py
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

SPACING_M = 0.13
DAMPING_ZONE_M = 0.25
AXLES_M = (0.0, 1.8, 8.5, 10.3, 18.3, 20.1, 26.8, 28.6)  # first-to-last wheel 28.6 m
IDENTITY = [
    ("000", "Diagnose I", "2"), ("002", "Bezeichnun", "'T'"), ("003", "Bezeichnun", "'M'"),
    ("004", "Bezeichnun", "'C'"), ("012", "Typennum", "13"), ("014", "Gerätestan", "3"),
    ("016", "Seriennum", "4803"), ("020", "CRC-Code", "0xD8"), ("022", "Software V", "41"),
]


def rec(ch: int, adr: str, label: str, data: str, t: dt.datetime) -> tuple[dt.datetime, str]:
    return t, (
        f"Diag_id:00002\tID:4083\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:WS4\tch:{ch}\tAdr:{adr}\t"
        f"Label:{label}\tData:{data}\tDate:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}"
    )


def passage(t0: dt.datetime, delays_ms: list[int], first: int) -> list[tuple[dt.datetime, str]]:
    second = 3 - first
    out = [rec(1, a, lab, d, t0) for a, lab, d in IDENTITY]
    t_on = t0
    for k, delay in enumerate(delays_ms):
        v = SPACING_M / (delay / 1000)
        if k:
            t_on += dt.timedelta(milliseconds=round((AXLES_M[k] - AXLES_M[k - 1]) / v * 1000))
        t_on2 = t_on + dt.timedelta(milliseconds=delay)
        zone = dt.timedelta(milliseconds=round(DAMPING_ZONE_M / v * 1000))
        out += [
            rec(first, "026", "Radsensor", "1", t_on),
            rec(second, "026", "Radsensor", "1", t_on2),
            rec(first, "026", "Radsensor", "0", t_on + zone),
            rec(second, "026", "Radsensor", "0", t_on2 + zone),
            rec(1, "080", "Summenzä", str(k + 1), t_on2 + zone),
        ]
    return out


def main() -> None:
    day = dt.datetime(2015, 10, 31)
    rows = passage(day.replace(hour=9, minute=40), [26, 26, 27, 27, 28, 28, 29, 29], first=1)
    # A maintenance trolley damps Sys1 only: not an axle.
    t = day.replace(hour=9, minute=50)
    rows += [rec(1, "026", "Radsensor", "1", t), rec(1, "026", "Radsensor", "0", t + dt.timedelta(milliseconds=180))]
    rows += passage(day.replace(hour=9, minute=55), [20] * 8, first=2)
    rows.sort(key=lambda r: r[0])
    out = Path(__file__).with_name("ws4_subsecond.log")
    out.write_text("\n".join(line for _, line in rows) + "\n", encoding="utf-8")
    print(f"wrote {len(rows)} records to {out}")


if __name__ == "__main__":
    main()
