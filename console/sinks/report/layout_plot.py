"""`trackside layout --plot`: the line drawn along its chainage.

Above, the schematic: the sections as bars between their heads (with the side an up train enters by), the
counting heads, the level crossings (where the chainage puts them, and where their coordinates do, when the
two differ), platforms and work sites. Below, the speed allowed along the line. matplotlib's own canvases
(no pyplot, no display); SVG keeps text as text and no date, so a layout gives the same bytes.
"""

from __future__ import annotations

import io
from itertools import pairwise

from console.analysis.layout_checks import (
    CROSSING_POSITION_TOLERANCE_M,
    SECTION_SIGN_CHECKS,
    LayoutFinding,
    crossing_places,
    section_spans,
)
from console.layout import Layout
from console.safe_text import clean

PLOT_SUFFIXES = (".png", ".svg")
_SECTION_COLOURS = ("#1f4e79", "#4f81bd")


def _speed_profile(lay: Layout, lo_m: float, hi_m: float) -> tuple[list[float], list[float]]:
    """Chainages and the speed allowed from each to the next (km/h), as a step line over [lo, hi]."""
    cuts = sorted({lo_m, hi_m, *(x for s in lay.speed_limits for x in (s.from_m, s.to_m) if lo_m < x < hi_m)})
    xs, ys = [], []
    for a, b in pairwise(cuts):
        mid = (a + b) / 2
        limits = [s.limit_mps for s in lay.speed_limits if s.from_m <= mid < s.to_m]
        xs.append(a)
        ys.append((min(limits) if limits else lay.line_speed_mps) * 3.6)
    xs.append(cuts[-1])
    ys.append(ys[-1] if ys else lay.line_speed_mps * 3.6)
    return xs, ys


def layout_plot(lay: Layout, findings: list[LayoutFinding], fmt: str) -> bytes:
    """The drawing as PNG or SVG bytes (``fmt``: "png" or "svg"); a section whose signs the checks doubt is
    labelled so."""
    from matplotlib import rc_context
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure

    spans = section_spans(lay)
    doubted = {f.subject for f in findings if f.check in SECTION_SIGN_CHECKS}
    places = crossing_places(lay)
    marks = [h.chainage_m for h in lay.heads] + [c.chainage_m for c in lay.crossings]
    marks += [x for p in lay.platforms for x in (p.from_m, p.to_m)]
    if len(lay.track) >= 2:
        marks += [lay.track[0].chainage_m, lay.track[-1].chainage_m]
    lo, hi = min(marks), max(marks)
    pad = max((hi - lo) * 0.04, 50.0)
    lo, hi = lo - pad, hi + pad
    km = 1e-3
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "trackside", "font.size": 8}):
        fig = Figure(figsize=(10.0, 4.2))
        (FigureCanvasSVG if fmt == "svg" else FigureCanvasAgg)(fig)
        ax, sp_ax = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1]})
        if len(lay.track) >= 2:
            ax.plot([lay.track[0].chainage_m * km, lay.track[-1].chainage_m * km], [0, 0], color="#444", lw=2)
        else:
            ax.axhline(0, color="#999", lw=1, ls=":")
        for i, sp in enumerate(spans):
            colour = _SECTION_COLOURS[i % 2]
            ax.plot([sp.from_m * km, sp.to_m * km], [1, 1], color=colour, lw=6, solid_capstyle="butt")
            label = clean(sp.section.id) + (" (check its signs)" if sp.section.id in doubted else "")
            ax.annotate(label, ((sp.from_m + sp.to_m) / 2 * km, 1.25), ha="center", fontsize=8, color=colour)
        for h in lay.heads:
            ax.plot([h.chainage_m * km] * 2, [-0.3, 1.1], color="#222", lw=1)
            ax.annotate(clean(h.id), (h.chainage_m * km, -0.6), ha="center", fontsize=7)
        for p in lay.platforms:
            ax.plot([p.from_m * km, p.to_m * km], [-1.2, -1.2], color="#8d6e63", lw=5, solid_capstyle="butt")
            ax.annotate(clean(p.station), ((p.from_m + p.to_m) / 2 * km, -1.6), ha="center", fontsize=7)
        for place in places:
            c = place.crossing
            ax.plot([c.chainage_m * km], [0], marker="X", ms=9, color="#b71c1c", ls="none")
            ax.annotate(clean(c.code), (c.chainage_m * km, 0.45), ha="center", fontsize=7, color="#b71c1c")
            at = place.track_chainage_m
            if at is not None and abs(at - c.chainage_m) > CROSSING_POSITION_TOLERANCE_M:
                # Where its lat/lon put it: a hollow mark, joined to the chainage's.
                ax.plot([at * km], [0], marker="X", ms=9, mfc="none", color="#b71c1c", ls="none")
                ax.annotate(
                    "",
                    (at * km, -0.15),
                    (c.chainage_m * km, -0.15),
                    arrowprops={"arrowstyle": "<-", "color": "#b71c1c"},
                )
        for w in lay.work_sites:
            x = (lay.head(w.head).chainage_m + w.distance_m) * km
            ax.plot([x], [-0.3], marker="^", ms=6, color="#ef6c00", ls="none")
            ax.annotate(clean(w.id), (x, -0.95), ha="center", fontsize=6, color="#ef6c00")
        ax.set_ylim(-2.0, 1.8)
        ax.set_yticks([])
        for side in ("left", "right", "top", "bottom"):
            ax.spines[side].set_visible(False)
        ax.tick_params(axis="x", bottom=False)
        ax.set_title(
            f"{clean(lay.name)}: sections, counting heads, crossings (x), platforms; up is to the right", loc="left"
        )
        xs, ys = _speed_profile(lay, lo, hi)
        sp_ax.step([x * km for x in xs], ys, where="post", color="#2e7d32", lw=1.2)
        sp_ax.set_ylabel("km/h")
        sp_ax.set_ylim(0, max(ys) * 1.2)
        sp_ax.set_xlabel("chainage, km")
        sp_ax.grid(True, lw=0.3, color="#d0d7de")
        sp_ax.set_xlim(lo * km, hi * km)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format=fmt, metadata={"Date": None} if fmt == "svg" else {"Software": None}, dpi=120)
    return buf.getvalue()
