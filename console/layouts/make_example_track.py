"""Print the example station's track polyline (run once; output pasted into example_station.toml).

A line heading south-south-east from 20.7500 N 105.9000 E: straight, a
right-hand curve of 1500 m radius between km 11.000 and km 11.700, straight
again.  Points every 100 m on the curve and 250 m elsewhere, positions by
the spherical destination formula (mean Earth radius); the chainage is the
distance along the line.
"""

from __future__ import annotations

import math

R_EARTH_M = 6_371_008.8


def destination(lat: float, lon: float, bearing_deg: float, dist_m: float) -> tuple[float, float]:
    p1, l1, b = math.radians(lat), math.radians(lon), math.radians(bearing_deg)
    d = dist_m / R_EARTH_M
    p2 = math.asin(math.sin(p1) * math.cos(d) + math.cos(p1) * math.sin(d) * math.cos(b))
    l2 = l1 + math.atan2(math.sin(b) * math.sin(d) * math.cos(p1), math.cos(d) - math.sin(p1) * math.sin(p2))
    return math.degrees(p2), math.degrees(l2)


def main() -> None:
    lat, lon, bearing = 20.7500, 105.9000, 165.0
    chainage, end = 10_000.0, 14_200.0
    curve = (11_000.0, 11_700.0, 1_500.0)  # from, to, radius (right-hand)
    print(f"[[track]]\nchainage_m = {chainage:.0f}\nlat = {lat:.6f}\nlon = {lon:.6f}\n")
    while chainage < end:
        in_curve = curve[0] <= chainage < curve[1]
        step = 100.0 if in_curve else 250.0
        if in_curve:
            # Chord of the arc: bearing turns by step / R; the chord starts at half the turn.
            turn = math.degrees(step / curve[2])
            lat, lon = destination(lat, lon, bearing + turn / 2, 2 * curve[2] * math.sin(step / curve[2] / 2))
            bearing += turn
        else:
            lat, lon = destination(lat, lon, bearing, step)
        chainage += step
        print(f"[[track]]\nchainage_m = {chainage:.0f}\nlat = {lat:.6f}\nlon = {lon:.6f}\n")


if __name__ == "__main__":
    main()
