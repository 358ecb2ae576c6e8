"""Rich tables for `trackside frames`: per-sensor summary and the events."""

from __future__ import annotations

from collections import Counter

import pandas as pd
from rich import box
from rich.table import Table
from rich.text import Text

from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.timefmt import display
from console.safe_text import inert
from parsers.frames.can_report import CanFileReport
from parsers.report import ParseReport


def _table(title: str) -> Table:
    return Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, title_style="bold")


def sensor_summary_table(frames: pd.DataFrame, events: list[DetectionEvent]) -> Table:
    tally: dict[str, Counter[str]] = {}
    for e in events:
        kinds = tally.setdefault(e.head, Counter())
        if e.kind is EventKind.AXLE:
            # 0: a sensor the layout does not orient; its axles are neither up nor down.
            kinds["up" if e.direction > 0 else "down" if e.direction < 0 else "unknown"] += 1
        else:
            kinds[str(e.kind)] += 1
    unknown = any(k["unknown"] for k in tally.values())
    what = "axles up / down" + (" / ? unknown" if unknown else "")
    t = _table(f"Sensors ({what}; faults, count errors, contact losses)")
    t.collapse_padding = unknown  # one column more still fits 80 columns
    columns = ("Sensor", "Frames", "From", "To", "Up", "Down", *(("?",) if unknown else ()), "Fault", "Err", "Lost")
    for c in columns:
        t.add_column(c, justify="left" if c in ("Sensor", "From", "To") else "right", no_wrap=True, min_width=len(c))
    if frames.empty:
        return t
    days = sorted({display(int(x.value))[:10] for x in (frames["time"].min(), frames["time"].max())})
    t.title = f"Sensors, {' to '.join(days)} ({what}; faults, count errors, contact losses)"
    for sensor, times in frames.groupby("sensor", observed=True)["time"]:
        k = tally.get(str(sensor), Counter())
        t.add_row(
            inert(sensor),
            Text(str(len(times))),
            Text(display(int(times.min().value))[11:]),
            Text(display(int(times.max().value))[11:]),
            Text(str(k["up"])),
            Text(str(k["down"])),
            *((Text(str(k["unknown"]), style="yellow" if k["unknown"] else ""),) if unknown else ()),
            Text(str(k["channel_fault"]), style="bold red" if k["channel_fault"] else ""),
            Text(str(k["count_error"]), style="yellow" if k["count_error"] else ""),
            Text(str(k["power_loss"]), style="yellow" if k["power_loss"] else ""),
        )
    return t


def events_table(events: list[DetectionEvent], limit: int = 200) -> Table:
    """Every event except axles (they are summed per sensor above)."""
    rest = [e for e in events if e.kind is not EventKind.AXLE]
    t = _table(f"Events other than axles ({len(rest)})")
    for c in ("Time", "Sensor", "Event", "Channel", "Detail"):
        t.add_column(c, no_wrap=c != "Detail")
    for e in rest[:limit]:
        t.add_row(
            Text(display(e.time_ns)),
            inert(e.head),
            Text(str(e.kind)),
            Text("–" if e.channel is None else str(e.channel)),
            inert(e.detail),
        )
    if len(rest) > limit:
        t.caption = f"first {limit} of {len(rest)}; --json has all"
    return t


def can_traffic_table(report: ParseReport) -> Table:
    """Per CAN log: its lines, the frames by kind and what was not a frame; the columns add up to Lines."""
    t = _table("CAN traffic (lines = count + foreign + remote + error + no frame + rejected)")
    t.add_column("File (format)", overflow="fold")
    for c in ("Lines", "Count", "Foreign", "Remote", "Error", "No frame", "Rejected"):
        t.add_column(c, justify="right", no_wrap=True, min_width=len(c))
    for f in report.files:
        if not isinstance(f, CanFileReport):
            continue
        fmt = f.format + (", gzip" if f.compressed else "")
        t.add_row(
            inert(f"{f.file} ({fmt})"),
            Text(f"{f.lines_read:,}"),
            Text(f"{f.count_frames:,}"),
            Text(f"{f.foreign:,}"),
            Text(f"{f.remote_frames:,}"),
            Text(f"{f.error_frames:,}", style="yellow" if f.error_frames else ""),
            Text(f"{f.blank:,}"),
            Text(f"{f.rejected:,}", style="bold red" if f.rejected else ""),
        )
    return t


def other_frames_table(frames: pd.DataFrame, limit: int = 50) -> Table | None:
    """CAN frames that are no sensor's count frame, by kind and id: how many, when, the last payload."""
    if frames.empty or "kind" not in frames.columns:
        return None
    other = frames[frames["kind"] != "count"]
    if other.empty:
        return None
    t = _table(f"Other CAN frames ({len(other):,}): not count frames, by kind and id")
    for c in ("Kind", "Id", "Frames", "From", "To", "Last data"):
        t.add_column(c, justify="right" if c == "Frames" else "left", no_wrap=True, min_width=len(c))
    days = sorted({display(int(x.value))[:10] for x in (other["time"].min(), other["time"].max())})
    t.title = f"Other CAN frames ({len(other):,}), {' to '.join(days)}: not count frames, by kind and id"
    groups = other.groupby(["kind", "can_id", "extended"], observed=True, sort=True)
    for n, ((kind, can_id, extended), g) in enumerate(groups):
        if n == limit:
            t.caption = f"first {limit} kinds and ids; --json lists every frame"
            break
        number = int(str(can_id))
        ident = "–" if kind == "error" else (f"{number:08X}x" if extended else f"{number:03X}")
        t.add_row(
            Text(str(kind)),
            Text(ident),
            Text(f"{len(g):,}"),
            Text(display(int(g["time"].min().value))[11:]),
            Text(display(int(g["time"].max().value))[11:]),
            inert(str(g["data"].iloc[-1]) or "–"),
        )
    return t
