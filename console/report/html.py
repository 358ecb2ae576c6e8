"""The report as one self-contained HTML file: inline CSS and SVG, no script, nothing fetched.

The page renders the same outline as the Markdown face (tables, in the
same order) and draws the plots where the outline has a figure: speed per
passage, section states over time, crossing warnings against the head's
arrival and the tail clearing, and the analog values per channel.  It
reads at 1024 px and prints on A4 (``@media print``: no navigation, no
scroll boxes, colours kept, rows and plots not split across pages).
Every log-derived text, in tables and inside SVG, goes through
:func:`console.report.svg.esc`: control characters as ``\\xNN``, bidi
overrides and isolates as ``\\u202e``, then entity-escaped.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np

from console.analysis.sections import SectionState
from console.analysis.timefmt import display
from console.report import svg, trends
from console.report.model import ReportData, analog_series, natural_key, timeline_order
from console.report.outline import Block, Bullets, Cell, Figure, Heading, Para, Styled, Table, outline
from console.report.svg import esc

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
    str(SectionState.CLEAR): svg.StateStyle("#e3f2e1", "#1b5e20", "·", ""),
    str(SectionState.OCCUPIED): svg.StateStyle("#f6c343", "#5d4300", "#", "hatch"),
    str(SectionState.DISTURBED): svg.StateStyle("#c62828", "#ffffff", "!", "cross"),
    str(SectionState.PREPARATORY): svg.StateStyle("#d1c4e9", "#311b92", "?", "dots"),
}
_TAGGED = re.compile(r"^(state|sev)-")
LONG_CELL_CHARS = 60


def _cell(c: Cell) -> str:
    if isinstance(c, Styled):
        if not c.style:
            return esc(c.text)
        tag = " tag" if _TAGGED.match(c.style) else ""
        return f'<span class="{esc(c.style)}{tag}">{esc(c.text)}</span>'
    return esc(c)


def _table(t: Table) -> str:
    def cls(i: int, cell: Cell | None = None) -> str:
        if t.numeric[i]:
            return ' class="num"'
        # Long unbroken text (an escaped log line) may wrap anywhere; short words keep their column wide.
        text = cell.text if isinstance(cell, Styled) else cell
        return ' class="long"' if text is not None and len(text) > LONG_CELL_CHARS else ""

    head = "".join(f"<th{cls(i)}>{esc(c)}</th>" for i, c in enumerate(t.columns))
    body = "".join(
        "<tr>" + "".join(f"<td{cls(i, c)}>{_cell(c)}</td>" for i, c in enumerate(row)) + "</tr>" for row in t.rows
    )
    out = f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'
    return out + (f'<p class="note">{esc(t.note)}</p>' if t.note else "")


# ----------------------------------------------------------------------------- plots


def _speeds(data: ReportData) -> str:
    if data.job is None:
        return ""
    p = data.job.analysis.passages
    trains = p[p["kind"] == "train"] if len(p) else p
    if trains.empty:
        return ""
    series = []
    heads = sorted({str(h) for h in trains["counting_head"]}, key=natural_key)
    for head in heads:
        s = svg.Series(head)
        rows = trains[trains["counting_head"].astype(str) == head]
        for t, whole, axle, n in zip(
            rows["start_ns"].tolist(),
            rows["speed_kmh_whole_train"].tolist(),
            rows["speed_kmh_per_axle_mean"].tolist(),
            rows["axles"].tolist(),
            strict=True,
        ):
            when = display(int(t))
            if np.isfinite(whole):
                s.points.append(svg.Point(int(t), float(whole), f"{head} {when}: whole train {whole:.1f} km/h"))
            if np.isfinite(axle):
                tip = f"{head} {when}: per-axle mean {axle:.1f} km/h ({n} axles)"
                s.points.append(svg.Point(int(t), float(axle), tip, filled=False))
        series.append(s)
    if not any(s.points for s in series):
        return ""
    return svg.scatter_over_time(series, "Speed per passage", "km/h", "filled: whole train · ring: per-axle mean")


def _sections(data: ReportData) -> str:
    res = data.sections
    if res is None or res.timeline.empty:
        return ""
    tl = res.timeline
    t0 = int(tl["time_ns"].min())
    t1 = max(data.data_end_ns() or t0, int(tl["time_ns"].max()))
    rows = []
    for sid in res.final:
        part = tl[tl["section"] == sid]
        times = part["time_ns"].astype("int64").tolist()
        states = part["state"].astype(str).tolist()
        reasons = part["reason"].astype(str).tolist()
        counts = part["count"].tolist()
        row = svg.BandRow(sid)
        for i, (t, st) in enumerate(zip(times, states, strict=True)):
            end = times[i + 1] if i + 1 < len(times) else t1
            if end <= t and i + 1 < len(times):
                continue  # replaced at the same instant
            tip = f"{sid} {st} from {display(t)} to {display(end)} (count {counts[i]}): {reasons[i]}"
            row.segments.append(svg.Segment(t, max(end, t), st, tip))
        rows.append(row)
    return svg.state_bands(rows, t0, t1, STATE_STYLES, "Section states over time", prefix="ts-state")


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
        tip = (
            f"{r.crossing} train {r.train}: on {display(r.t_on_ns)}, head {display(h)}, "
            f"tail clear {display(r.t_tail_clear_ns)}, off {display(r.t_off_ns)}"
            + (f"; {'; '.join(r.violations)}" if r.violations else "")
        )
        bars.append(
            svg.WarningBar(
                f"{r.crossing} {r.train} {when}",
                rel(r.t_on_ns),
                rel(r.t_off_ns),
                rel(r.t_tail_clear_ns),
                rel(r.baseline_off_ns),
                required.get(r.crossing, 0.0),
                bool(r.violations),
                tip,
            )
        )
    if not bars:
        return "", skipped
    return svg.warning_bars(bars, "Crossing warnings against head and tail arrival"), skipped


def _analog(data: ReportData) -> list[str]:
    series = analog_series(data)
    if series.empty:
        return []
    bands = {h.id: h.analog_band for h in data.layout.heads if h.analog_band} if data.layout is not None else {}
    out = []
    for head in sorted(set(series["head"].tolist()), key=natural_key):
        part = series[series["head"] == head]
        lines = [
            svg.Line(
                f"Sys{ch} Adr {adr:03d}",
                g["time_ns"].to_numpy(np.int64),
                g["value"].to_numpy(np.float64),
            )
            for (ch, adr), g in part.groupby(["channel", "address"], sort=True)
        ]
        out.append(
            svg.lines_over_time(lines, f"Analog values at {head}", "analog value", bands.get(head), heading=head)
        )
    return out


def _figure(plot: str, data: ReportData) -> str:
    if plot == "speeds":
        body = _speeds(data)
        caption = "Speed per passage over time: one shape and colour per counting head."
        return f"<figure>{body}<figcaption>{esc(caption)}</figcaption></figure>" if body else ""
    if plot == "sections":
        body = _sections(data)
        caption = (
            "Section states over time (hover a band for the reason); "
            "marks: · clear, # occupied, ! disturbed, ? preparatory."
        )
        return f"<figure>{body}<figcaption>{esc(caption)}</figcaption></figure>" if body else ""
    if plot == "crossings":
        body, skipped = _crossings(data)
        caption = (
            "Per crossing and train: the warning from on to off, relative to the head's arrival (0 s); "
            "the dashed tick is the warning time the crossing needs."
        )
        if skipped:
            caption += f" {skipped} timeline(s) without a head arrival time are not drawn."
        return f"<figure>{body}<figcaption>{esc(caption)}</figcaption></figure>" if body else ""
    if plot == "analog":
        bodies = _analog(data)
        caption = "Analog receiver values per channel; the shaded band is the layout's, where it gives one."
        return "".join(f"<figure>{b}<figcaption>{esc(caption)}</figcaption></figure>" for b in bodies)
    if plot.startswith("trend-"):
        caption = trends.caption(plot)
        return "".join(
            f"<figure>{b}<figcaption>{esc(caption)}</figcaption></figure>"
            for b in trends.trend_plots(plot, data.trends)
        )
    return ""


# ----------------------------------------------------------------------------- page


def render_blocks(blocks: list[Block], data: ReportData) -> str:
    parts: list[str] = []
    nav: list[str] = []
    for b in blocks:
        if isinstance(b, Heading):
            anchor = f' id="{esc(b.anchor)}"' if b.anchor else ""
            parts.append(f"<h{b.level}{anchor}>{esc(b.text)}</h{b.level}>")
            if b.level == 2 and b.anchor:
                nav.append(f'<a href="#{esc(b.anchor)}">{esc(b.text)}</a>')
        elif isinstance(b, Para):
            parts.append("<p>" + "".join(_cell(c) for c in b.parts) + "</p>")
        elif isinstance(b, Table):
            parts.append(_table(b))
        elif isinstance(b, Bullets):
            parts.append("<ul>" + "".join(f"<li>{esc(item)}</li>" for item in b.items) + "</ul>")
        elif isinstance(b, Figure):
            parts.append(_figure(b.plot, data))
    # The navigation goes after the title and the two summary lines.
    if nav:
        parts.insert(min(3, len(parts)), "<nav>" + "".join(nav) + "</nav>")
    return "\n".join(parts)


def render_html(data: ReportData, doc: dict[str, Any]) -> str:
    """The whole page: the report document's outline, with its plots drawn from ``data``."""
    body = render_blocks(outline(doc), data)
    footer = (
        f"trackside {esc(doc['trackside_version'])}, schema {esc(doc['schema'])}. No clock time is recorded: "
        "the same inputs give the same report."
    )
    return (
        "<!DOCTYPE html>\n"
        '<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
        # Defence in depth: even a text that escaped escaping could run no script and fetch nothing.
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
        "<title>trackside report</title>\n"
        f"<style>{STYLE}</style>\n</head>\n<body>\n<main>\n{body}\n<footer>{footer}</footer>\n</main>\n</body>\n</html>\n"
    )
