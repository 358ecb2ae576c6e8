"""Rich tables for `trackside analyze` / `speeds`: inventory, passages, parse report."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from rich import box
from rich.table import Table
from rich.text import Text

from console.analysis.diagnostics import DiagAnalysis
from console.analysis.inventory import DeviceInventory
from console.analysis.stream import take_passages
from console.analysis.timefmt import display, iso
from console.render.passage_spool import FirstPassages
from console.safe_text import inert
from parsers.report import ParseReport

REJECTIONS_SHOWN = 20
DEVICES_SHOWN = 6  # devices are columns: more do not fit in 80
_ARROWS = {"sys1_to_sys2": "1→2", "sys2_to_sys1": "2→1"}


def _num(value: object, fmt: str = "{:.1f}") -> Text:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return Text("–", style="dim")
    return Text(fmt.format(value))


def _time(ns: Any) -> Text:
    if ns is None or pd.isna(ns):
        return Text("–", style="dim")
    return Text(display(int(ns)))


def _table(title: str) -> Table:
    return Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, title_style="bold")


def inventory_table(analysis: DiagAnalysis, limit: int = DEVICES_SHOWN) -> Table:
    """Devices as columns, identity fields as rows: reads at 80 columns (the first ``limit`` devices)."""
    shown = analysis.devices[:limit]
    t = _table("Devices" if len(shown) == len(analysis.devices) else f"Devices ({len(analysis.devices):,})")
    t.add_column("", style="bold", no_wrap=True)
    if len(shown) < len(analysis.devices):
        t.caption = Text(f"first {len(shown)} of {len(analysis.devices):,} devices; --json has all")
    for d in shown:
        t.add_column(inert(f"ID {d.device_id}"), overflow="fold")
    fields: list[tuple[str, Callable[[DeviceInventory], object]]] = [
        ("Device / Type / GS", lambda d: f"{d.device} / {d.type} / {d.gs}"),
        ("Counting heads", lambda d: ", ".join(d.counting_heads)),
        ("Channels", lambda d: ", ".join(str(c) for c in d.channels)),
        ("Designation", lambda d: d.designation),
        ("Type number", lambda d: d.type_number),
        ("Hardware state", lambda d: d.hardware_state),
        ("Serial number", lambda d: d.serial_number),
        ("Software version", lambda d: d.software_version),
        ("CRC", lambda d: d.crc),
        ("Records", lambda d: f"{d.records:,}"),
        ("First record", lambda d: (iso(d.first_ns) or "").replace("T", " ")),
        ("Last record", lambda d: (iso(d.last_ns) or "").replace("T", " ")),
    ]
    for name, get in fields:
        t.add_row(name, *(inert(get(d) or "–") for d in shown))
    return t


def passages_table(analysis: DiagAnalysis, limit: int | None = None, first: FirstPassages | None = None) -> Table:
    """The passages (the first ``limit``), from the analysis or, when it holds none, from ``first``."""
    p, status, total = _listed_passages(analysis, limit, first)
    t = _table(f"Passages ({total}); speeds in km/h: per-second method (records), whole train, per-axle mean")
    t.add_column("Head", no_wrap=True, min_width=4)
    t.collapse_padding = True  # whole-second bounds widen a column: still 80 columns
    t.add_column("Start", no_wrap=True)
    t.add_column("Dur s", justify="right", no_wrap=True)
    t.add_column("Recs", justify="right", no_wrap=True)
    t.add_column("Axles", no_wrap=True)
    t.add_column("Per-sec", justify="right", no_wrap=True)
    t.add_column("Whole", justify="right", no_wrap=True)
    t.add_column("Axle", justify="right", no_wrap=True)
    rows = p if limit is None else p.head(limit)
    r: Any
    for r in rows.itertuples(index=False):
        per_sec = _num(r.speed_kmh_per_second_method)
        if not pd.isna(r.records_in_detection_second):
            per_sec.append(f"({int(r.records_in_detection_second)})", style="dim")
        axles = Text(str(r.axles))
        if not pd.isna(r.direction):
            axles.append(" " + _ARROWS.get(r.direction, str(r.direction)), style="cyan")
        t.add_row(
            inert(r.counting_head),
            _time(r.start_ns),
            _num(r.duration_s, "{:.2f}"),
            Text(f"{r.records:,}"),
            axles,
            per_sec,
            _whole_train(r),
            _num(r.speed_kmh_per_axle_mean),
        )
    notes = []
    if len(p) and (p["time_resolution_s"] >= 1).any():
        notes.append("whole train from whole-second times: figure, then its bounds (min–max)")
    if limit is not None and total > limit:
        notes.append(f"first {limit} of {total} passages; --json has all")
    if status:
        notes.append(f"{status} status-only record bursts (no wheel) not shown; --json has them (kind: status)")
    if notes:
        t.caption = Text("; ".join(notes))  # Text: brackets in a note are not markup
    return t


def _listed_passages(
    analysis: DiagAnalysis, limit: int | None, first: FirstPassages | None = None
) -> tuple[pd.DataFrame, int, int]:
    """The passages to list (no status-only ones), how many status-only, and how many listed in all.

    With a limit, only the rows shown become a table: a log of a million heads
    has a passage per head.
    """
    from console.analysis.diagnostics import PASSAGE_KINDS, passages_frame

    cols = analysis.passage_columns
    if first is not None and cols is None:  # the job kept only the first rows (analyze's text face)
        return passages_frame(first.cols, analysis.heads), first.status, first.listed
    if limit is None or cols is None:
        p = analysis.passages
        status = int((p["kind"] == "status").sum()) if len(p) else 0
        return (p[p["kind"] != "status"] if status else p), status, len(p) - status

    listed = np.flatnonzero(cols["kind"] != PASSAGE_KINDS.index("status"))
    rows = take_passages(cols, listed[:limit])
    return passages_frame(rows, analysis.heads), len(cols["kind"]) - len(listed), len(listed)


def _whole_train(r: Any) -> Text:
    """Whole-train speed; from whole-second times with the bounds they allow."""
    if r.time_resolution_s < 1 or pd.isna(r.speed_kmh_whole_train):
        return _num(r.speed_kmh_whole_train, "{:.2f}")
    # The figure (as the paper prints it), then the bounds that make it honest.
    text = _num(r.speed_kmh_whole_train, "{:.2f}")
    hi = "∞" if pd.isna(r.speed_kmh_whole_train_max) else f"{r.speed_kmh_whole_train_max:.0f}"
    text.append(f" {r.speed_kmh_whole_train_min:.0f}–{hi}", style="dim")
    return text


def parse_report_table(report: ParseReport) -> Table:
    t = _table("Parse report")
    # Overlap: records a file repeats from another input file, counted once.
    overlap = any(f.overlap_records for f in report.files)
    columns = ("File", "Lines", "Records", "Blank", "Rejected", *(("Overlap",) if overlap else ()), "Encoding")
    for c in columns:
        t.add_column(c, justify="left" if c in ("File", "Encoding") else "right", overflow="fold")
    for f in report.files:
        enc = f.encoding + (", gzip" if f.compressed else "") + (", no final newline" if f.ends_without_newline else "")
        t.add_row(
            inert(f.file),
            Text(f"{f.lines_read:,}"),
            Text(f"{f.records:,}"),
            Text(f"{f.blank:,}"),
            Text(f"{f.rejected:,}", style="bold red" if f.rejected else ""),
            *((Text(f"{f.overlap_records:,}"),) if overlap else ()),
            Text(enc),
        )
    if len(report.files) > 1:
        total_overlap = sum(f.overlap_records for f in report.files)
        t.add_row(
            Text("total", style="bold"),
            Text(f"{report.lines_read:,}"),
            Text(f"{report.records:,}"),
            Text(f"{report.blank:,}"),
            Text(f"{report.rejected:,}"),
            *((Text(f"{total_overlap:,}"),) if overlap else ()),
            Text(""),
        )
    return t


def rejections_table(report: ParseReport, limit: int = REJECTIONS_SHOWN) -> Table | None:
    if not report.rejected:
        return None
    t = _table(f"Rejected lines ({report.rejected:,})")
    t.add_column("File:line")
    t.add_column("Reason")
    t.add_column("Text")
    for r in report.rejections[:limit]:
        t.add_row(inert(f"{r.file}:{r.line}"), inert(r.reason), inert(r.text, style="dim"))
    if report.rejected > limit:
        shown = min(limit, len(report.rejections))
        t.caption = f"first {shown} of {report.rejected:,} shown; --json lists up to {report.max_rejections_kept}"
    return t
