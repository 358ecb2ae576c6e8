"""The report as one self-contained HTML file: inline CSS and SVG, no script, nothing fetched.

The page renders the same outline as the Markdown face (tables, in the
same order) and draws the plots where the outline has a figure: speed per
passage, section states over time, crossing warnings against the head's
arrival and the tail clearing, and the analog values per channel
(matplotlib's SVG backend, inlined: :mod:`console.sinks.report.plots`).  It
reads at 1024 px and prints on A4 (``@media print``: no navigation, no
scroll boxes, colours kept, rows and plots not split across pages).
Every log-derived text goes through :func:`esc` (tables) or
:func:`console.sinks.report.plots.label` (plots): control characters as
``\\xNN``, bidi overrides and isolates as ``\\u202e``, then entity-escaped.
"""

from __future__ import annotations

import html
import itertools
import re
from collections.abc import Callable, Iterator
from functools import partial
from typing import Any

import numpy as np

from console.analysis.passages.buckets import Columns
from console.analysis.sections.state import SectionState
from console.analysis.timefmt import display
from console.inputs.recognise import natural_key
from console.safe_text import PLAIN, clean
from console.sinks.report import plots, trends
from console.sinks.report.analog import analog_series
from console.sinks.report.blocks import Block, Bullets, Cell, Figure, Heading, Para, Styled, Table
from console.sinks.report.jsonwrite import Write
from console.sinks.report.model import ReportData, timeline_order
from console.sinks.report.outline import outline

STYLE = """
*{box-sizing:border-box}
body{margin:0;background:#eef0f3;color:#1b1f24;
 font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,"Helvetica Neue",Arial,sans-serif}
main{max-width:1180px;margin:0 auto;padding:20px 24px 40px;background:#fff}
h1{font-size:24px;margin:0 0 6px}
h2{font-size:19px;margin:30px 0 8px;padding-bottom:4px;border-bottom:2px solid #c9d1d9}
h3{font-size:15px;margin:18px 0 6px}
p{margin:6px 0}
nav{font-size:13px;margin:8px 0 4px}
nav a{margin-right:12px;color:#0b5cad;text-decoration:none}
.scroll{overflow-x:auto}
table{border-collapse:collapse;width:100%;font-size:12.5px;margin:6px 0 4px}
th,td{border:1px solid #d0d7de;padding:3px 6px;text-align:left;vertical-align:top;overflow-wrap:break-word}
td.long{overflow-wrap:anywhere}
th{background:#eef1f4;font-weight:600}
th.num,td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap;overflow-wrap:normal}
tbody tr:nth-child(even){background:#f8f9fa}
ul{margin:6px 0;padding-left:22px}
.note{color:#57606a;font-style:italic;font-size:12px;margin:2px 0 8px}
figure{margin:10px 0 14px;break-inside:avoid}
figure svg{display:block;width:100%;height:auto;border:1px solid #d0d7de}
figcaption{font-size:12px;color:#57606a;margin-top:3px}
.tag{display:inline-block;padding:0 5px;border-radius:3px;white-space:nowrap}
.verdict-unsafe,.verdict-failing,.verdict-ok{display:inline-block;padding:3px 10px;border-radius:4px;font-weight:700}
.verdict-unsafe{background:#c62828;color:#fff}
.verdict-failing{background:#f9a825;color:#1b1f24}
.verdict-ok{background:#2e7d32;color:#fff}
.state-clear{background:#e3f2e1}
.state-occupied{background:#f6c343}
.state-disturbed{background:#c62828;color:#fff;font-weight:700}
.state-preparatory{background:#d1c4e9}
.sev-critical{background:#c62828;color:#fff;font-weight:700}
.sev-warning{background:#f9a825}
.sev-info{color:#57606a}
.unsafe{color:#b71c1c;font-weight:700}
.failing{color:#8a5a00;font-weight:600}
.bad{color:#b71c1c;font-weight:600}
.warn{color:#8a5a00;font-weight:600}
.ok{color:#2e7d32;font-weight:600}
.muted{color:#6e7781}
.strong{font-weight:700}
footer{margin-top:28px;font-size:12px;color:#57606a}
@page{size:A4;margin:14mm 12mm}
@media print{
 body{background:#fff;font-size:10pt}
 main{max-width:none;padding:0}
 nav{display:none}
 .scroll{overflow:visible}
 table{font-size:8pt}
 thead{display:table-header-group}
 tr,figure{break-inside:avoid}
 h2,h3{break-after:avoid}
 *{-webkit-print-color-adjust:exact;print-color-adjust:exact}
}
"""

CSP = "default-src 'none'; style-src 'unsafe-inline'; img-src data:"

STATE_STYLES = {
    str(SectionState.CLEAR): plots.StateStyle("#e3f2e1", "#1b5e20", "·", "", 0),
    str(SectionState.OCCUPIED): plots.StateStyle("#f6c343", "#5d4300", "#", "//", 2),
    str(SectionState.DISTURBED): plots.StateStyle("#c62828", "#ffffff", "!", "xx", 3),
    str(SectionState.PREPARATORY): plots.StateStyle("#d1c4e9", "#311b92", "?", "..", 1),
}
_TAGGED = re.compile(r"^(state|sev)-")
LONG_CELL_CHARS = 60
# What the speed plot reads of each train passage (besides its head).
_PLOTTED = ("start_ns", "speed_kmh_whole_train", "speed_kmh_per_axle_mean", "axles")


def esc(value: object) -> str:
    """Log text made inert for HTML: control characters as \\xNN, then entity-escaped."""
    if type(value) is str and PLAIN.fullmatch(value):
        return value  # nothing to escape (most table cells)
    return html.escape(clean(value), quote=True)


def _cell(c: Cell) -> str:
    if isinstance(c, Styled):
        if not c.style:
            return esc(c.text)
        tag = " tag" if _TAGGED.match(c.style) else ""
        return f'<span class="{esc(c.style)}{tag}">{esc(c.text)}</span>'
    return esc(c)


def _table(t: Table, write: Write) -> None:
    def cls(i: int, cell: Cell | None = None) -> str:
        if t.numeric[i]:
            return ' class="num"'
        # Long unbroken text (an escaped log line) may wrap anywhere; short words keep their column wide.
        text = cell.text if isinstance(cell, Styled) else cell
        return ' class="long"' if text is not None and len(text) > LONG_CELL_CHARS else ""

    head = "".join(f"<th{cls(i)}>{esc(c)}</th>" for i, c in enumerate(t.columns))
    write(f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>')
    for row in t.rows:
        write("<tr>" + "".join(f"<td{cls(i, c)}>{_cell(c)}</td>" for i, c in enumerate(row)) + "</tr>")
    write("</tbody></table></div>")
    if t.note:
        write(f'<p class="note">{esc(t.note)}</p>')


# ----------------------------------------------------------------------------- plots


def _trains(data: ReportData) -> tuple[Columns, dict[str, Callable[[], np.ndarray]]] | None:
    """The train passages' plotted columns, and per head name its rows in the passages table's order
    (head, then start)."""
    if data.passage_spool is not None:
        cols = data.passage_spool.trains()
        keys: dict[str, list[int]] = {}
        for k in np.unique(cols["head"]).tolist():
            keys.setdefault(data.passage_spool.heads[k][1], []).append(k)

        def of_keys(ks: list[int]) -> np.ndarray:
            rows = np.flatnonzero(np.isin(cols["head"], ks))
            return rows[np.lexsort((cols["start_ns"][rows], cols["head"][rows]))]

        return cols, {name: partial(of_keys, ks) for name, ks in keys.items()}
    if data.job is None:
        return None
    p = data.job.analysis.passages
    trains = p[p["kind"] == "train"] if len(p) else p
    names = trains["counting_head"].astype(str).to_numpy(object)
    cols = {c: trains[c].to_numpy() for c in _PLOTTED}
    return cols, {name: partial(np.flatnonzero, names == name) for name in set(names.tolist())}


def _speeds(data: ReportData) -> str | None:
    """The speed plot, a point per train passage and speed (None: nothing to draw)."""
    found = _trains(data)
    if found is None:
        return None
    cols, heads = found
    whole = np.asarray(cols["speed_kmh_whole_train"], np.float64)
    axle = np.asarray(cols["speed_kmh_per_axle_mean"], np.float64)
    has_whole, has_axle = np.isfinite(whole), np.isfinite(axle)
    drawn = has_whole | has_axle
    if not drawn.any():
        return None
    top = max(float(whole[has_whole].max(initial=-np.inf)), float(axle[has_axle].max(initial=-np.inf)))
    spread = plots.spread_of(np.asarray(cols["start_ns"], np.int64)[drawn])

    def load(rows: Callable[[], np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        r = rows()  # one head's numbers in memory at a time
        return cols["start_ns"][r], whole[r], axle[r]

    series = [plots.SpeedSeries(h, partial(load, heads[h])) for h in sorted(heads, key=natural_key)]
    return plots.speed_plot(series, spread, top, "Speed per passage")


def _section_changes(data: ReportData) -> tuple[list[str], Callable[[str], Iterator[tuple[int, str, int, str]]]]:
    """The sections, and a section's state changes in order (time, state, count, reason)."""
    if data.history is not None:
        return list(data.history.final), data.history.changes
    assert data.sections is not None
    tl = data.sections.timeline

    def changes(sid: str) -> Iterator[tuple[int, str, int, str]]:
        part = tl[tl["section"] == sid]
        times = part["time_ns"].astype("int64").tolist()
        states, reasons = part["state"].astype(str).tolist(), part["reason"].astype(str).tolist()
        return zip(times, states, part["count"].tolist(), reasons, strict=True)

    return list(data.sections.final), changes


def _segments(changes: Iterator[tuple[int, str, int, str]], t1: int) -> Iterator[plots.Segment]:
    """A section's band: each state from its change to the next (the last one to ``t1``)."""
    prev = next(changes, None)
    while prev is not None:
        nxt = next(changes, None)
        t, st, _count, _reason = prev
        end = nxt[0] if nxt is not None else t1
        if not (end <= t and nxt is not None):  # else replaced at the same instant
            yield plots.Segment(t, max(end, t), st)
        prev = nxt


def _sections(data: ReportData) -> str | None:
    """The state plot, a band per section (None: no state change to draw)."""
    if data.history is not None:
        span = data.history.span_ns()
    elif data.sections is not None and not data.sections.timeline.empty:
        times = data.sections.timeline["time_ns"]
        span = (int(times.min()), int(times.max()))
    else:
        span = None
    if span is None:
        return None
    t0 = span[0]
    t1 = max(data.data_end_ns() or t0, span[1])
    sections, changes = _section_changes(data)
    # Where the changes lie in time (for the panels), read once in chunks: memory bounded by the hours they span.
    spread = plots.TimeSpread()
    for sid in sections:
        it = changes(sid)
        while chunk := [c[0] for c in itertools.islice(it, 50_000)]:
            spread.add(np.array(chunk, np.int64))
    rows = [plots.BandRow(sid, partial(lambda sid: _segments(iter(changes(sid)), t1), sid)) for sid in sections]
    return plots.state_plot(rows, spread, t1, STATE_STYLES, "Section states over time")


def _crossings(data: ReportData) -> tuple[str, int]:
    run = data.crossing
    if run is None or not run.timelines:
        return "", 0
    required = {c.code: c.warning_time_s for c in data.layout.crossings} if data.layout is not None else {}
    bars = []
    skipped = 0
    for r in sorted(run.timelines, key=timeline_order):
        if r.t_head_arrival_ns is None:
            skipped += 1
            continue
        h = r.t_head_arrival_ns

        def rel(t: int | None, h: int = h) -> float | None:
            return None if t is None else (t - h) / 1e9

        when = display(h)[11:19]
        bars.append(
            plots.WarningBar(
                f"{r.crossing} {r.train} {when}",
                rel(r.t_on_ns),
                rel(r.t_off_ns),
                rel(r.t_tail_clear_ns),
                rel(r.baseline_off_ns),
                required.get(r.crossing, 0.0),
                bool(r.violations),
            )
        )
    if not bars:
        return "", skipped
    return plots.warning_plot(bars, "Crossing warnings against head and tail arrival"), skipped


def _analog(data: ReportData) -> list[str]:
    series = analog_series(data)
    if series.empty:
        return []
    bands = {h.id: h.analog_band for h in data.layout.heads if h.analog_band} if data.layout is not None else {}
    out = []
    for n, head in enumerate(sorted(set(series["head"].tolist()), key=natural_key)):
        part = series[series["head"] == head]
        lines = [
            plots.Line(
                f"Sys{ch} Adr {adr:03d}",
                g["time_ns"].to_numpy(np.int64),
                g["value"].to_numpy(np.float64),
            )
            for (ch, adr), g in part.groupby(["channel", "address"], sort=True)
        ]
        out.append(plots.lines_plot(lines, f"Analog values at {head}", "analog value", bands.get(head), f"analog{n}"))
    return out


def _figure(plot: str, data: ReportData, write: Write) -> None:
    if plot in ("speeds", "sections"):
        body = _speeds(data) if plot == "speeds" else _sections(data)
        caption = (
            "Speed per passage over time: one shape and colour per counting head."
            if plot == "speeds"
            else "Section states over time (the reasons are in the state timeline below); "
            "marks: · clear, # occupied, ! disturbed, ? preparatory."
        )
        if body is not None:
            write(f"<figure>{body}<figcaption>{esc(caption)}</figcaption></figure>")
        return
    if plot == "crossings":
        svg_text, skipped = _crossings(data)
        caption = (
            "Per crossing and train: the warning from on to off, relative to the head's arrival (0 s); "
            "the dashed tick is the warning time the crossing needs."
        )
        if skipped:
            caption += f" {skipped} timeline(s) without a head arrival time are not drawn."
        if svg_text:
            write(f"<figure>{svg_text}<figcaption>{esc(caption)}</figcaption></figure>")
        return
    if plot == "analog":
        caption = "Analog receiver values per channel; the shaded band is the layout's, where it gives one."
        write("".join(f"<figure>{b}<figcaption>{esc(caption)}</figcaption></figure>" for b in _analog(data)))
        return
    if plot == "forecast":
        from console.sinks.report.forecast import forecast_plots

        caption = (
            "The daily figure (dots), its trend over the last days with the 90 % band of its slope, the threshold "
            "(dashed) and the crossing date (line) with its interval (shaded)."
        )
        write(
            "".join(
                f"<figure>{b}<figcaption>{esc(caption)}</figcaption></figure>" for b in forecast_plots(data.forecast)
            )
        )
        return
    if plot.startswith("trend-"):
        caption = trends.caption(plot)
        write(
            "".join(
                f"<figure>{b}<figcaption>{esc(caption)}</figcaption></figure>"
                for b in trends.trend_plots(plot, data.trends)
            )
        )


# ----------------------------------------------------------------------------- page


def write_blocks(blocks: list[Block], data: ReportData, write: Write) -> None:
    """The blocks as HTML, a line each; the navigation after the title and the two summary lines."""
    nav = [
        f'<a href="#{esc(b.anchor)}">{esc(b.text)}</a>'
        for b in blocks
        if isinstance(b, Heading) and b.level == 2 and b.anchor
    ]
    at = min(3, len(blocks))
    for i, b in enumerate(blocks):
        if i:
            write("\n")
        if i == at and nav:
            write("<nav>" + "".join(nav) + "</nav>\n")
        if isinstance(b, Heading):
            anchor = f' id="{esc(b.anchor)}"' if b.anchor else ""
            write(f"<h{b.level}{anchor}>{esc(b.text)}</h{b.level}>")
        elif isinstance(b, Para):
            write("<p>" + "".join(_cell(c) for c in b.parts) + "</p>")
        elif isinstance(b, Table):
            _table(b, write)
        elif isinstance(b, Bullets):
            write("<ul>" + "".join(f"<li>{esc(item)}</li>" for item in b.items) + "</ul>")
        elif isinstance(b, Figure):
            _figure(b.plot, data, write)
    if nav and at == len(blocks):
        write(("\n" if blocks else "") + "<nav>" + "".join(nav) + "</nav>")


def render_html(data: ReportData, doc: dict[str, Any], write: Write) -> None:
    """The whole page, piece by piece: the report document's outline, with its plots drawn from ``data``."""
    footer = (
        f"trackside {esc(doc['trackside_version'])}, schema {esc(doc['schema'])}. No clock time is recorded: "
        "the same inputs give the same report."
    )
    write(
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        # Defence in depth: even a text that escaped escaping could run no script and fetch nothing.
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
        "<title>trackside report</title>\n"
        f"<style>{STYLE}</style>\n</head>\n<body>\n<main>\n"
    )
    write_blocks(outline(doc), data, write)
    write(f"\n<footer>{footer}</footer>\n</main>\n</body>\n</html>\n")
