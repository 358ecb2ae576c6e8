"""Write example_station.log: a morning on the shipped example layout.

Diagnostic records (millisecond times) from the five counting heads WS1..WS5
of ``console/layouts/example_station.toml``, each on its own device, with a
heartbeat record (Adr 000) every 20 s so record gaps mean something.

    python sample_logs/make_example_station.py

What happens (the truth the tests assert, see README.md here):

* 08:00 tram3 runs up WS1 → WS5 at 10 m/s: every section occupied, then clear;
* 08:30 tram3 runs down WS5 → WS1 at 12 m/s;
* 09:00 tram3 runs up, but WS3's Sys2 misses the 4th axle: B1 and B2 go
  disturbed (one system only at WS3);
* 09:40 after resets of B1 and B2 at 09:30 (given on the command line),
  a sweep train runs up: B1 and B2 go preparatory → clear;
* 10:00–10:10 the device of WS5 is silent (power loss: a record gap);
* 10:30 a single damping of WS2 Sys1, alone (a trolley): held, then released.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

HEADS = {"WS1": (4081, 10050.0), "WS2": (4082, 10650.0), "WS3": (4083, 12400.0), "WS4": (4084, 13150.0), "WS5": (4085, 13950.0)}
AXLES_M = (0.0, 1.8, 8.5, 10.3, 18.3, 20.1, 26.8, 28.6)
SPACING_M, ZONE_M = 0.13, 0.25
DAY = dt.datetime(2026, 3, 2)


def rec(head: str, ch: int, adr: str, label: str, data: str, t: dt.datetime) -> tuple[dt.datetime, str]:
    dev = HEADS[head][0]
    return t, (
        f"Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:{adr}\t"
        f"Label:{label}\tData:{data}\tDate:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}"
    )


def ms(t: dt.datetime) -> dt.datetime:
    return t.replace(microsecond=(t.microsecond // 1000) * 1000)


def run(start: dt.datetime, speed: float, up: bool, miss: tuple[str, int, int] | None = None) -> list[tuple[dt.datetime, str]]:
    """A train's wheel records at every head; miss = (head, channel, axle index) not seen."""
    out = []
    order = sorted(HEADS, key=lambda h: HEADS[h][1], reverse=not up)
    origin = HEADS[order[0]][1] - (1 if up else -1) * 50.0
    for head in order:
        dist = abs(HEADS[head][1] - origin)
        for k, a in enumerate(AXLES_M):
            t1 = start + dt.timedelta(seconds=(dist + a) / speed)
            t2 = t1 + dt.timedelta(seconds=SPACING_M / speed)
            zone = dt.timedelta(seconds=ZONE_M / speed)
            first, second = (1, 2) if up else (2, 1)
            for ch, t_on in ((first, t1), (second, t2)):
                if miss == (head, ch, k):
                    continue
                out += [rec(head, ch, "026", "Radsensor", "1", ms(t_on)), rec(head, ch, "026", "Radsensor", "0", ms(t_on + zone))]
    return out


def main() -> None:
    rows: list[tuple[dt.datetime, str]] = []
    rows += run(DAY.replace(hour=8), 10.0, up=True)
    rows += run(DAY.replace(hour=8, minute=30), 12.0, up=False)
    rows += run(DAY.replace(hour=9), 10.0, up=True, miss=("WS3", 2, 3))
    rows += run(DAY.replace(hour=9, minute=40), 8.0, up=True)
    t = DAY.replace(hour=10, minute=30)
    rows += [rec("WS2", 1, "026", "Radsensor", "1", t), rec("WS2", 1, "026", "Radsensor", "0", t + dt.timedelta(milliseconds=300))]
    # Heartbeat every 20 s per device, 07:55 – 11:00, except WS5 10:00 – 10:10.
    beat = DAY.replace(hour=7, minute=55)
    while beat < DAY.replace(hour=11):
        for head in HEADS:
            silent = head == "WS5" and DAY.replace(hour=10) <= beat < DAY.replace(hour=10, minute=10)
            if not silent:
                rows.append(rec(head, 1, "000", "Diagnose I", "2", beat))
        beat += dt.timedelta(seconds=20)
    rows.sort(key=lambda r: r[0])
    out = Path(__file__).with_name("example_station.log")
    out.write_text("\n".join(line for _, line in rows) + "\n", encoding="utf-8")
    print(f"wrote {len(rows)} records to {out}")


if __name__ == "__main__":
    main()
