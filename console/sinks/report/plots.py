"""The HTML report's plots, drawn by matplotlib's SVG backend and inlined in the page.

No script, nothing fetched: each plot is one ``<svg>`` element (its XML
prologue, DOCTYPE and metadata dropped; ``xlink:href`` written as SVG 2's
``href``) that scales to the page width on screen and on A4 paper.  Text
stays text (``svg.fonttype = none``), with matplotlib's math parsing off,
and every label that may come from a log goes through
:func:`console.safe_text.clean` first (matplotlib escapes it for XML).

Time axes are real date axes (``AutoDateLocator`` with
``ConciseDateFormatter``): an hour reads as clock times, ten years as
years.  Data with long gaps (logs of 2015 and of 2026 in one report) is
drawn on broken axes: one panel per stretch of data, each with its own
date axis, so neither end is crammed (:func:`time_panels`).

Deterministic: the same inputs give the same bytes (no date in the
metadata, ``svg.hashsalt`` fixed, ids prefixed per figure so the plots of
one page never share one).  Bounded: a speed plot of more passages than
:data:`MAX_POINTS` shows each time bin's range and mean per head, a state
band of more changes than :data:`MAX_SEGMENTS` the worst state per time bin
(disturbed over occupied over preparatory over clear: never a section
shown clear when it was not), lines keep each bin's minimum and maximum.
Series differ by marker shape or dash as well as colour (Okabe–Ito), and
states by hatch and written mark, so a plot reads in black and white.
"""

from __future__ import annotations

import functools
import io
import itertools
import math
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, TypeVar, cast

import numpy as np

from console.safe_text import clean
from parsers.units import NS, NS_PER_DAY

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

WIDTH_IN = 10.0  # 720 pt: the page's width scales it (CSS), on screen and on A4
# Okabe–Ito: distinguishable with the common colour-vision deficiencies.
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
SHAPES = ("o", "s", "^", "D", "v", "X", "P")
DASHES: tuple[Any, ...] = ("-", "--", ":", "-.", (0, (4, 4)))
MAX_PANELS = 4
# A gap splits the time axis when it is this share of the whole span or more (and at least GAP_MIN_NS).
GAP_SHARE = 0.2
GAP_MIN_NS = 2 * 3600 * NS
# The plot is some 650 points wide: more marks than that only add bytes.  Past these, a reduction per time bin.
MAX_POINTS = 6000  # marks in a speed plot, all heads and panels: past it a head's bins show range and mean
MAX_SEGMENTS = 300  # state segments of one section in one panel: past it the worst state per bin
BINS = 300  # per panel, for the reductions above
_RC: dict[str, Any] = {
    "svg.fonttype": "none",
    "svg.hashsalt": "trackside",
    "svg.image_inline": True,
    "text.parse_math": False,  # '$GPRMC … $' in a label is text, not TeX
    "font.family": "sans-serif",
    "font.size": 10.0,
    "axes.titlesize": 11.0,
    "axes.edgecolor": "#444444",
    "axes.grid": True,
    "grid.color": "#e4e4e4",
    "timezone": "UTC",  # the logs' own times, as written: never the machine's zone
    "date.converter": "concise",
}


F = TypeVar("F", bound=Callable[..., str])


def styled(draw: F) -> F:
    """Draw inside matplotlib's defaults with this module's settings: a user's matplotlibrc changes nothing."""

    @functools.wraps(draw)
    def inside(*args: Any, **kwargs: Any) -> str:
        import matplotlib

        with matplotlib.rc_context():
            matplotlib.rcdefaults()
            matplotlib.rcParams.update(cast(Any, _RC))
            return draw(*args, **kwargs)

    return cast(F, inside)


def label(text: object) -> str:
    """Log text as a plot may show it: control, bidi and undecodable characters escaped."""
    return clean(text)


# ----------------------------------------------------------------------------- figure → inline SVG


_PROLOGUE = re.compile(r"\A.*?(?=<svg)", re.S)


def figure(height_in: float) -> Figure:
    from matplotlib.figure import Figure

    return Figure(figsize=(WIDTH_IN, height_in), dpi=72)


def to_svg(fig: Figure, title: str, prefix: str) -> str:
    """The figure as one inline ``<svg>`` element: a ``<title>``, ids prefixed, nothing that points outside."""
    import matplotlib
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    out = io.StringIO()
    with matplotlib.rc_context({"svg.hashsalt": f"trackside-{prefix}"}):
        FigureCanvasSVG(fig).print_svg(out, metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    text = _PROLOGUE.sub("", out.getvalue(), count=1)
    text = text.replace(' xmlns:xlink="http://www.w3.org/1999/xlink"', "", 1)
    text = text.replace('xlink:href="#', f'href="#{prefix}-').replace("url(#", f"url(#{prefix}-")
    text = text.replace(' id="', f' id="{prefix}-')
    from html import escape

    name = escape(label(title), quote=True)
    text = text.replace("<svg ", f'<svg role="img" aria-label="{name}" ', 1)
    text = text.replace(">", f"><title>{name}</title>", 1)
    return text.rstrip("\n")


def _legend(fig: Figure, handles: list[Any], labels: list[str], note: str = "", heading: str = "") -> None:
    """The legend in one row above the plot (under a heading, if any); a note on a line of its own below it."""
    height_in = fig.get_size_inches()[1]
    top = 1.0
    if heading:
        fig.text(0.07, 1 - 0.08 / height_in, label(heading), ha="left", va="top", fontsize=11, fontweight="bold")
        top = 1 - 0.26 / height_in
    if handles:
        fig.legend(
            handles, labels, loc="upper left", bbox_to_anchor=(0.07, top), ncol=min(len(handles), 8), frameon=False
        )
    if note:
        height_in = fig.get_size_inches()[1]
        fig.text(0.085, 1 - 0.36 / height_in, note, ha="left", va="top", fontsize=8.5, color="#444444")


# ----------------------------------------------------------------------------- time panels


class TimeSpread:
    """Where data lies in time, in bounded memory: per hour it occupies, the first and last instant."""

    def __init__(self) -> None:
        self.hours = np.zeros(0, np.int64)
        self.lo = np.zeros(0, np.int64)
        self.hi = np.zeros(0, np.int64)

    def add(self, t_ns: np.ndarray) -> None:
        t = np.asarray(t_ns, np.int64)
        if not len(t):
            return
        hours = np.concatenate([self.hours, t // (3600 * NS)])
        lo = np.concatenate([self.lo, t])
        hi = np.concatenate([self.hi, t])
        self.hours, inv = np.unique(hours, return_inverse=True)
        self.lo = np.full(len(self.hours), np.iinfo(np.int64).max)
        self.hi = np.full(len(self.hours), np.iinfo(np.int64).min)
        np.minimum.at(self.lo, inv, lo)
        np.maximum.at(self.hi, inv, hi)

    def panels(self) -> list[tuple[int, int]]:
        """The stretches of time to draw, each [first, last] ns: split at the widest long gaps."""
        if not len(self.hours):
            return []
        start, end = int(self.lo[0]), int(self.hi[-1])
        gaps = self.lo[1:] - self.hi[:-1]
        long = np.flatnonzero(gaps >= max(GAP_SHARE * (end - start), GAP_MIN_NS))
        cuts = sorted(long[np.argsort(-gaps[long], kind="stable")][: MAX_PANELS - 1].tolist())
        bounds = [0, *(c + 1 for c in cuts), len(self.hours)]
        return [(int(self.lo[a]), int(self.hi[b - 1])) for a, b in itertools.pairwise(bounds)]


def spread_of(*times: np.ndarray) -> TimeSpread:
    s = TimeSpread()
    for t in times:
        s.add(t)
    return s


def _padded(lo: int, hi: int) -> tuple[int, int]:
    """A panel's time range: the data and a margin, two minutes at least (a date axis needs ticks to place)."""
    if hi - lo < 120 * NS:
        mid = (lo + hi) // 2
        return mid - 60 * NS, mid + 60 * NS
    pad = (hi - lo) // 30
    return lo - pad, hi + pad


def _dates(t_ns: np.ndarray) -> np.ndarray:
    """ns since the epoch → matplotlib's date numbers (days since its epoch, 1970)."""
    return np.asarray(t_ns, np.float64) / NS_PER_DAY


def time_axes(fig: Figure, panels: Sequence[tuple[int, int]], rect: tuple[float, float, float, float]) -> list[Axes]:
    """One axes per panel side by side inside ``rect`` (left, bottom, width, height), a date axis each.

    Panels share the value axis; between two panels the axis is drawn broken (a pair of slashes).
    """
    import matplotlib.dates as mdates

    n = max(len(panels), 1)
    left, bottom, width, height = rect
    gap = 0.015 if n > 1 else 0.0
    w = (width - gap * (n - 1)) / n
    axes: list[Axes] = []
    for i, (lo, hi) in enumerate(panels or [(0, 60 * NS)]):
        ax = fig.add_axes((left + i * (w + gap), bottom, w, height), sharey=axes[0] if axes else None)
        a, b = _padded(lo, hi)
        ax.set_xlim(float(_dates(np.array([a]))[0]), float(_dates(np.array([b]))[0]))
        # One panel: minticks 3 (two years read in months, not as two year labels), maxticks 9; narrower
        # panels fewer labels.  Either way every span finds an interval (no "unable to pick" fallback).
        locator = (
            mdates.AutoDateLocator(minticks=3, maxticks=9) if n == 1 else mdates.AutoDateLocator(minticks=2, maxticks=5)
        )
        ax.xaxis.set_major_locator(locator)
        ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
        if i:
            ax.spines["left"].set_visible(False)
            ax.tick_params(axis="y", left=False, labelleft=False)
        if i < n - 1:
            ax.spines["right"].set_visible(False)
        axes.append(ax)
    for left_ax, right_ax in itertools.pairwise(axes):
        for ax, x in ((left_ax, 1.0), (right_ax, 0.0)):
            kw: dict[str, Any] = {"transform": ax.transAxes, "color": "#444444", "clip_on": False, "lw": 1.0}
            for y in (0.0, 1.0):
                ax.plot([x - 0.012, x + 0.012], [y - 0.03, y + 0.03], **kw)
    return axes


def _in(t: np.ndarray, panel: tuple[int, int]) -> np.ndarray:
    a, b = _padded(*panel)
    return (t >= a) & (t <= b)


# ----------------------------------------------------------------------------- speed per passage


@dataclass
class SpeedSeries:
    """One head's passages: start times (ns), whole-train speed and per-axle mean (NaN: none), read when drawn."""

    label: str
    load: Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]]


def _reduce(t: np.ndarray, v: np.ndarray, panel: tuple[int, int], bins: int) -> tuple[np.ndarray, ...]:
    """Per time bin of the panel: centre, minimum, maximum and mean of the values in it."""
    a, b = _padded(*panel)
    edges = np.linspace(a, b, bins + 1)
    k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, bins - 1)
    order = np.argsort(k, kind="stable")
    k, v = k[order], v[order]
    first = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    lo, hi = np.minimum.reduceat(v, first), np.maximum.reduceat(v, first)
    mean = np.add.reduceat(v, first) / np.diff(np.r_[first, len(v)])
    centre = (edges[k[first]] + edges[k[first] + 1]) / 2
    return centre, lo, hi, mean


@styled
def speed_plot(series: Sequence[SpeedSeries], spread: TimeSpread, top_kmh: float, title: str) -> str:
    """Whole-train speed (filled) and per-axle mean (ring) per passage, one shape and colour per head."""
    from matplotlib.lines import Line2D

    fig = figure(4.2)
    panels = spread.panels()
    axes = time_axes(fig, panels, (0.07, 0.14, 0.91, 0.69))
    axes[0].set_ylim(0.0, max(top_kmh, 1.0) * 1.08)
    axes[0].set_ylabel("km/h")
    handles, names = [], []
    reduced = False
    # Each head's share of the marks in each panel (two measures each); past it, its bins.
    allowed = MAX_POINTS // (2 * max(len(series), 1) * len(axes))
    bins = max(20, min(BINS, allowed // 2))
    for i, s in enumerate(series):
        colour, shape = PALETTE[i % len(PALETTE)], SHAPES[i % len(SHAPES)]
        t, whole, axle = s.load()
        for values, filled in ((whole, True), (axle, False)):
            ok = np.isfinite(values)
            tt, vv = np.asarray(t, np.int64)[ok], np.asarray(values, np.float64)[ok]
            style: dict[str, Any] = {
                "marker": shape,
                "linestyle": "none",
                "color": colour,
                "markersize": 6 if filled else 9,
                "markerfacecolor": colour if filled else "none",
                "markeredgewidth": 1.3,
            }
            for ax, panel in zip(axes, panels, strict=False):
                m = _in(tt, panel)
                if m.sum() > allowed:
                    reduced = True
                    centre, lo, hi, mean = _reduce(tt[m], vv[m], panel, bins)
                    x = _dates(centre)
                    ax.vlines(x, lo, hi, color=colour, linewidth=0.8, alpha=0.6)
                    ax.plot(x, mean, **{**style, "markersize": 4 if filled else 6})
                elif m.any():
                    ax.plot(_dates(tt[m]), vv[m], **style)
        handles.append(Line2D([], [], marker=shape, color=colour, linestyle="none", markersize=7))
        names.append(label(s.label))
        del t, whole, axle
    note = "filled: whole train · ring: per-axle mean"
    if reduced:
        note += " · dense: range and mean per time bin"
    _legend(fig, handles, names, note)
    fig.supxlabel("time (the logs' own)", fontsize=9, y=0.01)
    return to_svg(fig, title, "speeds")


# ----------------------------------------------------------------------------- lines over time


@dataclass(frozen=True)
class Line:
    label: str
    t_ns: np.ndarray
    values: np.ndarray


def thin(t: np.ndarray, v: np.ndarray, buckets: int = 500) -> tuple[np.ndarray, np.ndarray]:
    """At most about 2 × buckets points: each bucket's minimum and maximum, in time order (spikes stay)."""
    if len(t) <= 2 * buckets:
        return t, v
    edges = np.linspace(0, len(t), buckets + 1).astype(int)
    keep: list[int] = []
    for a, b in itertools.pairwise(edges.tolist()):
        if b > a:
            lo, hi = a + int(np.argmin(v[a:b])), a + int(np.argmax(v[a:b]))
            keep += sorted({lo, hi})
    idx = np.array(keep, dtype=np.int64)
    return t[idx], v[idx]


@styled
def lines_plot(lines: Sequence[Line], title: str, y_caption: str, band: tuple[float, float] | None, prefix: str) -> str:
    """One line per series (a dash and a colour each) over time, an optional shaded band."""
    from matplotlib.lines import Line2D

    fig = figure(3.4)
    panels = spread_of(*(ln.t_ns for ln in lines)).panels()
    axes = time_axes(fig, panels, (0.07, 0.16, 0.91, 0.6))
    axes[0].set_ylabel(y_caption)
    handles = []
    for i, ln in enumerate(lines):
        colour, dash = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)]
        for ax, panel in zip(axes, panels, strict=False):
            m = _in(ln.t_ns, panel)
            t, v = thin(ln.t_ns[m], ln.values[m])
            ax.plot(_dates(t), v, color=colour, linestyle=dash, linewidth=1.6, marker="o" if len(t) == 1 else "")
        handles.append(Line2D([], [], color=colour, linestyle=dash, linewidth=2))
    if band is not None:
        for ax in axes:
            ax.axhspan(band[0], band[1], color="#2e7d32", alpha=0.10, linestyle="--", edgecolor="#2e7d32")
    _legend(fig, handles, [label(ln.label) for ln in lines], heading=title)
    fig.supxlabel("time (the logs' own)", fontsize=9, y=0.01)
    return to_svg(fig, title, prefix)


# ----------------------------------------------------------------------------- state bands


@dataclass(frozen=True)
class StateStyle:
    fill: str
    ink: str  # text and hatch colour on this fill
    mark: str
    hatch: str  # matplotlib hatch: "", "//", "xx", ".."
    rank: int  # the worse state wins a time bin that holds several


@dataclass(frozen=True)
class Segment:
    t0_ns: int
    t1_ns: int
    state: str


@dataclass
class BandRow:
    label: str
    segments: Callable[[], Iterable[Segment]]  # each call reads the row afresh (a streamed history: from disk)


def _binned(segments: Iterable[Segment], panel: tuple[int, int], styles: dict[str, StateStyle]) -> list[Segment]:
    """The worst state in each time bin of the panel, runs of one state merged (memory: the bins)."""
    a, b = _padded(*panel)
    edges = np.linspace(a, b, BINS + 1)
    ranks = sorted({st.rank for st in styles.values()})
    cover = {r: np.zeros(BINS + 1, np.int64) for r in ranks}
    for chunk in _chunks(segments, 50_000):
        t0 = np.array([s.t0_ns for s in chunk], np.float64)
        t1 = np.array([s.t1_ns for s in chunk], np.float64)
        rank = np.array([styles[s.state].rank for s in chunk])
        keep = (t1 >= a) & (t0 <= b)
        i0 = np.clip(np.searchsorted(edges, t0[keep], side="right") - 1, 0, BINS - 1)
        i1 = np.clip(np.searchsorted(edges, t1[keep], side="left") - 1, 0, BINS - 1)
        i1 = np.maximum(i1, i0)
        for r in ranks:
            m = rank[keep] == r
            np.add.at(cover[r], i0[m], 1)
            np.add.at(cover[r], i1[m] + 1, -1)
    worst = np.full(BINS, -1)
    for r in ranks:
        worst = np.where(np.cumsum(cover[r])[:BINS] > 0, r, worst)
    by_rank = {st.rank: name for name, st in styles.items()}
    out: list[Segment] = []
    for k, run in itertools.groupby(range(BINS), key=lambda j: int(worst[j])):
        idx = list(run)
        if k >= 0:
            out.append(Segment(int(edges[idx[0]]), int(edges[idx[-1] + 1]), by_rank[k]))
    return out


def _chunks(items: Iterable[Segment], n: int) -> Iterator[list[Segment]]:
    it = iter(items)
    while chunk := list(itertools.islice(it, n)):
        yield chunk


def _row_segments(row: BandRow, panel: tuple[int, int], styles: dict[str, StateStyle]) -> tuple[list[Segment], bool]:
    """The row's segments within the panel: as they are, or binned past MAX_SEGMENTS (then True)."""
    a, b = _padded(*panel)
    it = iter(row.segments())
    first = [s for s in itertools.islice(it, MAX_SEGMENTS + 1) if s.t1_ns >= a and s.t0_ns <= b]
    if next(it, None) is None and len(first) <= MAX_SEGMENTS:
        return first, False
    return _binned(row.segments(), panel, styles), True


@styled
def state_plot(
    rows: Sequence[BandRow], spread: TimeSpread, end_ns: int, styles: dict[str, StateStyle], title: str
) -> str:
    """One band per section: each state from its change to the next, its mark written where it fits."""
    from matplotlib.patches import Patch

    height = 1.4 + 0.42 * max(len(rows), 1)
    fig = figure(height)
    spread.add(np.array([end_ns]))
    panels = spread.panels()
    bottom = 0.55 / height
    axes = time_axes(fig, panels, (0.09, bottom, 0.89, 1 - bottom - 0.75 / height))
    axes[0].set_ylim(len(rows) - 0.4, -0.6)
    axes[0].set_yticks(range(len(rows)), [label(r.label) for r in rows], fontweight="bold")
    binned = False
    for ax, panel in zip(axes, panels, strict=False):
        ax.grid(axis="y", visible=False)
        a, b = _padded(*panel)
        for y, row in enumerate(rows):
            segs, was_binned = _row_segments(row, panel, styles)
            binned |= was_binned
            for state, st in styles.items():  # one collection per state
                spans = [(max(s.t0_ns, a), min(max(s.t1_ns, s.t0_ns), b)) for s in segs if s.state == state]
                if not spans:
                    continue
                x = [(float(_dates(np.array([s]))[0]), float((e - s) / NS_PER_DAY)) for s, e in spans]
                edge = 0.0 if was_binned else 0.4  # bins: no outline (thin bins would read as black bars)
                ax.broken_barh(x, (y - 0.4, 0.8), facecolors=st.fill, edgecolors=st.ink, linewidth=edge, hatch=st.hatch)
            if len(segs) <= 60:  # a mark in each band wide enough for it
                points_per_ns = WIDTH_IN * 72 * ax.get_position().width / (b - a)
                for s in segs:
                    x0, x1 = max(s.t0_ns, a), min(s.t1_ns, b)
                    st = styles[s.state]
                    room = (x1 - x0) * points_per_ns  # the band's width in points; a character is about 6.5
                    name = f"{st.mark} {s.state}"
                    text = name if room > 6.5 * len(name) + 8 else st.mark if room > 12 else ""
                    if text:
                        mid = float(_dates(np.array([(x0 + x1) // 2]))[0])
                        ax.text(mid, y, text, ha="center", va="center", color=st.ink, fontweight="bold", fontsize=9)
    handles = [Patch(facecolor=st.fill, edgecolor=st.ink, hatch=st.hatch) for st in styles.values()]
    names = [f"{st.mark} {name}" for name, st in styles.items()]
    note = "many changes: the worst state of each time bin" if binned else ""
    _legend(fig, handles, names, note)
    fig.supxlabel("time (the logs' own)", fontsize=9, y=0.0)
    return to_svg(fig, title, "sections")


# ----------------------------------------------------------------------------- warning bars


@dataclass(frozen=True)
class WarningBar:
    """One crossing and train, in seconds relative to the head's arrival at the crossing."""

    label: str
    on_s: float | None
    off_s: float | None  # None: held on to the end of the data
    tail_s: float | None
    baseline_off_s: float | None
    required_s: float  # the warning time the crossing needs before the head arrives
    violation: bool


@styled
def warning_plot(bars: Sequence[WarningBar], title: str) -> str:
    """Per crossing and train: the warning from on to off, the head's arrival (0), the tail clearing."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    n = max(len(bars), 1)
    height = 1.3 + 0.24 * n
    fig = figure(height)
    bottom = 0.55 / height
    ax = fig.add_axes((0.2, bottom, 0.78, 1 - bottom - 0.5 / height))
    xs = [0.0]
    for b in bars:
        xs += [x for x in (b.on_s, b.off_s, b.tail_s, b.baseline_off_s, -b.required_s) if x is not None]
    lo, hi = min(xs), max(xs)
    pad = (hi - lo) * 0.04 or 1.0
    ax.set_xlim(lo - pad, hi + pad)
    ax.set_ylim(n - 0.4, -0.6)
    ax.grid(axis="y", visible=False)
    ax.axvline(0.0, color="#222222", linewidth=1.0)
    ax.set_yticks(range(len(bars)), [label(b.label) + ("  VIOLATION" if b.violation else "") for b in bars])
    for tick, b in zip(ax.get_yticklabels(), bars, strict=True):
        if b.violation:
            tick.set_color("#b71c1c")
            tick.set_fontweight("bold")
    for y, b in enumerate(bars):
        ax.plot([-b.required_s] * 2, [y - 0.45, y + 0.45], color="#555555", linestyle=":", linewidth=1.2)
        if b.on_s is not None:
            end = b.off_s if b.off_s is not None else hi + pad
            colour = "#c62828" if b.violation else "#E69F00"
            ax.barh(y, end - b.on_s, left=b.on_s, height=0.55, color=colour, alpha=0.85, edgecolor="#222222")
            if b.off_s is None:
                ax.text(end, y, "held on → ", ha="right", va="center", fontsize=8)
        ax.plot([0.0], [y], marker="v", color="#0072B2", markersize=7, linestyle="none")
        if b.tail_s is not None:
            ax.plot([b.tail_s], [y], marker="s", color="#009E73", markersize=6, linestyle="none")
        if b.baseline_off_s is not None:
            ax.plot([b.baseline_off_s], [y], marker="X", color="#CC79A7", markersize=7, linestyle="none")
    ax.set_xlabel("seconds relative to the head's arrival at the crossing")
    handles = [
        Patch(facecolor="#E69F00", alpha=0.85),
        Line2D([], [], marker="v", color="#0072B2", linestyle="none"),
        Line2D([], [], marker="s", color="#009E73", linestyle="none"),
        Line2D([], [], marker="X", color="#CC79A7", linestyle="none"),
        Line2D([], [], color="#555555", linestyle=":"),
    ]
    names = ["warning on → off", "head arrives", "tail clear", "baseline off", "required warning time"]
    _legend(fig, handles, names)
    return to_svg(fig, title, "crossings")


# ----------------------------------------------------------------------------- values per day


@dataclass(frozen=True)
class DaySeries:
    """One series of daily values: days as ``YYYY-MM-DD``, a value each (None: no value that day)."""

    label: str
    days: tuple[str, ...]
    values: tuple[float | None, ...]


@dataclass
class _Day:
    day: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # days since the epoch
    value: np.ndarray = field(default_factory=lambda: np.zeros(0))


@styled
def day_plot(series: Sequence[DaySeries], title: str, y_caption: str, prefix: str, zero_line: bool = False) -> str:
    """One line per series over whole days, a mark on each day's value; a day without a value breaks the line."""
    from matplotlib.lines import Line2D

    parsed = []
    for s in series:
        pairs = sorted((int(np.datetime64(d, "D").astype(np.int64)), v) for d, v in zip(s.days, s.values, strict=True))
        pts = [(d, float(v)) for d, v in pairs if v is not None and math.isfinite(float(v))]
        parsed.append(_Day(np.array([d for d, _ in pts], np.int64), np.array([v for _, v in pts], np.float64)))
    if not any(len(p.day) for p in parsed):
        return ""
    fig = figure(3.4)
    spread = spread_of(*(p.day * NS_PER_DAY for p in parsed))
    panels = [(lo - NS_PER_DAY // 2, hi + NS_PER_DAY // 2) for lo, hi in spread.panels()]
    axes = time_axes(fig, panels, (0.07, 0.16, 0.91, 0.6))
    axes[0].set_ylabel(y_caption)
    handles = []
    for i, (s, p) in enumerate(zip(series, parsed, strict=True)):
        colour, dash, shape = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)], SHAPES[i % len(SHAPES)]
        for ax, panel in zip(axes, panels, strict=False):
            m = _in(p.day * NS_PER_DAY, panel)
            d, v = p.day[m], p.value[m]
            # Consecutive days are joined; a day without a value breaks the line (NaN between runs).
            breaks = np.flatnonzero(np.diff(d) > 1) + 1
            x = np.insert(d.astype(np.float64), breaks, np.nan)
            y = np.insert(v, breaks, np.nan)
            ax.plot(x, y, color=colour, linestyle=dash, linewidth=1.6, marker=shape if len(d) <= 400 else "",
                    markersize=4)  # fmt: skip
        handles.append(Line2D([], [], color=colour, linestyle=dash, marker=shape, markersize=5))
        del s
    if zero_line:
        for ax in axes:
            ax.axhline(0.0, color="#b71c1c", linestyle="--", linewidth=1.0)
    _legend(fig, handles, [label(s.label) for s in series], heading=title)
    fig.supxlabel("day", fontsize=9, y=0.01)
    return to_svg(fig, title, prefix)
