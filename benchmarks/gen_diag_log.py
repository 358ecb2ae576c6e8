"""Generate a realistic Frauscher-style diagnostic log of about N records.

Trains pass four counting heads (WS1..WS4 on four evaluation boards); each
passage writes an identity/register dump like the Osong excerpt, then for
every axle the two systems' wheel-sensor onsets and releases (Radsensor,
Adr 026, Data 1 then 0) with millisecond times, and the sum counter.
The output is deterministic for a given seed.

    python benchmarks/gen_diag_log.py 3000000 /tmp/diag_3M.log
"""

from __future__ import annotations

import argparse
import datetime as dt
import random
from pathlib import Path

SPACING_M = 0.13
DAMPING_ZONE_M = 0.25
# A 3-car tram: first-to-last wheel 28.6 m, as on the Osong test line.
AXLE_POSITIONS_M = (0.0, 1.8, 8.5, 10.3, 18.3, 20.1, 26.8, 28.6)

IDENTITY_DUMP = [
    ("000", "Diagnose I", "2"),
    ("002", "Bezeichnun", "'T'"),
    ("003", "Bezeichnun", "'M'"),
    ("004", "Bezeichnun", "'C'"),
    *[(f"{a:03d}", "Bezeichnun", "' '") for a in range(5, 12)],
    ("012", "Typennum", "13"),
    ("014", "Gerätestan", "3"),
    ("016", "Seriennum", "4803"),
    ("020", "CRC-Code", "0xD8"),
    ("022", "Software V", "41"),
    ("032", "Diagnose", "217"),
    ("082", "Zähler 4-Fl", "0"),
    ("086", "Zähler 1-Fl", "0"),
    ("134", "Analogwer", "2416"),
    ("136", "Analogwer", "2402"),
]


def _line(dev: int, head: str, ch: int, adr: str, label: str, data: str, t: dt.datetime) -> str:
    return (
        f"Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:{head}\t"
        f"ch:{ch}\tAdr:{adr}\tLabel:{label}\tData:{data}\t"
        f"Date:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}"
    )


def passage_lines(
    dev: int, head: str, t0: dt.datetime, speed_mps: float, up: bool, sum_count: int
) -> list[tuple[dt.datetime, str]]:
    """All records one train writes while passing one head."""
    out: list[tuple[dt.datetime, str]] = []
    for adr, label, data in IDENTITY_DUMP:
        out.append((t0, _line(dev, head, 1, adr, label, data, t0)))
    first, second = (1, 2) if up else (2, 1)
    for k, pos in enumerate(AXLE_POSITIONS_M):
        t_on = t0 + dt.timedelta(seconds=pos / speed_mps)
        t_on2 = t_on + dt.timedelta(seconds=SPACING_M / speed_mps)
        t_off = t_on + dt.timedelta(seconds=DAMPING_ZONE_M / speed_mps)
        t_off2 = t_on2 + dt.timedelta(seconds=DAMPING_ZONE_M / speed_mps)
        out.append((t_on, _line(dev, head, first, "026", "Radsensor", "1", t_on)))
        out.append((t_on2, _line(dev, head, second, "026", "Radsensor", "1", t_on2)))
        out.append((t_off, _line(dev, head, first, "026", "Radsensor", "0", t_off)))
        out.append((t_off2, _line(dev, head, second, "026", "Radsensor", "0", t_off2)))
        out.append((t_off2, _line(dev, head, 1, "080", "Summenzä", str((sum_count + k + 1) % 256), t_off2)))
    out.sort(key=lambda r: r[0])
    return out


def generate(n_records: int, path: Path, seed: int = 1, encoding: str = "utf-8") -> int:
    """Write about n_records records to path; returns the number written."""
    rng = random.Random(seed)
    heads = [(4081, "WS1"), (4082, "WS2"), (4083, "WS3"), (4084, "WS4")]
    t = dt.datetime(2015, 10, 31, 5, 0, 0)
    written = 0
    sums = {h: 0 for _, h in heads}
    with path.open("w", encoding=encoding, newline="\n") as f:
        while written < n_records:
            speed = rng.uniform(3.0, 16.0)
            up = rng.random() < 0.5
            order = heads if up else heads[::-1]
            tt = t
            batch: list[tuple[dt.datetime, str]] = []
            for dev, head in order:
                batch.extend(passage_lines(dev, head, tt, speed, up, sums[head]))
                sums[head] += len(AXLE_POSITIONS_M)
                tt += dt.timedelta(seconds=400.0 / speed)
            batch.sort(key=lambda r: r[0])
            f.write("\n".join(line for _, line in batch))
            f.write("\n")
            written += len(batch)
            t += dt.timedelta(seconds=rng.uniform(240, 900))
    return written


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("records", type=int)
    ap.add_argument("path", type=Path)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--encoding", default="utf-8")
    args = ap.parse_args()
    n = generate(args.records, args.path, args.seed, args.encoding)
    print(f"wrote {n} records to {args.path} ({args.path.stat().st_size / 1e6:.0f} MB)")


if __name__ == "__main__":
    main()
