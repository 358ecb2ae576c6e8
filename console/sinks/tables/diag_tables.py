"""Rich tables for `trackside analyze` / `speeds`: inventory, passages, parse report."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from rich import box
from rich.table import Table
from rich.text import Text

from console import plural
from console.analysis.timefmt import display, iso
from console.safe_text import inert
from parsers.report import ParseReport

if TYPE_CHECKING:  # the parse report tables (gnss) need neither the analysis nor Arrow behind it
    from console.analysis.inventory import DeviceInventory
    from console.analysis.passages.diag_analysis import DiagAnalysis
    from console.sinks.tables.passage_spool import FirstPassages

REJECTIONS_SHOWN = 20
DEVICES_SHOWN = 6  # devices are columns: more do not fit in 80
_ARROWS = {"sys1_to_sys2": "1→2", "sys2_to_sys1": "2→1"}


def _num(value: object, fmt: str = "{:.1f}") -> Text:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return Text("–", style="dim")
    return Text(fmt.format(value))


def _time(ns: Any) -> Text:
    if ns is None or (isinstance(ns, float) and math.isnan(ns)):
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


def passages_table(
    analysis: DiagAnalysis, limit: int | None = None, first: FirstPassages | None = None, unpaired: int = 0
) -> Table:
    """The passages (the first ``limit``), from the analysis or, when it holds none, from ``first``.

    Axles no onset pair could give are "–", and the caption says why; ``unpaired`` (the log's wheel
    detections on one system only) is told there too, beyond those of the "–" passages.  Rows are read
    from numpy columns: a small log's table needs no pandas (start-up time).
    """
    from console.analysis.passages.buckets import axles_unknown_codes

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
    n = len(p["start_ns"]) if limit is None else min(limit, len(p["start_ns"]))
    p = {k: v[:n] for k, v in p.items()}
    unknown = axles_unknown_codes(p["detections_sys1"], p["detections_sys2"])
    for i in range(n):
        per_sec = _num(_at(p, "speed_kmh_per_second_method", i))
        in_second = _at(p, "records_in_detection_second", i)
        if in_second is not None:
            per_sec.append(f"({int(in_second)})", style="dim")
        axles = Text("–" if unknown[i] else str(int(p["axles"][i])))
        direction = p["direction"][i]
        if direction is not None:
            axles.append(" " + _ARROWS.get(direction, str(direction)), style="cyan")
        t.add_row(
            inert(p["counting_head"][i]),
            _time(p["start_ns"][i]),
            _num(_at(p, "duration_s", i), "{:.2f}"),
            Text(f"{int(p['records'][i]):,}"),
            axles,
            per_sec,
            _whole_train(p, i),
            _num(_at(p, "speed_kmh_per_axle_mean", i)),
        )
    notes = []
    if n and (p["time_resolution_s"] >= 1).any():
        notes.append("whole train from whole-second times: figure, then its bounds (min–max)")
    if limit is not None and total > limit:
        notes.append(f"first {limit} of {total} passages; --json has all")
    if status:
        notes.append(
            f"{plural.count(status, 'status-only record burst')} (no wheel) not shown; --json has them (kind: status)"
        )
    blind = unknown > 0
    if blind.any():
        notes.append("Axles –: wheel onsets on one system only, or none: no axle can be paired")
    shown_unpaired = int(p["detections_sys1"][blind].sum() + p["detections_sys2"][blind].sum())
    if unpaired > shown_unpaired:
        more = unpaired - shown_unpaired
        other = "other " if blind.any() else ""
        notes.append(
            f"{more} {other}{'wheel detection' if more == 1 else 'wheel detections'} on one system only (not axles)"
        )
    if notes:
        t.caption = Text("\n".join(notes))  # one note a line; Text: brackets in a note are not markup
    return t


# The passage columns a table row shows.
_SHOWN = (
    "counting_head",
    "start_ns",
    "duration_s",
    "records",
    "axles",
    "direction",
    "detections_sys1",
    "detections_sys2",
    "records_in_detection_second",
    "speed_kmh_per_second_method",
    "speed_kmh_whole_train",
    "speed_kmh_whole_train_min",
    "speed_kmh_whole_train_max",
    "speed_kmh_per_axle_mean",
    "time_resolution_s",
)


def _at(p: dict[str, np.ndarray], column: str, i: int) -> float | None:
    """A number of row ``i``; None where it is missing (NaN)."""
    value = float(p[column][i])
    return None if math.isnan(value) else value


def _listed_passages(
    analysis: DiagAnalysis, limit: int | None, first: FirstPassages | None = None
) -> tuple[dict[str, np.ndarray], int, int]:
    """The passages to list (no status-only ones) as columns, how many status-only, and how many listed in all.

    With a limit, only the rows shown are looked up: a log of a million heads has a passage per head.
    """
    from console.analysis.passages.passage_frame import PASSAGE_KINDS

    cols = analysis.passage_columns
    if first is not None and cols is None:  # the job kept only the first rows (analyze's text face)
        return _shown_columns(first.cols, analysis), first.status, first.listed
    if limit is None or cols is None:
        p = analysis.passages
        status = int((p["kind"] == "status").sum()) if len(p) else 0
        listed = p[p["kind"] != "status"] if status else p
        out = {c: listed[c].to_numpy() for c in _SHOWN}
        # A missing direction may read as NaN in pandas' string dtype: None, as the columns give it.
        out["direction"] = np.array([d if isinstance(d, str) else None for d in out["direction"]], dtype=object)
        return out, status, len(p) - status
    from console.analysis.passages.stream import take_passages

    keep = np.flatnonzero(cols["kind"] != PASSAGE_KINDS.index("status"))
    rows = take_passages(cols, keep[:limit])
    return _shown_columns(rows, analysis), len(cols["kind"]) - len(keep), len(keep)


def _shown_columns(cols: Any, analysis: DiagAnalysis) -> dict[str, np.ndarray]:
    """The shown columns from ``passage_columns.passage_columns`` columns (codes turned into names), without pandas."""
    from console.analysis.counting.wheels import DIRECTION_12, DIRECTION_21
    from console.analysis.head_table import heads_at

    if cols is None or len(cols["head"]) == 0:
        return {c: np.zeros(0, object if c in ("counting_head", "direction") else np.float64) for c in _SHOWN}
    used, inverse = np.unique(cols["head"], return_inverse=True)
    _, names = heads_at(analysis.heads, used)
    head_names = np.empty(len(used), dtype=object)
    head_names[:] = names
    out = {c: np.asarray(cols[c]) for c in _SHOWN if c not in ("counting_head", "direction")}
    out["counting_head"] = head_names[inverse.reshape(-1)]
    out["direction"] = np.array([None, DIRECTION_12, DIRECTION_21, "mixed"], dtype=object)[cols["direction"]]
    return out


def _whole_train(p: dict[str, np.ndarray], i: int) -> Text:
    """Whole-train speed; from whole-second times with the bounds they allow."""
    whole = _at(p, "speed_kmh_whole_train", i)
    text = _num(whole, "{:.2f}")
    if float(p["time_resolution_s"][i]) < 1 or whole is None:
        return text
    # The figure (as the paper prints it), then the bounds that make it honest.
    high = _at(p, "speed_kmh_whole_train_max", i)
    low = _at(p, "speed_kmh_whole_train_min", i)
    text.append(f" {low:.0f}–{'∞' if high is None else f'{high:.0f}'}", style="dim")
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
