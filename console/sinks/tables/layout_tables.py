"""Rich tables for `trackside layout`: the line as the analyses read it, then the checks' findings.

Every name comes from a file someone wrote by hand: it is shown as data (``inert``), never as markup.
"""

from __future__ import annotations

from rich import box
from rich.console import RenderableType
from rich.table import Table
from rich.text import Text

from console.analysis.layout_checks import WARNING, LayoutFinding, crossing_places, section_spans
from console.layout import Layout, format_kilometre_post
from console.plural import count
from console.safe_text import inert


def _table(title: str, *columns: tuple[str, bool]) -> Table:
    """A table whose columns keep their cells on one line but the last, which wraps (names, lists)."""
    t = Table(title=title, title_justify="left", title_style="bold", box=box.SIMPLE_HEAD, pad_edge=False)
    for i, (name, right) in enumerate(columns):
        last = i == len(columns) - 1
        t.add_column(name, justify="right" if right else "left", no_wrap=not last)
    return t


def _m(x: float) -> str:
    return f"{x:,.0f}" if x == round(x) else f"{x:,.1f}"


def _names(ids: tuple[str, ...] | list[str]) -> Text:
    return inert(", ".join(ids)) if ids else Text("–")


def layout_view(lay: Layout, findings: list[LayoutFinding]) -> list[RenderableType]:
    out: list[RenderableType] = []
    speed = lay.line_speed_mps
    out.append(inert(f"{lay.name}, from {lay.source}", style="bold"))
    head = f"Line speed {speed:g} m/s ({speed * 3.6:.0f} km/h); up is increasing chainage"
    if len(lay.track) >= 2:
        head += (
            f"; track {format_kilometre_post(lay.track[0].chainage_m)} to "
            f"{format_kilometre_post(lay.track[-1].chainage_m)} ({count(len(lay.track), 'point')})"
        )
    else:
        head += "; no [[track]] polyline"
    out.append(inert(head))

    t = _table(
        f"Counting heads ({len(lay.heads)}), in chainage order, with what an up train does at each",
        ("Head", False),
        ("km", True),
        ("Spacing m", True),
        ("Ch", True),
        ("Up order", False),
        ("Device", True),
        ("Sections", False),
    )
    for h in sorted(lay.heads, key=lambda h: h.chainage_m):
        roles = [f"{'enters' if sign > 0 else 'leaves'} {s.id}" for s, sign in lay.sections_of(h.id)]
        t.add_row(
            inert(h.id),
            format_kilometre_post(h.chainage_m),
            f"{h.spacing_m:g}",
            str(h.channels),
            h.up,
            "–" if h.device_id is None else str(h.device_id),
            _names(roles),
        )
    out.append(t)

    if lay.sections:
        t = _table(
            f"Sections ({len(lay.sections)}): the heads an up train enters and leaves by; lengths in m",
            ("Section", False),
            ("Enter", False),
            ("Leave", False),
            ("From", True),
            ("To", True),
            ("Length", True),
            ("Crossings", False),
            ("Name", False),
        )
        for sp in section_spans(lay):
            t.add_row(
                inert(sp.section.id),
                _names(sp.enter),
                _names(sp.leave),
                format_kilometre_post(sp.from_m),
                format_kilometre_post(sp.to_m),
                _m(sp.to_m - sp.from_m),
                _names(sp.crossings),
                inert(sp.section.name or "–"),
            )
        out.append(t)

    if lay.crossings:
        t = _table(
            f"Level crossings ({len(lay.crossings)}): where the chainage and the lat/lon put each; off the track in m",
            ("Crossing", False),
            ("km", True),
            ("Warn s", True),
            ("Clear m", True),
            ("Section", False),
            ("lat/lon at", True),
            ("Off m", True),
            ("Name", False),
        )
        for p in crossing_places(lay):
            c = p.crossing
            t.add_row(
                inert(c.code),
                format_kilometre_post(c.chainage_m),
                f"{c.warning_time_s:g}",
                f"{c.d_off_m:g}",
                inert(p.section or "–"),
                "–" if p.track_chainage_m is None else format_kilometre_post(p.track_chainage_m),
                "–" if p.track_offset_m is None else f"{p.track_offset_m:,.1f}",
                inert(c.name or "–"),
            )
        out.append(t)

    if lay.consists:
        t = _table(
            f"Consists ({len(lay.consists)})", ("Consist", False), ("Axles", True), ("Length m", True), ("Name", False)
        )
        for k in lay.consists:
            t.add_row(inert(k.id), str(len(k.axles_m)), f"{k.length_m:g}", inert(k.name or "–"))
        out.append(t)

    extras = []
    if lay.speed_limits:
        limits = ", ".join(f"{_m(s.from_m)}–{_m(s.to_m)} m: {s.limit_mps:g} m/s" for s in lay.speed_limits)
        extras.append(f"Speed limits: {limits}")
    if lay.platforms:
        extras.append("Platforms: " + ", ".join(f"{p.station} {_m(p.from_m)}–{_m(p.to_m)} m" for p in lay.platforms))
    if lay.work_sites:
        sites = ", ".join(f"{w.id} {w.distance_m:+g} m from {w.head}" for w in lay.work_sites)
        extras.append(f"Work sites: {sites}")
    devices = {
        "power gap": lay.power_gap_s,
        "GNSS report period": lay.gnss_report_period_s,
        "GNSS latency": lay.gnss_latency_s,
    }
    said = [f"{k} {v:g} s" for k, v in devices.items() if v is not None]
    if said:
        extras.append("Devices: " + ", ".join(said))
    out += [inert(line) for line in extras]

    for f in findings:
        out.append(inert(f"{f.level:<8} {f.message}", style="yellow" if f.level == WARNING else ""))
    warnings = sum(1 for f in findings if f.level == WARNING)
    notes = len(findings) - warnings
    if warnings:
        verdict = f"{count(warnings, 'warning')}" + (f", {count(notes, 'note')}" if notes else "")
    else:
        verdict = "checked: no warning" + (f", {count(notes, 'note')}" if notes else "")
    out.append(Text(verdict, style="bold yellow" if warnings else "bold green"))
    return out
