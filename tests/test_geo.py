"""console.analysis.geo: exact distance, the paper's haversine, along-track chainage."""

from __future__ import annotations

import math

import numpy as np
import pytest

from console.analysis.geo import TrackProjector, geodesic_m, haversine_m
from console.layout import TrackPoint, load_layout


def test_geodesic_matches_a_known_distance() -> None:
    # One degree of latitude at the equator on WGS 84: 110 574.39 m.
    assert geodesic_m(0, 0, 1, 0) == pytest.approx(110_574.389, abs=0.01)


def test_haversine_errs_by_up_to_about_0_4_percent_at_21_n() -> None:
    # FORMATS.md §5: the spherical formula errs by about 0.4 % at 21° N (it depends on the bearing).
    errs = []
    for bearing_deg in range(0, 180, 15):
        b = math.radians(bearing_deg)
        lat2, lon2 = 21.0 + 0.01 * math.cos(b), 105.9 + 0.01 * math.sin(b)
        exact = geodesic_m(21.0, 105.9, lat2, lon2)
        errs.append(abs(haversine_m(21.0, 105.9, lat2, lon2) - exact) / exact)
    assert 0.003 < max(errs) < 0.0045
    assert min(errs) < 0.002


def test_straight_line_shortens_a_curve_by_16_percent() -> None:
    # A 1 km arc of 500 m radius (FORMATS.md §5): the chord is 2·500·sin(1 rad) = 841 m.
    lat0, lon0, r = 20.73, 105.90, 500.0
    m_lat = geodesic_m(lat0 - 0.0005, lon0, lat0 + 0.0005, lon0) / 0.001
    m_lon = geodesic_m(lat0, lon0 - 0.0005, lat0, lon0 + 0.0005) / 0.001
    angles = np.linspace(0, 2.0, 101)  # 1000 m of arc
    pts = [
        TrackPoint(float(r * a), lat0 + r * math.sin(a) / m_lat, lon0 + r * (1 - math.cos(a)) / m_lon) for a in angles
    ]
    proj = TrackProjector(pts)
    end = proj.project(pts[-1].lat, pts[-1].lon).chainage_m[0]
    chord = geodesic_m(pts[0].lat, pts[0].lon, pts[-1].lat, pts[-1].lon)
    assert end == pytest.approx(1000.0, abs=0.5)
    assert 1 - chord / end == pytest.approx(0.159, abs=0.002)


def test_projection_round_trip_on_the_example_track() -> None:
    lay = load_layout("example")
    proj = TrackProjector(lay.track)
    ch = np.linspace(10_000, 14_200, 50)
    lat, lon = proj.position(ch)
    back = proj.project(lat, lon)
    assert np.abs(back.chainage_m - ch).max() < 0.05
    assert back.offset_m.max() < 0.05


def test_chainage_runs_on_beyond_the_ends_of_the_track() -> None:
    lay = load_layout("example")
    proj = TrackProjector(lay.track)
    lat, lon = proj.position(np.array([9_000.0, 15_000.0]))
    assert proj.project(lat, lon).chainage_m == pytest.approx([9_000.0, 15_000.0], abs=0.05)


def test_a_fix_beside_the_track_projects_with_its_offset() -> None:
    lay = load_layout("example")
    proj = TrackProjector(lay.track)
    lat, lon = proj.position(11_850.0)
    p = proj.project(lat + 30 / proj.m_per_deg_lat, lon)  # 30 m north of the crossing
    assert p.offset_m[0] == pytest.approx(30 * abs(math.sin(math.radians(proj.bearing_deg(11_850.0)))), abs=1.0)


def _former_project(proj: TrackProjector, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The projection as it was before the search tree: every fix against every segment."""
    from benchmarks.bench_projection import dense_project

    p = dense_project(proj, lat, lon)
    return p.chainage_m, p.offset_m


@pytest.mark.parametrize("track", ["example", "winding"])
def test_the_tree_projects_as_the_former_dense_method_within_a_millimetre(track: str) -> None:
    from benchmarks.bench_projection import winding_track

    points = load_layout("example").track if track == "example" else winding_track(2_000, seed=3)
    proj = TrackProjector(points)
    rng = np.random.default_rng(7)
    n = 3_000
    # On the line, beside it (up to 500 m), and beyond both ends.
    ch = rng.uniform(proj.chainage[0] - 1_000, proj.chainage[-1] + 1_000, n)
    lat, lon = proj.position(ch)
    lat = lat + rng.normal(0, 150, n) / proj.m_per_deg_lat
    lon = lon + rng.normal(0, 150, n) / proj.m_per_deg_lon
    got = proj.project(lat, lon)
    want_ch, want_off = _former_project(proj, lat, lon)
    assert np.abs(got.offset_m - want_off).max() < 1e-3
    assert np.abs(got.chainage_m - want_ch).max() < 1e-3


def test_projection_memory_is_bounded_for_a_day_of_fixes() -> None:
    # 86,400 fixes onto a 10,000-point line: the former method needed fixes × segments
    # arrays (about 33 GB); the tree needs a few MB beyond the inputs (bench_projection.py).
    import resource

    from benchmarks.bench_projection import fixes_along, winding_track

    proj = TrackProjector(winding_track(10_000))
    lat, lon = fixes_along(proj, 86_400)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    p = proj.project(lat, lon)
    grown_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - before
    assert not np.isnan(p.chainage_m).any()
    assert grown_mb < 150
