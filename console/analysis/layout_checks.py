"""A layout read as the analyses will read it, and checked for what loading cannot refuse.

Loading (``console.layout``) refuses what no line can have. What is left here is what a line may have on
purpose but usually has by mistake, so each finding is a warning, never a refusal:
- a section whose signs contradict the chainage order of its heads (right only where the heads' chainages
  are of different lines, as on a branch), or whose bounds all carry one sign;
- a head or a crossing beyond the ends of the ``[[track]]`` polyline;
- a crossing whose coordinates and chainage put it in two places: the warning is timed from the chainage,
  while a person checks the coordinates on a map.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

from geographiclib.geodesic import Geodesic

from console.layout import Layout, LevelCrossing, Section, format_kilometre_post

# The crossing controller's GNSS noise allowance (ControllerSettings.noise_m): two statements of where a
# crossing is that differ by more than the margin its timing absorbs are a typo in one of them.
CROSSING_POSITION_TOLERANCE_M = 15.0
# A polyline's chord runs a little short of the curved track it stands for (a few per cent on a coarse curve);
# a segment whose coordinates and chainage disagree by more than this is a typo in one of them.
TRACK_SCALE_TOLERANCE = 0.10
TRACK_SCALE_MIN_M = 10.0

WARNING = "warning"
NOTE = "note"
SECTION_SIGN_CHECKS = ("section_signs", "section_one_way")


@dataclass(frozen=True)
class LayoutFinding:
    level: str  # WARNING or NOTE
    check: str  # a stable key, for scripts
    subject: str  # the head, section or crossing it is about
    message: str


@dataclass(frozen=True)
class SectionSpan:
    """A section's place on the line: what an up train enters it by and leaves it by, and its chainages."""

    section: Section
    enter: tuple[str, ...]  # heads of sign +1
    leave: tuple[str, ...]  # heads of sign −1
    from_m: float
    to_m: float
    crossings: tuple[str, ...]  # codes of the crossings between its ends


@dataclass(frozen=True)
class CrossingPlace:
    """Where a crossing's coordinates fall on the track, against its chainage (None: no track to say)."""

    crossing: LevelCrossing
    section: str | None  # the section it lies in, if any
    track_chainage_m: float | None  # the chainage its lat/lon projects to
    track_offset_m: float | None  # its lat/lon's distance from the track


def _km(chainage_m: float) -> str:
    return format_kilometre_post(chainage_m)


def section_spans(lay: Layout) -> list[SectionSpan]:
    out = []
    for s in lay.sections:
        at = [lay.head(b.head).chainage_m for b in s.bounds]
        lo, hi = min(at), max(at)
        inside = tuple(c.code for c in lay.crossings if lo <= c.chainage_m <= hi)
        enter = tuple(b.head for b in s.bounds if b.sign > 0)
        leave = tuple(b.head for b in s.bounds if b.sign < 0)
        out.append(SectionSpan(s, enter, leave, lo, hi, inside))
    return out


def crossing_places(lay: Layout) -> list[CrossingPlace]:
    spans = section_spans(lay)
    proj = None
    if len(lay.track) >= 2 and lay.crossings:
        # Here, not at the top: shapely costs every command that reads a layout its start-up.
        from console.analysis.geo import TrackProjector

        proj = TrackProjector(lay.track)
    out = []
    for c in lay.crossings:
        section = next((sp.section.id for sp in spans if sp.from_m <= c.chainage_m <= sp.to_m), None)
        if proj is None:
            out.append(CrossingPlace(c, section, None, None))
            continue
        p = proj.project(c.lat, c.lon)
        out.append(CrossingPlace(c, section, float(p.chainage_m[0]), float(p.offset_m[0])))
    return out


def check_layout(lay: Layout) -> list[LayoutFinding]:
    """Every finding, warnings first, each group in the layout's order."""
    found = [*_section_findings(lay), *_track_findings(lay), *_crossing_findings(lay)]
    used = {b.head for s in lay.sections for b in s.bounds} | {w.head for w in lay.work_sites}
    if lay.sections:  # a layout of heads alone (osong) means no sections: nothing to note
        found += [
            LayoutFinding(
                NOTE,
                "head_unused",
                h.id,
                f"head {h.id} bounds no section: its passages are analysed, no section counts them",
            )
            for h in lay.heads
            if h.id not in used
        ]
    return sorted(found, key=lambda f: f.level != WARNING)


def _section_findings(lay: Layout) -> list[LayoutFinding]:
    out = []
    for sp in section_spans(lay):
        sid = sp.section.id
        if len(sp.section.bounds) >= 2 and not (sp.enter and sp.leave):
            sign = "+1" if sp.enter else "-1"
            out.append(
                LayoutFinding(
                    WARNING,
                    "section_one_way",
                    sid,
                    f"section {sid}: every bound has sign {sign}, so a train through it is counted "
                    f"{'in' if sp.enter else 'out'} at both ends and the count never returns to zero; "
                    "the head at the low-chainage end should be +1, the other -1",
                )
            )
            continue
        for e in sp.enter:
            for leave in sp.leave:
                ce, cl = lay.head(e).chainage_m, lay.head(leave).chainage_m
                if ce > cl:
                    out.append(
                        LayoutFinding(
                            WARNING,
                            "section_signs",
                            sid,
                            f"section {sid}: an up train enters at {e} ({_km(ce)}) but leaves at {leave} ({_km(cl)}), "
                            "down the line from it: check the signs (+1 at the low-chainage end); right only where "
                            "the two heads' chainages are of different lines",
                        )
                    )
    return out


def _track_findings(lay: Layout) -> list[LayoutFinding]:
    if len(lay.track) < 2:
        return []
    low, high = _km(lay.track[0].chainage_m), _km(lay.track[-1].chainage_m)
    out = [
        LayoutFinding(
            WARNING,
            "head_off_track",
            h,
            f"head {h} ({_km(lay.head(h).chainage_m)}) lies beyond the track's ends ({low} to {high}): the simulator "
            "runs no train past it and GNSS fixes are not placed there",
        )
        for h in lay.heads_off_track()
    ]
    for i, (a, b) in enumerate(itertools.pairwise(lay.track)):
        by_chainage = b.chainage_m - a.chainage_m
        apart = float(Geodesic.WGS84.Inverse(a.lat, a.lon, b.lat, b.lon, Geodesic.DISTANCE)["s12"])
        if abs(apart - by_chainage) > max(TRACK_SCALE_MIN_M, TRACK_SCALE_TOLERANCE * by_chainage):
            out.append(
                LayoutFinding(
                    WARNING,
                    "track_scale",
                    f"track[{i}]",
                    f"track[{i}] to track[{i + 1}]: the chainage says {by_chainage:,.0f} m, the coordinates lie "
                    f"{apart:,.0f} m apart: one of them is mistyped, and fixes between are placed by the chainage",
                )
            )
    return out


def _crossing_findings(lay: Layout) -> list[LayoutFinding]:
    if not lay.crossings:
        return []
    if len(lay.track) < 2:
        return [
            LayoutFinding(
                WARNING,
                "crossing_no_track",
                c.code,
                f"crossing {c.code}: the layout has no [[track]] polyline, so GNSS fixes cannot be placed on the "
                "line and `trackside crossing` refuses it",
            )
            for c in lay.crossings
        ]
    out = []
    low, high = lay.track[0].chainage_m, lay.track[-1].chainage_m
    for place in crossing_places(lay):
        c = place.crossing
        if not low <= c.chainage_m <= high:
            out.append(
                LayoutFinding(
                    WARNING,
                    "crossing_off_track",
                    c.code,
                    f"crossing {c.code}: chainage {_km(c.chainage_m)} lies beyond the track's ends "
                    f"({_km(low)} to {_km(high)})",
                )
            )
            continue
        assert place.track_chainage_m is not None and place.track_offset_m is not None
        along = place.track_chainage_m - c.chainage_m
        if place.track_offset_m > CROSSING_POSITION_TOLERANCE_M or abs(along) > CROSSING_POSITION_TOLERANCE_M:
            out.append(
                LayoutFinding(
                    WARNING,
                    "crossing_position",
                    c.code,
                    f"crossing {c.code}: its lat/lon lies {place.track_offset_m:,.0f} m off the track at "
                    f"{_km(place.track_chainage_m)}, {abs(along):,.0f} m {'up' if along > 0 else 'down'} the line from "
                    f"its chainage {_km(c.chainage_m)} (more than {CROSSING_POSITION_TOLERANCE_M:g} m): one of them "
                    "is wrong, and the warning is timed from the chainage",
                )
            )
    return out


def layout_document(lay: Layout, findings: list[LayoutFinding]) -> dict[str, object]:
    """The layout as the analyses read it, with the checks' findings (``trackside.layout/1``)."""
    places = crossing_places(lay)
    return {
        "schema": "trackside.layout/1",
        "name": lay.name,
        "source": lay.source,
        "line_speed_mps": lay.line_speed_mps,
        "track": (
            {"from_m": lay.track[0].chainage_m, "to_m": lay.track[-1].chainage_m, "points": len(lay.track)}
            if len(lay.track) >= 2
            else None
        ),
        "heads": [
            {
                "id": h.id,
                "chainage_m": h.chainage_m,
                "spacing_m": h.spacing_m,
                "channels": h.channels,
                "up": h.up,
                "device_id": h.device_id,
                "analog_band": list(h.analog_band) if h.analog_band else None,
                "sections": [{"section": s.id, "sign": sign} for s, sign in lay.sections_of(h.id)],
            }
            for h in sorted(lay.heads, key=lambda h: h.chainage_m)
        ],
        "sections": [
            {
                "id": sp.section.id,
                "name": sp.section.name,
                "enter": list(sp.enter),
                "leave": list(sp.leave),
                "from_m": sp.from_m,
                "to_m": sp.to_m,
                "length_m": sp.to_m - sp.from_m,
                "crossings": list(sp.crossings),
            }
            for sp in section_spans(lay)
        ],
        "crossings": [
            {
                "code": p.crossing.code,
                "name": p.crossing.name,
                "chainage_m": p.crossing.chainage_m,
                "lat": p.crossing.lat,
                "lon": p.crossing.lon,
                "warning_time_s": p.crossing.warning_time_s,
                "d_off_m": p.crossing.d_off_m,
                "section": p.section,
                "track_chainage_m": p.track_chainage_m,
                "track_offset_m": p.track_offset_m,
            }
            for p in places
        ],
        "consists": [
            {"id": c.id, "name": c.name, "axles": len(c.axles_m), "length_m": c.length_m} for c in lay.consists
        ],
        "speed_limits": [{"from_m": s.from_m, "to_m": s.to_m, "limit_mps": s.limit_mps} for s in lay.speed_limits],
        "platforms": [{"station": p.station, "from_m": p.from_m, "to_m": p.to_m} for p in lay.platforms],
        "work_sites": [
            {"id": w.id, "head": w.head, "distance_m": w.distance_m, "warning_time_s": w.warning_time_s}
            for w in lay.work_sites
        ],
        "devices": {
            "power_gap_s": lay.power_gap_s,
            "gnss_report_period_s": lay.gnss_report_period_s,
            "gnss_latency_s": lay.gnss_latency_s,
        },
        "findings": [
            {"level": f.level, "check": f.check, "subject": f.subject, "message": f.message} for f in findings
        ],
    }
