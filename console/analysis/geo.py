"""Geodesy for the line: exact distances, the paper's haversine, chainage.

* :func:`geodesic_m` — the WGS 84 ellipsoidal distance (geographiclib, exact
  to nanometres): the reference.
* :func:`haversine_m` — seed 004's formula (4)/(5) on a sphere of the mean
  Earth radius, shown beside it.  The paper prints the second term with
  latitudes where it needs the longitude difference; this is the intended
  formula.  At 21° N it errs by up to about 0.4 % (tested).
* :class:`TrackProjector` — projects fixes onto the layout's polyline and
  returns the *along-track chainage* and the cross-track offset.  A straight
  line from the train to the crossing shortens the distance along a curve
  (16 % on a 1 km arc of 500 m radius); the chainage difference is the
  distance the train must really run.  The nearest segment of each fix
  comes from a shapely STRtree, so memory grows with fixes + segments, not
  their product (34 k fixes onto 4,397 segments took 6 GB as a dense
  fixes × segments array; benchmarks/bench_projection.py measures it).
* Kilometre posts: ``11+850`` ↔ 11850 m (:func:`parse_kilometre_post`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from geographiclib.geodesic import Geodesic

from console.layout import TrackPoint

MEAN_EARTH_RADIUS_M = 6_371_008.8  # IUGG mean radius, the usual haversine R
# The end segments run on this far beyond the mapped line in the search tree (the
# projection itself extends them without limit): fixes further out are off the map.
END_EXTENSION_M = 200_000.0

__all__ = ["MEAN_EARTH_RADIUS_M", "Projection", "TrackProjector", "geodesic_m", "haversine_m"]


def geodesic_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Exact WGS 84 distance in metres (Karney's algorithm)."""
    return float(Geodesic.WGS84.Inverse(lat1, lon1, lat2, lon2, Geodesic.DISTANCE)["s12"])


def haversine_m(lat1: float, lon1: float, lat2: float, lon2: float, radius_m: float = MEAN_EARTH_RADIUS_M) -> float:
    """Great-circle distance on a sphere (seed 004, eq. 4-5, misprint corrected)."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    a = math.sin(dp / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2) ** 2
    return 2 * radius_m * math.asin(math.sqrt(min(1.0, a)))


@dataclass(frozen=True)
class Projection:
    chainage_m: np.ndarray  # along the track, in the layout's chainage
    offset_m: np.ndarray  # distance from the track (cross-track)


class TrackProjector:
    """Project positions onto a polyline of (chainage, lat, lon) points.

    Positions go to a local east/north plane around the line (metres, from
    geographiclib's local radii of curvature at the line's mean latitude);
    over a line of tens of kilometres that plane's distortion is far below
    GNSS noise.  A fix projects onto its nearest segment; its chainage is
    interpolated in the layout's own chainage, so projected positions and
    layout objects (heads, crossings) share one scale.
    """

    def __init__(self, track: Sequence[TrackPoint]) -> None:
        if len(track) < 2:
            raise ValueError("a track needs at least two points to project onto")
        lat = np.array([p.lat for p in track])
        lon = np.array([p.lon for p in track])
        self.chainage = np.array([p.chainage_m for p in track], dtype=float)
        self.lat0, self.lon0 = float(lat.mean()), float(lon.mean())
        # Metres per degree at the line's latitude, from the WGS 84 ellipsoid.
        step = 1e-3
        self.m_per_deg_lat = geodesic_m(self.lat0 - step / 2, self.lon0, self.lat0 + step / 2, self.lon0) / step
        self.m_per_deg_lon = geodesic_m(self.lat0, self.lon0 - step / 2, self.lat0, self.lon0 + step / 2) / step
        self.x, self.y = self._plane(lat, lon)
        self._tree: shapely.STRtree | None = None

    def _segments_tree(self) -> shapely.STRtree:
        """The track's segments in a search tree; the end segments lengthened (built once)."""
        if self._tree is None:
            x0, y0, x1, y1 = self.x[:-1].copy(), self.y[:-1].copy(), self.x[1:].copy(), self.y[1:].copy()
            # Lengthen the first segment backwards and the last one forwards.
            for a, b, sign in ((1, 0, -1.0), (-2, -1, 1.0)):
                dx, dy = self.x[b] - self.x[a], self.y[b] - self.y[a]
                k = END_EXTENSION_M / max(math.hypot(dx, dy), 1e-9)
                if sign < 0:
                    x0[0], y0[0] = self.x[0] + k * dx, self.y[0] + k * dy
                else:
                    x1[-1], y1[-1] = self.x[-1] + k * dx, self.y[-1] + k * dy
            coords = np.stack([np.stack([x0, y0], axis=1), np.stack([x1, y1], axis=1)], axis=1)
            self._tree = shapely.STRtree(shapely.linestrings(coords))
        return self._tree

    def _plane(self, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(lon) - self.lon0) * self.m_per_deg_lon, (np.asarray(lat) - self.lat0) * self.m_per_deg_lat

    def _on_segments(self, px: np.ndarray, py: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(chainage, squared distance) of points on given segments, one segment per point."""
        ax, ay = self.x[seg], self.y[seg]
        dx, dy = self.x[seg + 1] - ax, self.y[seg + 1] - ay
        t = ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)
        # Beyond either end the line runs on along its end segment (a train
        # approaching from outside the mapped stretch still gets a chainage).
        last = len(self.x) - 2
        t = np.clip(t, np.where(seg == 0, -np.inf, 0.0), np.where(seg == last, np.inf, 1.0))
        dist2 = (px - (ax + t * dx)) ** 2 + (py - (ay + t * dy)) ** 2
        ch = self.chainage[seg] + t * (self.chainage[seg + 1] - self.chainage[seg])
        return ch, dist2

    def project(self, lat: np.ndarray | float, lon: np.ndarray | float) -> Projection:
        """Chainage and cross-track offset of each position, on its nearest segment.

        The tree proposes the nearest segment(s) of every point (all of them on a tie);
        the distance is then measured as the dense method measures it and, among tied
        candidates, the lowest segment wins, as ``argmin`` chose before."""
        px, py = self._plane(np.atleast_1d(lat).astype(float), np.atleast_1d(lon).astype(float))
        n = len(px)
        if n == 0:
            return Projection(np.zeros(0), np.zeros(0))
        pts, segs = self._segments_tree().query_nearest(shapely.points(px, py), all_matches=True)
        ch, dist2 = self._on_segments(px[pts], py[pts], segs)
        # One candidate per point: the smallest distance, then the lowest segment.
        order = np.lexsort((segs, dist2, pts))
        first = np.ones(len(order), dtype=bool)
        first[1:] = pts[order][1:] != pts[order][:-1]
        pick = order[first]
        out_ch, out_d2 = np.full(n, np.nan), np.full(n, np.nan)
        out_ch[pts[pick]], out_d2[pts[pick]] = ch[pick], dist2[pick]
        return Projection(out_ch, np.sqrt(out_d2))

    def position(self, chainage_m: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(lat, lon) of points at the given chainages, on the polyline."""
        ch = np.atleast_1d(chainage_m).astype(float)
        i = np.clip(np.searchsorted(self.chainage, ch) - 1, 0, len(self.chainage) - 2)
        f = (ch - self.chainage[i]) / (self.chainage[i + 1] - self.chainage[i])  # may run past 0..1 at the ends
        x = self.x[i] + f * (self.x[i + 1] - self.x[i])
        y = self.y[i] + f * (self.y[i + 1] - self.y[i])
        return self.lat0 + y / self.m_per_deg_lat, self.lon0 + x / self.m_per_deg_lon

    def bearing_deg(self, chainage_m: float) -> float:
        """Direction of increasing chainage at a point, degrees from north."""
        i = int(np.clip(np.searchsorted(self.chainage, chainage_m) - 1, 0, len(self.chainage) - 2))
        return math.degrees(math.atan2(self.x[i + 1] - self.x[i], self.y[i + 1] - self.y[i])) % 360.0
