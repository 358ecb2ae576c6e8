"""Write crossing_example.csv: head and EOT telemetry of two trains on the example layout.

Device streams (time, device, role, lat, lon, speed, course) as the units
send them, from the same simulator as the crossing tests, so the truth is
known (see README.md here).

    python sample_logs/make_crossing_sample.py
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

from console.analysis.crossing.values import ControllerSettings
from console.layout import load_layout
from console.sim.crossing_runs import RawFix, RunConditions, simulate
from parsers.units import NS

START = dt.datetime(2026, 1, 19, 17, 0, 0, tzinfo=dt.UTC)


def main() -> None:
    layout = load_layout("example")
    by_code = {c.code: c for c in layout.crossings}
    runs = [
        # A: 120 m freight up at 15 m/s past 11+850, a fix every 5 s, 3 m noise, 10 % loss.
        (
            "A",
            by_code["11+850"],
            RunConditions(
                period_s=5,
                noise_m=3,
                loss=0.1,
                scenario="through",
                speed_mps=15,
                direction=1,
                length_m=120,
                seed=11,
                run_past_m=2000,
            ),
            0,
        ),
        # B: 300 m train down past 12+940 that stops with its tail on the road, fixes every 10 s.
        (
            "B",
            by_code["12+940"],
            RunConditions(
                period_s=10,
                noise_m=4,
                loss=0.2,
                scenario="stop_on_crossing",
                speed_mps=12,
                direction=-1,
                length_m=300,
                seed=7,
                run_past_m=2000,
            ),
            900,
        ),
    ]
    lines = ["time,device,role,lat,lon,speed,course"]
    for name, crossing, cond, offset_s in runs:
        raw: list[RawFix] = []
        start = int(START.timestamp()) * NS + offset_s * NS
        simulate(layout, crossing, cond, ControllerSettings(), start_ns=start, raw=raw)
        for f in sorted(raw, key=lambda r: r.t_fix_ns):
            t = (
                dt.datetime.fromtimestamp(f.t_fix_ns / NS, dt.UTC)
                .isoformat(timespec="milliseconds")
                .replace("+00:00", "Z")
            )
            lines.append(f"{t},{name}-{f.role},{f.role},{f.lat:.7f},{f.lon:.7f},{f.speed_mps:.2f},{f.course_deg:.1f}")
    out = Path(__file__).with_name("crossing_example.csv")
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {len(lines) - 1} fixes to {out}")


if __name__ == "__main__":
    main()
