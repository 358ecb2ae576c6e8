"""Memory a live unit costs: N units heard once each (one fix near a crossing of the example layout), through the
engine's fix stage (the crossing units and the integrity monitor), measured with tracemalloc.

    python benchmarks/bench_units_memory.py 2000

Stop 45: about 40 KB a unit (the review's figure: 1.8 GB at 40,000 units); a deque is 600 B however few items it
keeps, and each train kept two dozen.
"""

from __future__ import annotations

import argparse
import gc
import resource
import time
import tracemalloc

from console.analysis.geo import TrackProjector
from console.cli.common import load_layout
from console.engine.fixes import FixStage
from console.inputs.base import GnssFix

T0_NS = 1_800_000_000 * 10**9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("units", type=int, nargs="?", default=2000)
    ap.add_argument("--top", type=int, default=8, help="the lines that allocate most, per unit")
    ap.add_argument("--rss", action="store_true", help="no tracemalloc (it doubles the memory): time and peak RSS")
    args = ap.parse_args()
    lay = load_layout("example")
    lat, lon = TrackProjector(lay.track).position(11_700.0)
    stage = FixStage(lay, lambda e: None)

    def fix(i: int, name: str) -> None:
        t = T0_NS + i * 10**6
        stage.take(GnssFix("gpsd://bench", name, t, float(lat[0]), float(lon[0]), 10.0, 150.0, 0.0), t + 10**8)

    fix(0, "warm-up")  # the modules' and the stage's own memory, before counting
    gc.collect()
    if args.rss:
        rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        t0 = time.perf_counter()
        for i in range(args.units):
            fix(i + 1, f"unit{i}")
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        print(
            f"{args.units:,} units: {time.perf_counter() - t0:.1f} s, peak RSS {rss / 1024:.0f} MB"
            f" ({(rss - rss0) / args.units:.1f} KB a unit over the warm-up's {rss0 / 1024:.0f} MB)"
        )
        return
    tracemalloc.start(1)
    before = tracemalloc.take_snapshot()
    for i in range(args.units):
        fix(i + 1, f"unit{i}")
    gc.collect()
    diff = tracemalloc.take_snapshot().compare_to(before, "lineno")
    total = sum(d.size_diff for d in diff)
    print(f"{args.units:,} units: {total / args.units / 1024:.1f} KB a unit ({total / 2**20:.1f} MB in all)")
    for d in diff[: args.top]:
        frame = d.traceback[0]
        print(f"  {d.size_diff / args.units:7.0f} B  {frame.filename.rsplit('/console/', 1)[-1]}:{frame.lineno}")


if __name__ == "__main__":
    main()
