"""How many updates a second the station view can draw, with 5 trains on the example line.

Issue 6's target: smooth at 10 or more updates a second.  One update is a
model tick (on a worker thread in the app) plus a redraw of every view (on
the UI thread); both are timed here, inside a real Textual app under Pilot.
"draw" waits for Textual to lay out and paint (``pilot.pause``), so it
includes Textual's own frame pacing; the CPU figure is what an update costs.

    python benchmarks/bench_station.py [--updates 200] [--size 100x30]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time

from console.layout import load_layout
from console.tui.app import TICK_S, StationApp
from console.tui.model import SPEEDS, StationModel
from console.tui.sources import SimSource


async def measure(updates: int, size: tuple[int, int], speed: int) -> None:
    model = StationModel(SimSource(load_layout("example"), seed=1))
    model.speed_index = SPEEDS.index(speed)
    app = StationApp(model, autoplay=False)
    async with app.run_test(size=size) as pilot:
        model.step(10)
        for _ in range(5):
            model.source.add_train()  # type: ignore[attr-defined]
        while len(model.source.trains()) < 5:  # let them all enter and report
            model.step(5)
        ticks, draws = [], []
        trains = []
        cpu0, wall0 = time.process_time(), time.perf_counter()
        for _ in range(updates):
            t0 = time.perf_counter()
            model.tick(TICK_S)
            t1 = time.perf_counter()
            app.refresh_views()
            await pilot.pause()  # let Textual lay out and paint
            t2 = time.perf_counter()
            ticks.append(t1 - t0)
            draws.append(t2 - t1)
            trains.append(len(model.source.trains()))
        cpu = (time.process_time() - cpu0) / updates
        wall = (time.perf_counter() - wall0) / updates
    per = [a + b for a, b in zip(ticks, draws, strict=True)]
    print(
        f"speed {speed:>4}×  trains {min(trains)}–{max(trains)}  "
        f"tick median {ms(statistics.median(ticks))} p95 {ms(p95(ticks))}  "
        f"draw median {ms(statistics.median(draws))} p95 {ms(p95(draws))}  "
        f"→ {1 / statistics.median(per):4.0f} updates/s wall (median); CPU {ms(cpu)} of {ms(wall)} per update"
    )


def ms(seconds: float) -> str:
    return f"{seconds * 1000:6.1f} ms"


def p95(values: list[float]) -> float:
    return sorted(values)[int(0.95 * len(values))]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--updates", type=int, default=200)
    ap.add_argument("--size", default="100x30")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))
    for speed in (5, 100, 1000):
        asyncio.run(measure(args.updates, (w, h), speed))


if __name__ == "__main__":
    main()
