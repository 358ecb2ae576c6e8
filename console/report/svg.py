"""Small hand-written SVG plots for the HTML report.

No script, no external font or stylesheet: each plot is one ``<svg>``
element with a ``viewBox`` (it scales to the page width, on screen and on
paper) and the generic ``sans-serif`` family.  Every text that may come
from a log (labels, tooltips in ``<title>``) goes through :func:`esc`.
Series differ by marker shape or dash pattern as well as by colour, and
states carry a hatch pattern and a written mark, so a plot reads in black
and white and for colour-blind readers.
"""

from __future__ import annotations

import datetime as dt
import html
import itertools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from console.analysis.timefmt import NS as _NS
from console.safe_text import PLAIN, clean

WIDTH = 1000
FONT = 'font-family="sans-serif" font-size="12"'
# Okabe–Ito: distinguishable with the common colour-vision deficiencies.
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000")
SHAPES = ("circle", "square", "triangle", "diamond", "triangle-down", "cross", "plus")
DASHES = ("", "7 3", "2 3", "9 3 2 3", "4 4")
_EPOCH = dt.datetime(1970, 1, 1)
_TIME_STEPS_S = (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400)


def esc(value: object) -> str:
    """Log text made inert for HTML and SVG: control characters as \\xNN, then entity-escaped."""
    if type(value) is str and PLAIN.fullmatch(value):
        return value  # nothing to escape (most table cells)
    return html.escape(clean(value), quote=True)


def _fmt(x: float) -> str:
    return f"{x:.1f}".rstrip("0").rstrip(".")


def _clock(ns: float) -> dt.datetime:
    return _EPOCH + dt.timedelta(microseconds=int(ns) // 1000)


def time_ticks(t0_ns: float, t1_ns: float, max_ticks: int = 8) -> list[tuple[float, str]]:
    """Round times of day between t0 and t1 (ns since the epoch), labelled HH:MM (or HH:MM:SS)."""
    span_s = max((t1_ns - t0_ns) / _NS, 1e-9)
    step = next((s for s in _TIME_STEPS_S if span_s / s <= max_ticks), _TIME_STEPS_S[-1])
    first = math.ceil(t0_ns / _NS / step) * step
    out: list[tuple[float, str]] = []
    t = first
    while t * _NS <= t1_ns:
        label = _clock(t * _NS).strftime("%H:%M" if step >= 60 else "%H:%M:%S")
        out.append((t * _NS, label))
        t += step
    return out


def value_ticks(lo: float, hi: float, max_ticks: int = 6) -> list[tuple[float, str]]:
    """1-2-5 steps covering lo..hi."""
    span = max(hi - lo, 1e-9)
    raw = span / max_ticks
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step) * step
    out = []
    k = 0
    while first + k * step <= hi + step * 1e-9:
        v = first + k * step
        out.append((v, _fmt(v) if abs(v) >= 1e-9 else "0"))
        k += 1
    return out


def nice_range(lo: float, hi: float, pad: float = 0.05) -> tuple[float, float]:
    """lo..hi widened a little (and made non-empty)."""
    if not math.isfinite(lo) or not math.isfinite(hi):
        return 0.0, 1.0
    if hi <= lo:
        return lo - 1.0, hi + 1.0
    d = (hi - lo) * pad
    return lo - d, hi + d


@dataclass(frozen=True)
class Frame:
    """The plot area inside an SVG and the data ranges it shows."""

    height: float
    left: float
    right: float
    top: float
    bottom: float
    x0: float
    x1: float
    y0: float = 0.0
    y1: float = 1.0

    def x(self, v: float) -> float:
        w = WIDTH - self.left - self.right
        return self.left + (v - self.x0) / (self.x1 - self.x0 or 1.0) * w

    def y(self, v: float) -> float:
        h = self.height - self.top - self.bottom
        return self.top + h - (v - self.y0) / (self.y1 - self.y0 or 1.0) * h


def open_svg(height: float, label: str) -> str:
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {WIDTH} {_fmt(height)}" width="100%" '
        f'role="img" aria-label="{esc(label)}" {FONT}><title>{esc(label)}</title>'
        f'<rect x="0" y="0" width="{WIDTH}" height="{_fmt(height)}" fill="#ffffff"/>'
    )


def _x_axis(f: Frame, ticks: list[tuple[float, str]], caption: str) -> list[str]:
    base = f.height - f.bottom
    out = [
        f'<line x1="{_fmt(f.left)}" y1="{_fmt(base)}" x2="{_fmt(WIDTH - f.right)}" y2="{_fmt(base)}" stroke="#444"/>'
    ]
    for v, label in ticks:
        x = f.x(v)
        out.append(f'<line x1="{_fmt(x)}" y1="{_fmt(f.top)}" x2="{_fmt(x)}" y2="{_fmt(base)}" stroke="#e4e4e4"/>')
        out.append(f'<text x="{_fmt(x)}" y="{_fmt(base + 16)}" text-anchor="middle" fill="#333">{esc(label)}</text>')
    mid = (f.left + WIDTH - f.right) / 2
    out.append(f'<text x="{_fmt(mid)}" y="{_fmt(base + 34)}" text-anchor="middle" fill="#333">{esc(caption)}</text>')
    return out


def _y_axis(f: Frame, ticks: list[tuple[float, str]], caption: str) -> list[str]:
    out = [
        f'<line x1="{_fmt(f.left)}" y1="{_fmt(f.top)}" x2="{_fmt(f.left)}" '
        f'y2="{_fmt(f.height - f.bottom)}" stroke="#444"/>'
    ]
    for v, label in ticks:
        y = f.y(v)
        out.append(
            f'<line x1="{_fmt(f.left)}" y1="{_fmt(y)}" x2="{_fmt(WIDTH - f.right)}" y2="{_fmt(y)}" stroke="#e4e4e4"/>'
        )
        out.append(f'<text x="{_fmt(f.left - 6)}" y="{_fmt(y + 4)}" text-anchor="end" fill="#333">{esc(label)}</text>')
    mid = (f.top + f.height - f.bottom) / 2
    out.append(
        f'<text x="14" y="{_fmt(mid)}" text-anchor="middle" fill="#333" '
        f'transform="rotate(-90 14 {_fmt(mid)})">{esc(caption)}</text>'
    )
    return out


def marker(shape: str, x: float, y: float, colour: str, filled: bool = True, tip: str = "", r: float = 5.0) -> str:
    """One point: a shape of the series, filled or hollow, with an optional tooltip."""
    # A hollow mark is a larger ring with no fill: drawn over a filled one of the same value, both show.
    fill = colour if filled else "none"
    if not filled:
        r += 2.5
    style = f'fill="{fill}" stroke="{colour}" stroke-width="1.6"'
    title = f"<title>{esc(tip)}</title>" if tip else ""
    if shape == "square":
        side = _fmt(r * 1.7)
        body = f'<rect x="{_fmt(x - r * 0.85)}" y="{_fmt(y - r * 0.85)}" width="{side}" height="{side}" {style}>'
        return body + title + "</rect>"
    if shape in ("triangle", "triangle-down", "diamond"):
        if shape == "triangle":
            pts = [(x, y - r * 1.1), (x + r, y + r * 0.8), (x - r, y + r * 0.8)]
        elif shape == "triangle-down":
            pts = [(x, y + r * 1.1), (x + r, y - r * 0.8), (x - r, y - r * 0.8)]
        else:
            pts = [(x, y - r * 1.2), (x + r, y), (x, y + r * 1.2), (x - r, y)]
        p = " ".join(f"{_fmt(a)},{_fmt(b)}" for a, b in pts)
        return f'<polygon points="{p}" {style}>{title}</polygon>'
    if shape in ("cross", "plus"):
        if shape == "plus":
            d = f"M{_fmt(x - r)},{_fmt(y)}H{_fmt(x + r)}M{_fmt(x)},{_fmt(y - r)}V{_fmt(y + r)}"
        else:
            a, b, c, e = _fmt(x - r), _fmt(x + r), _fmt(y - r), _fmt(y + r)
            d = f"M{a},{c}L{b},{e}M{a},{e}L{b},{c}"
        width = "2.4" if filled else "1.2"
        return f'<path d="{d}" stroke="{colour}" stroke-width="{width}" fill="none">{title}</path>'
    return f'<circle cx="{_fmt(x)}" cy="{_fmt(y)}" r="{_fmt(r)}" {style}>{title}</circle>'


# ----------------------------------------------------------------------------- scatter over time


@dataclass(frozen=True)
class Point:
    t_ns: int
    value: float
    tip: str = ""
    filled: bool = True


@dataclass
class Series:
    label: str
    points: Iterable[Point] = field(default_factory=list)  # drawn in this order; may be read once only


def scatter_over_time(
    series: Sequence[Series],
    span_ns: tuple[int, int],
    top_value: float,
    title: str,
    y_caption: str,
    legend_note: str = "",
    height: float = 340,
) -> Iterator[str]:
    """Points over time, one shape and colour per series; filled and hollow points for two measures.

    ``span_ns`` and ``top_value``: the first and last time and the largest value
    of the finite points, known before the points are read (they are drawn as they come).
    """
    t0, t1 = span_ns
    if t1 <= t0:
        t0, t1 = t0 - 60 * _NS, t1 + 60 * _NS
    pad = (t1 - t0) * 0.03
    lo, hi = nice_range(0.0, top_value * 1.08, pad=0.0)
    f = Frame(height, 62, 20, 34, 52, t0 - pad, t1 + pad, lo, hi)
    yield open_svg(height, title)
    yield from _x_axis(f, time_ticks(f.x0, f.x1), f"time of day, {_clock(t0):%Y-%m-%d}")
    yield from _y_axis(f, value_ticks(lo, hi), y_caption)
    for i, s in enumerate(series):
        colour, shape = PALETTE[i % len(PALETTE)], SHAPES[i % len(SHAPES)]
        for p in s.points:
            if math.isfinite(p.value):
                yield marker(shape, f.x(p.t_ns), f.y(p.value), colour, p.filled, p.tip)
    # Legend, above the plot area.
    x = f.left
    for i, s in enumerate(series):
        colour, shape = PALETTE[i % len(PALETTE)], SHAPES[i % len(SHAPES)]
        yield marker(shape, x + 6, 16, colour, True)
        yield f'<text x="{_fmt(x + 16)}" y="20" fill="#222">{esc(s.label)}</text>'
        x += 28 + 7.2 * len(clean(s.label))
    if legend_note:
        yield f'<text x="{WIDTH - f.right}" y="20" text-anchor="end" fill="#444">{esc(legend_note)}</text>'
    yield "</svg>"


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


def lines_over_time(
    lines: Sequence[Line],
    title: str,
    y_caption: str,
    band: tuple[float, float] | None = None,
    height: float = 260,
    heading: str = "",
) -> str:
    """One polyline per series (a dash pattern and a colour each), an optional shaded band."""
    allt = np.concatenate([ln.t_ns for ln in lines]) if lines else np.zeros(1)
    allv = np.concatenate([ln.values for ln in lines]) if lines else np.zeros(1)
    t0, t1 = float(allt.min()), float(allt.max())
    if t1 <= t0:
        t0, t1 = t0 - 60 * _NS, t1 + 60 * _NS
    lo, hi = float(allv.min()), float(allv.max())
    if band is not None:
        lo, hi = min(lo, band[0]), max(hi, band[1])
    lo, hi = nice_range(lo, hi, pad=0.08)
    f = Frame(height, 62, 20, 34, 52, t0, t1, lo, hi)
    out = [open_svg(height, title)]
    out += _x_axis(f, time_ticks(t0, t1), f"time of day, {_clock(t0):%Y-%m-%d}")
    out += _y_axis(f, value_ticks(lo, hi), y_caption)
    if band is not None:
        y_hi, y_lo = f.y(band[1]), f.y(band[0])
        out.append(
            f'<rect x="{_fmt(f.left)}" y="{_fmt(y_hi)}" width="{_fmt(WIDTH - f.left - f.right)}" '
            f'height="{_fmt(y_lo - y_hi)}" fill="#2e7d32" fill-opacity="0.10" stroke="#2e7d32" '
            f'stroke-dasharray="3 3"><title>band {_fmt(band[0])}–{_fmt(band[1])}</title></rect>'
        )
    for i, ln in enumerate(lines):
        colour, dash = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)]
        t, v = thin(ln.t_ns, ln.values)
        pts = " ".join(f"{_fmt(f.x(a))},{_fmt(f.y(b))}" for a, b in zip(t.tolist(), v.tolist(), strict=True))
        dash_attr = f' stroke-dasharray="{dash}"' if dash else ""
        if len(t) == 1:
            out.append(marker("circle", f.x(float(t[0])), f.y(float(v[0])), colour, True, ln.label, 3))
        else:
            out.append(
                f'<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="1.8"{dash_attr}>'
                f"<title>{esc(ln.label)}</title></polyline>"
            )
    x = f.left
    if heading:
        out.append(f'<text x="{_fmt(x)}" y="21" fill="#111" font-size="14" font-weight="bold">{esc(heading)}</text>')
        x += 24 + 8.5 * len(clean(heading))
    for i, ln in enumerate(lines):
        colour, dash = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)]
        dash_attr = f' stroke-dasharray="{dash}"' if dash else ""
        out.append(
            f'<line x1="{_fmt(x)}" y1="16" x2="{_fmt(x + 26)}" y2="16" stroke="{colour}" '
            f'stroke-width="2.2"{dash_attr}/>'
        )
        out.append(f'<text x="{_fmt(x + 32)}" y="20" fill="#222">{esc(ln.label)}</text>')
        x += 44 + 7.2 * len(clean(ln.label))
    out.append("</svg>")
    return "".join(out)


# ----------------------------------------------------------------------------- state bands


@dataclass(frozen=True)
class StateStyle:
    fill: str
    ink: str  # text and hatch colour on this fill
    mark: str
    pattern: str  # "" | "hatch" | "cross" | "dots"


@dataclass(frozen=True)
class Segment:
    t0_ns: int
    t1_ns: int
    state: str
    tip: str = ""


@dataclass
class BandRow:
    label: str
    segments: Iterable[Segment] = field(default_factory=list)  # may be read once only


def _patterns(prefix: str, styles: dict[str, StateStyle]) -> str:
    out = ["<defs>"]
    for name, st in styles.items():
        pid = f"{prefix}-{name}"
        body = f'<rect width="8" height="8" fill="{st.fill}"/>'
        if st.pattern == "hatch":
            body += (
                f'<path d="M-2,2 L2,-2 M0,8 L8,0 M6,10 L10,6" stroke="{st.ink}" '
                'stroke-width="1.2" stroke-opacity="0.55"/>'
            )
        elif st.pattern == "cross":
            body += f'<path d="M0,0 L8,8 M8,0 L0,8" stroke="{st.ink}" stroke-width="1.2" stroke-opacity="0.6"/>'
        elif st.pattern == "dots":
            body += f'<circle cx="4" cy="4" r="1.3" fill="{st.ink}" fill-opacity="0.6"/>'
        out.append(f'<pattern id="{pid}" width="8" height="8" patternUnits="userSpaceOnUse">{body}</pattern>')
    out.append("</defs>")
    return "".join(out)


def state_bands(
    rows: Sequence[BandRow], t0_ns: int, t1_ns: int, styles: dict[str, StateStyle], title: str, prefix: str = "st"
) -> Iterator[str]:
    """One band per row (a section): segments filled by state, with the state's mark and name where they fit.

    The SVG comes in pieces, each segment as it is read: a long history is never one string.
    """
    if t1_ns <= t0_ns:
        t1_ns = t0_ns + 60 * _NS
    row_h, gap = 30, 10
    top, bottom = 40, 52
    height = top + bottom + len(rows) * (row_h + gap)
    f = Frame(height, 110, 20, top, bottom, t0_ns, t1_ns)
    yield open_svg(height, title)
    yield _patterns(prefix, styles)
    yield from _x_axis(f, time_ticks(t0_ns, t1_ns), f"time of day, {_clock(t0_ns):%Y-%m-%d}")
    for i, row in enumerate(rows):
        y = top + i * (row_h + gap)
        yield (
            f'<text x="{_fmt(f.left - 8)}" y="{_fmt(y + row_h / 2 + 4)}" text-anchor="end" fill="#222" '
            f'font-weight="bold">{esc(row.label)}</text>'
        )
        for seg in row.segments:
            st = styles[seg.state]
            x0, x1 = f.x(max(seg.t0_ns, t0_ns)), f.x(min(seg.t1_ns, t1_ns))
            w = max(x1 - x0, 1.2)
            tip = f"<title>{esc(seg.tip)}</title>" if seg.tip else ""
            yield (
                f'<rect x="{_fmt(x0)}" y="{y}" width="{_fmt(w)}" height="{row_h}" fill="url(#{prefix}-{seg.state})" '
                f'stroke="{st.ink}" stroke-width="0.4">{tip}</rect>'
            )
            text = f"{st.mark} {seg.state}" if w >= 9 + 7 * len(seg.state) else st.mark if w >= 10 else ""
            if text:
                yield (
                    f'<text x="{_fmt(x0 + w / 2)}" y="{_fmt(y + row_h / 2 + 4)}" text-anchor="middle" '
                    f'fill="{st.ink}" font-weight="bold">{esc(text)}</text>'
                )
    # Legend: swatch, mark and name, so the plot reads without colour.
    x = f.left
    for name, st in styles.items():
        yield (
            f'<rect x="{_fmt(x)}" y="8" width="22" height="14" fill="url(#{prefix}-{name})" '
            f'stroke="{st.ink}" stroke-width="0.6"/>'
        )
        yield f'<text x="{_fmt(x + 28)}" y="20" fill="#222">{esc(f"{st.mark} {name}")}</text>'
        x += 48 + 7.5 * len(name)
    yield "</svg>"


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
    tip: str = ""


def warning_bars(bars: Sequence[WarningBar], title: str) -> str:
    """Per crossing and train: the warning from on to off, the head's arrival (0), the tail clearing."""
    row_h, gap, top, bottom = 16, 6, 40, 52
    height = top + bottom + max(len(bars), 1) * (row_h + gap)
    xs = [0.0]
    for b in bars:
        xs += [x for x in (b.on_s, b.off_s, b.tail_s, b.baseline_off_s, -b.required_s) if x is not None]
    lo, hi = nice_range(min(xs), max(xs), pad=0.04)
    f = Frame(height, 150, 20, top, bottom, lo, hi)
    out = [open_svg(height, title)]
    out += _x_axis(f, value_ticks(lo, hi, 10), "seconds relative to the head's arrival at the crossing")
    x_head = f.x(0.0)
    out.append(
        f'<line x1="{_fmt(x_head)}" y1="{top - 4}" x2="{_fmt(x_head)}" y2="{_fmt(height - bottom)}" stroke="#222"/>'
    )
    for i, b in enumerate(bars):
        y = top + i * (row_h + gap)
        mid = y + row_h / 2
        ink = "#b71c1c" if b.violation else "#222"
        label = b.label + ("  VIOLATION" if b.violation else "")
        weight = ' font-weight="bold"' if b.violation else ""
        out.append(
            f'<text x="{_fmt(f.left - 8)}" y="{_fmt(mid + 4)}" text-anchor="end" fill="{ink}"{weight}>'
            f"{esc(label)}</text>"
        )
        req = f.x(-b.required_s)
        out.append(
            f'<line x1="{_fmt(req)}" y1="{y - 2}" x2="{_fmt(req)}" y2="{y + row_h + 2}" stroke="#555" '
            'stroke-dasharray="2 2"><title>the warning time the crossing needs</title></line>'
        )
        if b.on_s is not None:
            end = b.off_s if b.off_s is not None else hi
            x0, x1 = f.x(b.on_s), f.x(end)
            fill = "#E69F00" if not b.violation else "#c62828"
            tip = f"<title>{esc(b.tip)}</title>" if b.tip else ""
            out.append(
                f'<rect x="{_fmt(x0)}" y="{y + 3}" width="{_fmt(max(x1 - x0, 1.0))}" height="{row_h - 6}" '
                f'fill="{fill}" fill-opacity="0.85" stroke="{ink}" '
                f'stroke-width="{1.5 if b.violation else 0.5}">{tip}</rect>'
            )
            if b.off_s is None:
                out.append(
                    f'<text x="{_fmt(x1 - 4)}" y="{_fmt(mid + 4)}" text-anchor="end" fill="#222">held on →</text>'
                )
        out.append(marker("triangle-down", x_head, mid, "#0072B2", True, "head arrives", 5))
        if b.tail_s is not None:
            out.append(marker("square", f.x(b.tail_s), mid, "#009E73", True, f"tail clear at {b.tail_s:+.0f} s", 4.5))
        if b.baseline_off_s is not None:
            out.append(
                marker(
                    "cross",
                    f.x(b.baseline_off_s),
                    mid,
                    "#CC79A7",
                    True,
                    f"baseline off at {b.baseline_off_s:+.0f} s",
                    4.5,
                )
            )
    # Legend.
    items = [
        ('<rect x="{x}" y="10" width="22" height="10" fill="#E69F00" fill-opacity="0.85"/>', "warning on → off"),
        (None, "head arrives"),
        (None, "tail clear"),
        (None, "baseline off"),
        ('<line x1="{x}" y1="8" x2="{x}" y2="22" stroke="#555" stroke-dasharray="2 2"/>', "required warning time"),
    ]
    x = f.left
    for k, (shape, text) in enumerate(items):
        if shape is not None:
            out.append(shape.format(x=_fmt(x if k == 0 else x + 11)))
        elif k == 1:
            out.append(marker("triangle-down", x + 8, 15, "#0072B2", True))
        elif k == 2:
            out.append(marker("square", x + 8, 15, "#009E73", True, "", 4.5))
        else:
            out.append(marker("cross", x + 8, 15, "#CC79A7", True, "", 4.5))
        out.append(f'<text x="{_fmt(x + 28)}" y="20" fill="#222">{esc(text)}</text>')
        x += 40 + 7.0 * len(text)
    out.append("</svg>")
    return "".join(out)


# ----------------------------------------------------------------------------- values per day


@dataclass(frozen=True)
class DaySeries:
    """One series of daily values: days as ``YYYY-MM-DD``, a value each (None: no value that day)."""

    label: str
    days: tuple[str, ...]
    values: tuple[float | None, ...]


def day_ticks(d0: int, d1: int, max_ticks: int = 10) -> list[tuple[float, str]]:
    """Whole days between d0 and d1 (days since the epoch), labelled ``MM-DD`` (``YYYY-MM-DD`` when years differ)."""
    step = next((s for s in (1, 2, 7, 14, 28, 91, 182, 365) if (d1 - d0) / s <= max_ticks), 365)
    years = {str(np.datetime64(d0, "D"))[:4], str(np.datetime64(d1, "D"))[:4]}
    out = []
    for d in range(d0, d1 + 1, step):
        text = str(np.datetime64(d, "D"))
        out.append((float(d), text if len(years) > 1 else text[5:]))
    return out


def lines_per_day(
    series: Sequence[DaySeries], title: str, y_caption: str, heading: str = "", zero_line: bool = False
) -> str:
    """One line per series over whole days, a marker (the series' shape) on each day's value; gaps stay gaps."""
    day_index = {d: int(np.datetime64(d, "D").astype(np.int64)) for s in series for d in s.days}
    values = [v for s in series for v in s.values if v is not None]
    if not day_index or not values:
        return ""
    d0, d1 = min(day_index.values()), max(day_index.values())
    lo, hi = min(values), max(values)
    if zero_line:
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    lo, hi = nice_range(lo, hi, pad=0.08)
    height = 260.0
    f = Frame(height, 62, 20, 34, 52, d0 - 0.5, d1 + 0.5, lo, hi)
    out = [open_svg(height, title)]
    first, last = str(np.datetime64(d0, "D")), str(np.datetime64(d1, "D"))
    out += _x_axis(f, day_ticks(d0, d1), f"day, {first} to {last}" if d1 > d0 else f"day, {first}")
    out += _y_axis(f, value_ticks(lo, hi), y_caption)
    if zero_line and lo < 0 < hi:
        out.append(
            f'<line x1="{_fmt(f.left)}" y1="{_fmt(f.y(0))}" x2="{_fmt(WIDTH - f.right)}" y2="{_fmt(f.y(0))}" '
            'stroke="#b71c1c" stroke-dasharray="4 3"><title>0: the band edge</title></line>'
        )
    for i, s in enumerate(series):
        colour, dash, shape = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)], SHAPES[i % len(SHAPES)]
        pts = sorted((day_index[d], v) for d, v in zip(s.days, s.values, strict=True) if v is not None)
        # Consecutive days are joined; a day without a value breaks the line.
        run: list[tuple[int, float]] = []
        for p in [*pts, None]:
            if p is not None and (not run or p[0] == run[-1][0] + 1):
                run.append(p)
                continue
            if len(run) > 1:
                xy = " ".join(f"{_fmt(f.x(d))},{_fmt(f.y(v))}" for d, v in run)
                dash_attr = f' stroke-dasharray="{dash}"' if dash else ""
                out.append(f'<polyline points="{xy}" fill="none" stroke="{colour}" stroke-width="1.8"{dash_attr}/>')
            run = [p] if p is not None else []
        for d, v in pts:
            tip = f"{s.label}, {np.datetime64(d, 'D')}: {v:g}"
            out.append(marker(shape, f.x(d), f.y(v), colour, True, tip, 3.5))
    x = f.left
    if heading:
        out.append(f'<text x="{_fmt(x)}" y="21" fill="#111" font-size="14" font-weight="bold">{esc(heading)}</text>')
        x += 24 + 8.5 * len(clean(heading))
    for i, s in enumerate(series):
        colour, dash, shape = PALETTE[i % len(PALETTE)], DASHES[i % len(DASHES)], SHAPES[i % len(SHAPES)]
        dash_attr = f' stroke-dasharray="{dash}"' if dash else ""
        out.append(
            f'<line x1="{_fmt(x)}" y1="16" x2="{_fmt(x + 26)}" y2="16" stroke="{colour}" stroke-width="2"{dash_attr}/>'
        )
        out.append(marker(shape, x + 13, 16, colour, True, "", 3.5))
        out.append(f'<text x="{_fmt(x + 32)}" y="20" fill="#222">{esc(s.label)}</text>')
        x += 44 + 7.2 * len(clean(s.label))
    out.append("</svg>")
    return "".join(out)
