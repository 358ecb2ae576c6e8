"""Peak memory and time of projecting GNSS fixes onto a long track polyline.

"Real data first" §3: projecting 34 k fixes onto a 4,397-segment track used
6 GB (a dense fixes × segments array).  Target: a day of 1 Hz fixes (86,400)
onto a 10,000-point polyline in under 200 MB, the same chainage within 1 mm.

    python benchmarks/bench_projection.py [--fixes 86400] [--points 10000] [--impl tree|dense]

Each run is one process: peak RSS (ru_maxrss) is the process's own.  The
``dense`` implementation is the former one (every fix against every
segment at once); run it with few fixes, its memory grows with their product.
"""

from __future__ import annotations

import argparse
import math
import resource
import time

import numpy as np

from console.analysis.geo import Projection, TrackProjector
from console.layout import TrackPoint


def winding_track(points: int, seed: int = 0) -> list[TrackPoint]:
    """A line of ``points`` vertices 10 m apart, curving gently (radius ≥ 500 m), near 20.7° N."""
    rng = np.random.default_rng(seed)
    heading = np.cumsum(rng.normal(0, 10 / 500 / 2, points))  # ≤ about 1/500 rad per metre
    x = np.concatenate([[0.0], np.cumsum(10 * np.sin(heading[1:]))])
    y = np.concatenate([[0.0], np.cumsum(10 * np.cos(heading[1:]))])
    m_lat, m_lon = 110_740.0, 104_140.0
    return [TrackPoint(10.0 * i, 20.7 + y[i] / m_lat, 105.9 + x[i] / m_lon) for i in range(points)]


def dense_project(proj: TrackProjector, lat: np.ndarray, lon: np.ndarray) -> Projection:
    """The former implementation, verbatim in substance: fixes × segments arrays at once."""
    px, py = proj._plane(lat, lon)
    ax, ay = proj.x[:-1], proj.y[:-1]
    dx, dy = np.diff(proj.x), np.diff(proj.y)
    seg_len2 = dx * dx + dy * dy
    t = ((px[:, None] - ax) * dx + (py[:, None] - ay) * dy) / seg_len2
    lo = np.zeros_like(seg_len2)
    hi = np.ones_like(seg_len2)
    lo[0], hi[-1] = -np.inf, np.inf
    t = np.clip(t, lo, hi)
    qx, qy = ax + t * dx, ay + t * dy
    dist2 = (px[:, None] - qx) ** 2 + (py[:, None] - qy) ** 2
    best = np.argmin(dist2, axis=1)
    rows = np.arange(len(px))
    tb = t[rows, best]
    ch = proj.chainage[best] + tb * (proj.chainage[best + 1] - proj.chainage[best])
    return Projection(ch, np.sqrt(dist2[rows, best]))


def fixes_along(proj: TrackProjector, n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``n`` fixes at random chainages (a train's day, shuffled), 5 m noise each way."""
    rng = np.random.default_rng(seed)
    ch = rng.uniform(proj.chainage[0] - 200, proj.chainage[-1] + 200, n)
    lat, lon = proj.position(ch)
    return lat + rng.normal(0, 5, n) / proj.m_per_deg_lat, lon + rng.normal(0, 5, n) / proj.m_per_deg_lon


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--fixes", type=int, default=86_400)
    ap.add_argument("--points", type=int, default=10_000)
    ap.add_argument("--impl", choices=("tree", "dense"), default="tree")
    args = ap.parse_args()
    proj = TrackProjector(winding_track(args.points))
    lat, lon = fixes_along(proj, args.fixes)
    base_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0 = time.perf_counter()
    p = proj.project(lat, lon) if args.impl == "tree" else dense_project(proj, lat, lon)
    wall = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    assert not np.isnan(p.chainage_m).any() and math.isfinite(float(p.offset_m.max()))
    print(
        f"{args.impl}: {args.fixes:,} fixes onto {args.points:,} points: {wall:.2f} s, "
        f"peak RSS {peak_mb:.0f} MB (before projecting {base_mb:.0f} MB), max offset {p.offset_m.max():.1f} m"
    )


if __name__ == "__main__":
    main()
