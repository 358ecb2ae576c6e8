"""Write ws4_health.log: two counting heads over four hours, one of them failing.

WS4 (device 4083) is healthy; WS5 (device 4084) has a Sys2 sensor that
starts to fail at 07:30: its analog value drifts down 120 counts an hour and
its 1-edge counter (disturbances) grows ever faster.  Truths in README.md
here; ``tests/test_health.py`` asserts them.

Every 5 minutes each head writes a status dump (sum counter, per channel the
4-edge and 1-edge counters and the two analog values, Adr 134/136); once an
hour, at :22:37.250, an 8-axle tram passes WS4 and a minute later WS5.  WS4's
device restarts at 08:02:30 (identity dump again, counters back to 0).
Deterministic: the noise comes from a seeded generator.

    python sample_logs/make_ws4_health.py
"""

from __future__ import annotations

import datetime as dt
import random
from pathlib import Path

DAY = dt.datetime(2015, 10, 31)
START, END = DAY.replace(hour=6), DAY.replace(hour=10)
STATUS_EVERY = dt.timedelta(minutes=5)
HEADS = {"WS4": 4083, "WS5": 4084}
SERIALS = {"WS4": "4803", "WS5": "4804"}
ANALOG_LEVEL = {("WS4", 1): 2410, ("WS4", 2): 2398, ("WS5", 1): 2405, ("WS5", 2): 2402}
ADR_OFFSET = {"134": 7, "136": -7}  # the two analog registers of a channel differ a little (paper: 2416 / 2402)
FAIL_HEAD, FAIL_CH = "WS5", 2
FAIL_START = DAY.replace(hour=7, minute=30)
DRIFT_PER_H = 120.0  # analog counts lost per hour after FAIL_START
DISTURB_RAMP_PER_H2 = 100.0  # disturbance rate grows 100/h every hour after FAIL_START
BASE_DISTURB_P = 0.15  # healthy: chance of one disturbance per 5-minute dump (≈ 1.8/h)
RESTART_HEAD, RESTART_AT = "WS4", DAY.replace(hour=8, minute=2, second=30)
SPACING_M = 0.13
AXLES_M = (0.0, 1.8, 8.5, 10.3, 18.3, 20.1, 26.8, 28.6)
SPEED_MPS = 5.0
ZONE_M = 0.25


def identity(head: str) -> list[tuple[str, str, str]]:
    return [
        ("000", "Diagnose I", "2"), ("002", "Bezeichnun", "'T'"), ("003", "Bezeichnun", "'M'"),
        ("004", "Bezeichnun", "'C'"), ("012", "Typennum", "13"), ("014", "Gerätestan", "3"),
        ("016", "Seriennum", SERIALS[head]), ("020", "CRC-Code", "0xD8"), ("022", "Software V", "41"),
    ]


def rec(head: str, ch: int, adr: str, label: str, data: str, t: dt.datetime) -> tuple[dt.datetime, str]:
    return t, (
        f"Diag_id:00002\tID:{HEADS[head]}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\tch:{ch}\tAdr:{adr}\t"
        f"Label:{label}\tData:{data}\tDate:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}"
    )


def ms(x: float) -> dt.timedelta:
    return dt.timedelta(milliseconds=round(x))


class Head:
    """Counter state of one head's device."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.sum = 0
        self.four = {1: 0, 2: 0}
        self.one = {1: 0, 2: 0}
        self.ramp_done = 0  # disturbances already added by the failure ramp

    def restart(self, t: dt.datetime) -> list[tuple[dt.datetime, str]]:
        self.sum, self.four, self.one = 0, {1: 0, 2: 0}, {1: 0, 2: 0}
        return [rec(self.name, 1, a, lab, d, t + ms(4 * i)) for i, (a, lab, d) in enumerate(identity(self.name))]

    def passage(self, t0: dt.datetime) -> list[tuple[dt.datetime, str]]:
        out = []
        delay = SPACING_M / SPEED_MPS * 1000
        zone = ZONE_M / SPEED_MPS * 1000
        for x_m in AXLES_M:
            on1 = t0 + ms(x_m / SPEED_MPS * 1000)
            on2 = on1 + ms(delay)
            self.sum += 1
            self.four[1] += 1
            self.four[2] += 1
            out += [
                rec(self.name, 1, "026", "Radsensor", "1", on1),
                rec(self.name, 2, "026", "Radsensor", "1", on2),
                rec(self.name, 1, "026", "Radsensor", "0", on1 + ms(zone)),
                rec(self.name, 2, "026", "Radsensor", "0", on2 + ms(zone)),
                rec(self.name, 1, "080", "Summenzä", str(self.sum), on2 + ms(zone)),
            ]
        return out

    def status(self, t: dt.datetime, rng: random.Random) -> list[tuple[dt.datetime, str]]:
        out = [rec(self.name, 1, "080", "Summenzä", str(self.sum), t)]
        hours_failing = max(0.0, (t - FAIL_START).total_seconds() / 3600)
        for ch in (1, 2):
            failing = self.name == FAIL_HEAD and ch == FAIL_CH and hours_failing > 0
            self.one[ch] += rng.random() < BASE_DISTURB_P
            if failing:
                # ∫ 100 x dx = 50 x²: the rate climbs from ~2/h to ~250/h by 10:00.
                target = int(DISTURB_RAMP_PER_H2 / 2 * hours_failing**2)
                self.one[ch] += target - self.ramp_done
                self.ramp_done = target
            level = ANALOG_LEVEL[(self.name, ch)] - (DRIFT_PER_H * hours_failing if failing else 0.0)
            k = 1 + 4 * ch
            out += [
                rec(self.name, ch, "084", "Zähler 4-Fl", str(self.four[ch]), t + ms(k)),
                rec(self.name, ch, "088", "Zähler 1-Fl", str(self.one[ch]), t + ms(k + 1)),
            ]
            for j, (adr, offset) in enumerate(ADR_OFFSET.items()):
                value = round(level + offset + rng.randint(-4, 4))
                out.append(rec(self.name, ch, adr, "Analogwer", str(value), t + ms(k + 2 + j)))
        return out


def main() -> None:
    rng = random.Random(20151031)
    heads = {name: Head(name) for name in HEADS}
    rows: list[tuple[dt.datetime, str]] = []
    for i, head in enumerate(heads.values()):
        rows += head.restart(START - dt.timedelta(seconds=30) + dt.timedelta(seconds=i))
    t = START
    while t <= END:
        for i, head in enumerate(heads.values()):
            rows += head.status(t + dt.timedelta(milliseconds=500 * i), rng)
        nxt = t + STATUS_EVERY
        if t < RESTART_AT <= nxt:
            rows += heads[RESTART_HEAD].restart(RESTART_AT)
        if t.minute == 20:  # an hourly tram at :22, well clear of the dumps: WS4, then WS5
            tram = t.replace(minute=22, second=37, microsecond=250_000)
            rows += heads["WS4"].passage(tram)
            rows += heads["WS5"].passage(tram + dt.timedelta(seconds=61, milliseconds=130))
        t = nxt
    rows.sort(key=lambda r: r[0])
    out = Path(__file__).with_name("ws4_health.log")
    out.write_text("\n".join(line for _, line in rows) + "\n", encoding="utf-8")
    print(f"wrote {len(rows)} records to {out}")


if __name__ == "__main__":
    main()
