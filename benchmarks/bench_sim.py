"""How much faster than real time the station simulator runs headless.

Issue 5's target: at least 1000× real time on the example station with
6 trains an hour.

    python benchmarks/bench_sim.py [--hours 2] [--seeds 3]
"""

from __future__ import annotations

import argparse
import time

from console.layout import load_layout
from console.sim.line_values import SimConfig
from console.sim.station import StationSim


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--hours", type=float, default=2.0)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--trains-per-hour", type=float, default=6.0)
    args = ap.parse_args()
    layout = load_layout("example")
    seconds = args.hours * 3600
    for seed in range(1, args.seeds + 1):
        sim = StationSim(layout, SimConfig(seed=seed, trains_per_hour=args.trains_per_hour))
        t0 = time.perf_counter()
        sim.run(seconds)
        wall = time.perf_counter() - t0
        print(
            f"seed {seed}: {args.hours:g} h simulated in {wall:.2f} s = {seconds / wall:,.0f}× real time "
            f"({len(sim.trains)} trains, {len(sim.truth_axles)} axle passages, {len(sim.all_fixes)} GNSS fixes)"
        )


if __name__ == "__main__":
    main()
