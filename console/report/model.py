"""What a report holds (:class:`ReportData`) and its JSON form (schema ``trackside.report/1``).

:func:`document` turns the analyses into plain JSON values, in the order
the report presents them (docs/report-schema.md).  :func:`outline` turns
that document into headings, paragraphs and tables; the Markdown and HTML
faces render the outline, so the three formats cannot disagree.  Nothing
here computes what the analysis modules compute: it selects, groups and
names.

Safety classes (the report's first part):

* **unsafe** (counted as ``critical`` by ``--fail-on``): a level-crossing
  timeline with a safety violation (the road open with the train on it),
  and every critical health finding (a faulty channel, an analog value
  drifted out of its band: a head that may stop detecting);
* **failing** (counted as ``warning``): a section that ended the log
  disturbed (fail-safe: it shows occupied until a reset, so trains are
  stopped, not endangered), a refused reset, a crossing warning held on
  after the head arrived with the tail never confirmed clear (the road
  stays closed), and every warning-level health finding.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pandas as pd

from console import __version__
from console.analysis.crossing_batch import CrossingRun
from console.analysis.crossing_timeline import TimelineRow
from console.analysis.diagnostics import SpeedSettings, passages_json_text
from console.analysis.events import DetectionEvent, EventKind
from console.analysis.health import Finding, Severity
from console.analysis.sections import SectionsResult, SectionState
from console.analysis.timefmt import iso
from console.jobs import DiagJob
from console.layout import Layout
from console.render.section_tables import sections_json
from parsers.report import ParseReport

SCHEMA = "trackside.report/1"

# Input formats, as the input summary names them.
DIAGNOSTIC = "diagnostic"
NMEA = "nmea"
GNSS_CSV = "gnss-csv"
GNSS_JSONL = "gnss-jsonl"
CENTRE = "centre"
FRAMES = "frames"
CAN = "can"
VOLTAGES = "voltages"
LAYOUT = "layout"
TRUTH = "truth"
EMPTY = "empty"
UNKNOWN = "unknown"
GNSS_FORMATS = (NMEA, GNSS_CSV, GNSS_JSONL, CENTRE)

# Parse reports by kind, in the order the report lists them.
REPORT_KINDS = ("diagnostic", "gnss", "frames", "can", "voltages")

UNSAFE = "unsafe"
FAILING = "failing"
SECTION_INITIAL = "unknown"  # each section starts preparatory: the log does not say the line was empty


@dataclass(frozen=True)
class InputFile:
    """One input file: what it was recognised as, whether it was read, and why not."""

    path: str  # as given (a directory's files: the directory as given / the relative path)
    format: str
    read: bool
    note: str = ""


@dataclass(frozen=True)
class Attention:
    """One item of the report's first part: unsafe or failing."""

    severity: Severity  # CRITICAL for unsafe, WARNING (or a finding's own) for failing
    safety: str  # UNSAFE | FAILING
    topic: str  # crossing | health | section | reset
    subject: str
    time_ns: int | None
    message: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "class": self.safety,
            "severity": str(self.severity),
            "topic": self.topic,
            "subject": self.subject,
            "time": iso(self.time_ns),
            "message": self.message,
        }


@dataclass
class ReportData:
    """Everything the report shows, as the analyses returned it."""

    inputs: list[InputFile]
    layout: Layout | None
    settings: SpeedSettings
    job: DiagJob | None = None
    events: list[DetectionEvent] = field(default_factory=list)  # from the diagnostic logs
    sections: SectionsResult | None = None
    section_source: str | None = None  # "diagnostic" | "frames": where the section events came from
    findings: list[Finding] = field(default_factory=list)
    frames: pd.DataFrame | None = None  # sensor and CAN frames together
    frame_events: list[DetectionEvent] = field(default_factory=list)
    fixes: pd.DataFrame | None = None
    crossing: CrossingRun | None = None
    reports: dict[str, ParseReport] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)  # part → why it is empty

    def attention(self) -> list[Attention]:
        """Unsafe items first, then failing ones; each in time order."""
        items: list[Attention] = []
        if self.crossing is not None:
            for tl_row in self.crossing.timelines:
                for v in tl_row.violations:
                    items.append(
                        Attention(
                            Severity.CRITICAL,
                            UNSAFE,
                            "crossing",
                            f"{tl_row.crossing} train {tl_row.train}",
                            tl_row.t_head_arrival_ns or tl_row.t_on_ns,
                            v,
                        )
                    )
        for f in self.findings:
            if f.severity is Severity.CRITICAL:
                items.append(Attention(f.severity, UNSAFE, "health", _where(f), f.time_ns, f.message))
        if self.sections is not None:
            tl = self.sections.timeline
            for sid, (state, count, _in, _out, reason) in self.sections.final.items():
                if state == SectionState.DISTURBED:
                    rows = tl[(tl["section"] == sid) & (tl["state"] == state)]
                    since = int(rows["time_ns"].iloc[-1]) if len(rows) else None
                    items.append(
                        Attention(
                            Severity.WARNING,
                            FAILING,
                            "section",
                            f"section {sid}",
                            since,
                            f"ended the log disturbed (count {count}): {reason}; needs a reset and a sweep train",
                        )
                    )
            r: Any
            for r in self.sections.resets.itertuples(index=False):
                if not r.accepted:
                    items.append(
                        Attention(
                            Severity.WARNING,
                            FAILING,
                            "reset",
                            f"section {r.section}",
                            int(r.time_ns),
                            f"reset refused: {r.reason}",
                        )
                    )
        if self.crossing is not None:
            for row in self.crossing.timelines:
                # A train still approaching when the data ends is not a fault; one that reached the
                # crossing with its tail never confirmed clear keeps the road closed.
                if row.t_off_ns is None and row.t_head_arrival_ns is not None:
                    items.append(
                        Attention(
                            Severity.WARNING,
                            FAILING,
                            "crossing",
                            f"{row.crossing} train {row.train}",
                            row.t_head_arrival_ns,
                            f"warning held on after the head arrived ({row.reason_off or 'no tail clear'}): "
                            "the road stays closed",
                        )
                    )
        for f in self.findings:
            if f.severity is Severity.WARNING:
                items.append(Attention(f.severity, FAILING, "health", _where(f), f.time_ns, f.message))
        order = {UNSAFE: 0, FAILING: 1}
        return sorted(
            items, key=lambda a: (order[a.safety], -1 if a.time_ns is None else a.time_ns, a.topic, a.subject)
        )

    def worst(self) -> Severity | None:
        """The highest severity among health findings and attention items (None: nothing at all)."""
        sev = [f.severity for f in self.findings] + [a.severity for a in self.attention()]
        return max(sev, key=lambda s: s.rank) if sev else None

    def data_end_ns(self) -> int | None:
        """The last time any log speaks of: where open-ended bars of the plots stop."""
        ends: list[int] = []
        if self.job is not None:
            ends += [d.last_ns for d in self.job.analysis.devices if d.last_ns]
        if self.frames is not None and len(self.frames):
            ends.append(int(self.frames["time"].max().value))
        ends += [e.time_ns for e in self.events[-1:] + self.frame_events[-1:]]
        if self.sections is not None and len(self.sections.timeline):
            ends.append(int(self.sections.timeline["time_ns"].max()))
        return max(ends) if ends else None


_NUMBER_PARTS = re.compile(r"(\d+)")


def natural_key(text: str) -> tuple[Any, ...]:
    """``WS10`` after ``WS9``, train ``T10`` after ``T2``."""
    return tuple(int(p) if i % 2 else p.casefold() for i, p in enumerate(_NUMBER_PARTS.split(text)))


def timeline_order(r: TimelineRow) -> tuple[Any, ...]:
    """Crossing timelines per crossing, then in the order the trains arrived."""
    t = r.t_head_arrival_ns if r.t_head_arrival_ns is not None else r.t_on_ns
    return (natural_key(r.crossing), -1 if t is None else t, natural_key(r.train))


def _where(f: Finding) -> str:
    if f.rule == "voltage_margin":
        return f"sensor {f.counting_head}"
    where = f.counting_head or "–"
    if f.channel is not None:
        where += f" Sys{f.channel}" if f.channel in (1, 2) else f" ch {f.channel}"
    return where


def _f(x: Any, digits: int = 3) -> float | None:
    """A finite float rounded for the document, else None."""
    if x is None:
        return None
    v = float(x)
    return None if not math.isfinite(v) else round(v, digits)


# ----------------------------------------------------------------------------- document


def _inputs(data: ReportData) -> dict[str, Any]:
    by_file: dict[str, tuple[str, dict[str, Any]]] = {}
    for kind in REPORT_KINDS:
        rep = data.reports.get(kind)
        if rep is not None:
            for fr in rep.files:
                by_file[fr.file] = (kind, fr.to_dict())
    rows = []
    for inp in data.inputs:
        _kind, fr_dict = by_file.get(inp.path, ("", {}))
        rows.append(
            {
                "file": inp.path,
                "format": inp.format,
                "read": inp.read,
                "note": inp.note,
                "lines_read": fr_dict.get("lines_read"),
                "records": fr_dict.get("records"),
                "blank": fr_dict.get("blank"),
                "rejected": fr_dict.get("rejected"),
                "bytes_read": fr_dict.get("bytes_read"),
                "encoding": fr_dict.get("encoding"),
                "compressed": fr_dict.get("compressed"),
            }
        )
    reports = [data.reports[k] for k in REPORT_KINDS if k in data.reports]
    rejections = [r.to_dict() for rep in reports for r in rep.rejections]
    by_reason: Counter[str] = Counter()
    unknown_labels: Counter[str] = Counter()
    for rep in reports:
        by_reason.update(rep.rejected_by_reason)
        unknown_labels.update(rep.unknown_labels)
    return {
        "files": rows,
        "totals": {
            "files": len(rows),
            "read": sum(1 for r in rows if r["read"]),
            "lines_read": sum(rep.lines_read for rep in reports),
            "records": sum(rep.records for rep in reports),
            "blank": sum(rep.blank for rep in reports),
            "rejected": sum(rep.rejected for rep in reports),
        },
        "rejections": rejections,
        "rejected_by_reason": dict(sorted(by_reason.items())),
        "unknown_labels": dict(sorted(unknown_labels.items())),
    }


def _sensors(data: ReportData) -> list[dict[str, Any]]:
    """Frame and CAN sensors: frames, span, and their events tallied by kind."""
    frames = data.frames
    if frames is None or frames.empty:
        return []
    tally: dict[str, Counter[str]] = {}
    for e in data.frame_events:
        kinds = tally.setdefault(e.head, Counter())
        if e.kind is EventKind.AXLE:
            kinds["up" if e.direction > 0 else "down" if e.direction < 0 else "unknown"] += 1
        else:
            kinds[str(e.kind)] += 1
    out = []
    groups = frames.groupby(frames["sensor"].astype(str), sort=True)["time"]
    for sensor, times in sorted(groups, key=lambda g: natural_key(str(g[0]))):
        k = tally.get(str(sensor), Counter())
        out.append(
            {
                "sensor": str(sensor),
                "frames": len(times),
                "first": iso(int(times.min().value)),
                "last": iso(int(times.max().value)),
                "axles_up": k["up"],
                "axles_down": k["down"],
                "axles_unknown_direction": k["unknown"],
                "channel_faults": k[str(EventKind.CHANNEL_FAULT)],
                "count_errors": k[str(EventKind.COUNT_ERROR)],
                "contact_losses": k[str(EventKind.POWER_LOSS)],
            }
        )
    return out


def _gnss_units(data: ReportData) -> list[dict[str, Any]]:
    fixes = data.fixes
    if fixes is None or fixes.empty:
        return []
    out = []
    groups = fixes.groupby(fixes["device"].astype(str), sort=True)
    for device, rows in sorted(groups, key=lambda g: natural_key(str(g[0]))):
        roles = sorted({str(x) for x in rows["role"]} - {""})
        valid = rows[rows["valid"].astype(bool)]
        times = rows["time"].dropna()
        out.append(
            {
                "device": str(device),
                "role": "/".join(roles) or None,
                "sources": sorted({str(x) for x in rows["source"]}),
                "fixes": len(rows),
                "valid": len(valid),
                "first": iso(int(times.min().value)) if len(times) else None,
                "last": iso(int(times.max().value)) if len(times) else None,
            }
        )
    return out


def _passages(data: ReportData) -> tuple[list[dict[str, Any]], int]:
    if data.job is None:
        return [], 0
    p = data.job.analysis.passages
    status = int((p["kind"] == "status").sum()) if len(p) else 0
    shown = p[p["kind"] != "status"] if status else p
    # The same passage objects as `trackside analyze --json`.
    return list(json.loads(passages_json_text(shown))), status


def _ledger_summary(result: SectionsResult) -> list[dict[str, Any]]:
    led = result.ledger
    if led.empty:
        return []
    out = []
    for (section, head), g in led.groupby(["section", "head"], sort=True):
        d = g["delta"].to_numpy()
        out.append(
            {
                "section": str(section),
                "head": str(head),
                "count_in": int((d > 0).sum()),
                "count_out": int((d < 0).sum()),
                "first": iso(int(g["time_ns"].min())),
                "last": iso(int(g["time_ns"].max())),
            }
        )
    return out


def _sections(data: ReportData) -> dict[str, Any] | None:
    if data.sections is None:
        return None
    body = sections_json(data.sections)
    return {
        "initial": SECTION_INITIAL,
        "events_from": data.section_source,
        "final": body["sections"],
        "timeline": body["timeline"],
        "ledger_summary": _ledger_summary(data.sections),
        "ledger": body["ledger"],
        "resets": body["resets"],
    }


def analog_series(data: ReportData) -> pd.DataFrame:
    """The analog receiver values (``analog_value`` registers) as time_ns, head, channel, address, value."""
    cols = ["time_ns", "head", "channel", "address", "value"]
    rec = data.job.records if data.job is not None else pd.DataFrame()
    if rec.empty or "label_canonical" not in rec.columns:
        return pd.DataFrame(columns=cols)
    pick = rec[rec["label_canonical"] == "analog_value"]
    return (
        pd.DataFrame(
            {
                "time_ns": pick["time"].to_numpy(dtype="datetime64[ns]").view(np.int64),
                "head": pick["counting_head"].astype(str).to_numpy(),
                "channel": pick["channel"].to_numpy(dtype=np.int64),
                "address": pick["address"].to_numpy(dtype=np.int64),
                "value": pick["value"].to_numpy(dtype=np.float64),
            },
            columns=cols,
        )
        .sort_values(["head", "channel", "address", "time_ns"], kind="stable")
        .reset_index(drop=True)
    )


def _analog(data: ReportData) -> list[dict[str, Any]]:
    series = analog_series(data)
    out = []
    for key, g in series.groupby(["head", "channel", "address"], sort=True):
        head, channel, address = cast(tuple[str, int, int], key)
        v = g["value"].to_numpy()
        out.append(
            {
                "counting_head": str(head),
                "channel": int(channel),
                "address": int(address),
                "values": len(v),
                "min": _f(v.min()),
                "mean": _f(v.mean()),
                "max": _f(v.max()),
                "first": iso(int(g["time_ns"].min())),
                "last": iso(int(g["time_ns"].max())),
            }
        )
    return out


def _crossings(data: ReportData) -> dict[str, Any] | None:
    run = data.crossing
    if run is None:
        return None
    return {
        "violations": sum(1 for r in run.timelines if r.violations),
        "timelines": [r.to_dict() for r in sorted(run.timelines, key=timeline_order)],
        "events": [
            {"time": iso(e.t_ns), "crossing": e.crossing, "train": e.train, "kind": e.kind, "reason": e.reason}
            for e in run.events
        ],
        "trains": [
            {"train": t.train, "head": list(t.head), "eot": list(t.eot), "length_m": t.length_m}
            for t in sorted(run.trains, key=lambda t: natural_key(t.train))  # T2 before T10
        ],
        "off_track_fixes": run.off_track,
        "unassigned_devices": list(run.unassigned_devices),
    }


def document(data: ReportData) -> dict[str, Any]:
    """The report as plain JSON values (schema ``trackside.report/1``), in presentation order."""
    attention = data.attention()
    unsafe = sum(1 for a in attention if a.safety == UNSAFE)
    failing = len(attention) - unsafe
    worst = data.worst()
    passages, status = _passages(data)
    counts = Counter(str(f.severity) for f in data.findings)
    analysis = data.job.analysis if data.job is not None else None
    s = data.settings
    return {
        "schema": SCHEMA,
        "trackside_version": __version__,
        "layout": data.layout.source if data.layout is not None else None,
        "settings": {
            "spacing_m": s.spacing_m,
            "train_length_m": s.train_length_m,
            "idle_gap_s": s.idle_gap_s,
            "pair_window_s": round(s.pair_window_s, 6),
            "section_initial": SECTION_INITIAL,
        },
        "verdict": UNSAFE if unsafe else FAILING if failing else "ok",
        "worst_severity": None if worst is None else str(worst),
        "safety": {"unsafe": unsafe, "failing": failing, "items": [a.to_dict() for a in attention]},
        "inputs": _inputs(data),
        "devices": [d.to_dict() for d in analysis.devices] if analysis is not None else [],
        "sensors": _sensors(data),
        "gnss_units": _gnss_units(data),
        "passages": passages,
        "status_bursts": status,
        "overlap_records": analysis.overlap_records if analysis is not None else 0,
        "unpaired_detections": analysis.unpaired_detections if analysis is not None else 0,
        "sections": _sections(data),
        "health": {
            "counts": {k: counts.get(k, 0) for k in ("critical", "warning", "info")},
            "findings": [f.to_dict() for f in data.findings],
            "analog": _analog(data),
        },
        "crossings": _crossings(data),
        "warnings": list(data.warnings),
        "notes": dict(sorted(data.notes.items())),
    }


def json_text(doc: dict[str, Any]) -> str:
    """Indented, ASCII-only, key order as built: the same document gives the same bytes."""
    return json.dumps(doc, ensure_ascii=True, indent=1, allow_nan=False) + "\n"


# ----------------------------------------------------------------------------- outline
#
# The document as blocks.  Every string in a block is raw text (from a log or
# not); the renderers escape all of it for their format.


@dataclass(frozen=True)
class Styled:
    """Text with a style hint the HTML face shows (state, severity, verdict); Markdown shows the text."""

    text: str
    style: str = ""


Cell = str | Styled


@dataclass(frozen=True)
class Heading:
    level: int
    text: str
    anchor: str = ""


@dataclass(frozen=True)
class Para:
    parts: tuple[Cell, ...]


@dataclass(frozen=True)
class Table:
    columns: tuple[str, ...]
    numeric: tuple[bool, ...]  # right-aligned columns
    rows: list[list[Cell]]
    note: str = ""


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]


@dataclass(frozen=True)
class Figure:
    plot: str  # speeds | sections | crossings | analog: drawn by the HTML face from ReportData


Block = Heading | Para | Table | Bullets | Figure

TIMELINE_ROWS_SHOWN = 400
REJECTIONS_SHOWN = 20
STATE_MARKS = {"clear": "·", "occupied": "#", "disturbed": "!", "preparatory": "?"}
SEVERITY_MARKS = {"critical": "!!", "warning": "!", "info": "·"}
_ARROWS = {"sys1_to_sys2": "1→2", "sys2_to_sys1": "2→1", "mixed": "mixed"}


def show_time(text: str | None) -> str:
    """ISO 8601 → ``2026-03-02 08:00:00.500`` (milliseconds when the time has a fraction); None → ``–``."""
    if not text:
        return "–"
    day, _, clock = text.partition("T")
    whole, dot, frac = clock.partition(".")
    return f"{day} {whole}" + (f".{(frac + '000')[:3]}" if dot else "")


def _clock(text: str | None, day: str | None) -> str:
    """A time of day when the table's day is known, else the full time."""
    shown = show_time(text)
    return shown[11:] if day and text and text.startswith(day) else shown


def _one_day(values: list[str | None]) -> str | None:
    days = {v[:10] for v in values if v}
    return days.pop() if len(days) == 1 else None


def _n(x: Any, fmt: str = "{:.1f}") -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else fmt.format(x)


def _state(state: str) -> Styled:
    return Styled(f"{STATE_MARKS.get(state, '')} {state}".strip(), f"state-{state}")


def _severity(sev: str) -> Styled:
    return Styled(f"{SEVERITY_MARKS.get(sev, '')} {sev}".strip(), f"sev-{sev}")


def _table(columns: list[tuple[str, bool]], rows: list[list[Cell]], note: str = "") -> Table:
    return Table(tuple(c for c, _ in columns), tuple(n for _, n in columns), rows, note)


def _safety_part(doc: dict[str, Any]) -> list[Block]:
    s = doc["safety"]
    out: list[Block] = [
        Heading(2, "1. Safety violations and failing items", "safety"),
        Para(
            (
                "Unsafe: a level-crossing safety violation (the road open with the train on it) or a critical "
                "health finding (a head that may stop detecting). Failing: a section that ended disturbed "
                "(fail-safe, but trains wait for a reset), a refused reset, a crossing warning held on after the "
                "train arrived, "
                "a warning-level health finding.",
            )
        ),
    ]
    if not s["items"]:
        out.append(Para((Styled("Nothing unsafe or failing.", "ok"),)))
        return out
    rows: list[list[Cell]] = [
        [
            Styled("UNSAFE" if a["class"] == UNSAFE else "failing", a["class"]),
            _severity(a["severity"]),
            a["topic"],
            a["subject"],
            show_time(a["time"]),
            a["message"],
        ]
        for a in s["items"]
    ]
    cols = [("Class", False), ("Severity", False), ("Topic", False), ("Subject", False), ("Time", False)]
    out.append(_table([*cols, ("What", False)], rows))
    return out


def _inputs_part(doc: dict[str, Any]) -> list[Block]:
    inp = doc["inputs"]
    out: list[Block] = [Heading(2, "2. Inputs and parse report", "inputs")]
    rows: list[list[Cell]] = []
    for f in inp["files"]:
        rows.append(
            [
                f["file"],
                f["format"],
                "yes" if f["read"] else Styled("no", "muted"),
                _n(f["lines_read"], "{:,}"),
                _n(f["records"], "{:,}"),
                _n(f["blank"], "{:,}"),
                Styled(_n(f["rejected"], "{:,}"), "bad" if f["rejected"] else ""),
                f["note"],
            ]
        )
    t = inp["totals"]
    rows.append(
        [
            Styled("total", "strong"),
            "",
            f"{t['read']} of {t['files']}",
            f"{t['lines_read']:,}",
            f"{t['records']:,}",
            f"{t['blank']:,}",
            f"{t['rejected']:,}",
            "",
        ]
    )
    cols = [("File", False), ("Format", False), ("Read", False), ("Lines", True), ("Records", True)]
    out.append(_table([*cols, ("Blank", True), ("Rejected", True), ("Note", False)], rows))
    rej = inp["rejections"]
    if t["rejected"]:
        shown = rej[:REJECTIONS_SHOWN]
        out.append(Heading(3, f"Rejected lines (first {len(shown)} of {t['rejected']:,})", "rejections"))
        out.append(
            _table(
                [("File", False), ("Line", True), ("Reason", False), ("Text", False)],
                [[r["file"], str(r["line"]), r["reason"], r["text"]] for r in shown],
                "The JSON report lists up to 1,000 rejected lines per input kind.",
            )
        )
        reasons = ", ".join(f"{k} {v:,}" for k, v in inp["rejected_by_reason"].items())
        out.append(Para(("Rejected by reason: ", reasons + ".")))
    if inp["unknown_labels"]:
        labels = ", ".join(f"{k} ({v:,})" for k, v in inp["unknown_labels"].items())
        out.append(Para(("Unknown labels, kept verbatim (records): ", labels + ".")))
    if doc["warnings"]:
        out.append(Heading(3, "Warnings", "warnings"))
        out.append(Bullets(tuple(doc["warnings"])))
    return out


def _devices_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "3. Device inventory", "devices")]
    if doc["devices"]:
        out.append(Heading(3, "Axle-counter devices (diagnostic logs)", "diag-devices"))
        rows: list[list[Cell]] = []
        for d in doc["devices"]:
            ident = [
                ("designation", ""),
                ("type_number", "type "),
                ("hardware_state", "hw "),
                ("serial_number", "serial "),
                ("software_version", "sw "),
                ("crc", "CRC "),
            ]
            rows.append(
                [
                    str(d["device_id"]),
                    f"{d['device']} / {d['type']} / {d['gs']}",
                    ", ".join(d["counting_heads"]),
                    ", ".join(str(c) for c in d["channels"]),
                    ", ".join(f"{p}{d[k]}" for k, p in ident if d[k] is not None) or "–",
                    f"{d['records']:,}",
                    show_time(d["first"]),
                    show_time(d["last"]),
                ]
            )
        cols = [("Device", True), ("Device / Type / GS", False), ("Counting heads", False), ("Channels", False)]
        out.append(_table([*cols, ("Identity", False), ("Records", True), ("First", False), ("Last", False)], rows))
    if doc["sensors"]:
        out.append(Heading(3, "Intelligent sensors (frames and CAN)", "sensors"))
        rows = [
            [
                s["sensor"],
                f"{s['frames']:,}",
                show_time(s["first"]),
                show_time(s["last"]),
                str(s["axles_up"]),
                str(s["axles_down"]),
                str(s["channel_faults"]),
                str(s["count_errors"]),
                str(s["contact_losses"]),
            ]
            for s in doc["sensors"]
        ]
        cols = [("Sensor", False), ("Frames", True), ("First", False), ("Last", False), ("Axles up", True)]
        cols += [("Axles down", True), ("Faults", True), ("Count errors", True), ("Contact losses", True)]
        out.append(_table(cols, rows))
    if doc["gnss_units"]:
        out.append(Heading(3, "GNSS units (times UTC)", "gnss-units"))
        rows = [
            [
                u["device"],
                u["role"] or "–",
                ", ".join(u["sources"]),
                f"{u['fixes']:,}",
                f"{u['valid']:,}",
                show_time(u["first"]),
                show_time(u["last"]),
            ]
            for u in doc["gnss_units"]
        ]
        cols = [("Device", False), ("Role", False), ("Sources", False), ("Fixes", True), ("Valid", True)]
        out.append(_table([*cols, ("First", False), ("Last", False)], rows))
    if not (doc["devices"] or doc["sensors"] or doc["gnss_units"]):
        out.append(Para(("No devices: no diagnostic log, frame file or GNSS telemetry was read.",)))
    return out


def _passages_part(doc: dict[str, Any]) -> list[Block]:
    s = doc["settings"]
    out: list[Block] = [
        Heading(2, "4. Passages and speeds", "passages"),
        Para(
            (
                "Speeds in km/h. Per-second: the paper's method, coil spacing × records in the first detection "
                "second (the records counted in brackets). Whole train: (train length + spacing) / the entering "
                "system's first detection → the leaving system's last. Per axle: spacing / each wheel's "
                f"Sys1→Sys2 delay (logs with sub-second times), here the mean. Spacing {s['spacing_m']} m, "
                f"train length {s['train_length_m']} m; a gap of {s['idle_gap_s']:g} s ends a passage.",
            )
        ),
    ]
    if not doc["passages"]:
        out.append(Para(("No passages: no wheel detection in the diagnostic logs.",)))
    else:
        out.append(Figure("speeds"))
        rows: list[list[Cell]] = []
        for p in doc["passages"]:
            per_sec = _n(p["speed_kmh_per_second_method"])
            if p["records_in_detection_second"] is not None:
                per_sec += f" ({p['records_in_detection_second']})"
            rows.append(
                [
                    p["counting_head"],
                    show_time(p["start"]),
                    _n(p["duration_s"], "{:.2f}"),
                    str(p["axles"]),
                    _ARROWS.get(p["direction"] or "", "–"),
                    per_sec,
                    _n(p["speed_kmh_whole_train"], "{:.2f}"),
                    _n(p["speed_kmh_per_axle_mean"]),
                    Styled(p["kind"], "muted" if p["kind"] != "train" else ""),
                ]
            )
        cols = [("Head", False), ("Start", False), ("Dur s", True), ("Axles", True), ("Dir", False)]
        cols += [("Per-second", True), ("Whole train", True), ("Per-axle mean", True), ("Kind", False)]
        out.append(_table(cols, rows))
    notes = []
    if doc["status_bursts"]:
        notes.append(f"{doc['status_bursts']:,} status-only record bursts (no wheel) are counted, not listed.")
    if doc["overlap_records"]:
        notes.append(f"{doc['overlap_records']:,} records repeat another file's second and were counted once.")
    if doc["unpaired_detections"]:
        notes.append(f"{doc['unpaired_detections']:,} wheel detections on one system only (not axles).")
    if notes:
        out.append(Para((" ".join(notes),)))
    return out


def _sections_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "5. Sections", "sections")]
    sec = doc["sections"]
    if sec is None:
        out.append(Para((doc["notes"].get("sections", "No section states."),)))
        return out
    source = {"diagnostic": "the diagnostic logs", "frames": "the sensor and CAN frames"}.get(
        sec["events_from"] or "", "no events"
    )
    out.append(
        Para(
            (
                "Each section starts preparatory (? state unknown until a sweep train has run in and out): "
                f"the log does not say the line was empty. Detection events from {source}. "
                "Marks: · clear, # occupied, ! disturbed, ? preparatory.",
            )
        )
    )
    out.append(Figure("sections"))
    out.append(Heading(3, "States at the end of the data", "section-states"))
    rows: list[list[Cell]] = [
        [s["section"], _state(s["state"]), str(s["count"]), str(s["count_in"]), str(s["count_out"]), s["reason"]]
        for s in sec["final"]
    ]
    cols = [("Section", False), ("State", False), ("Count", True), ("In", True), ("Out", True), ("Why", False)]
    out.append(_table(cols, rows))
    tl = sec["timeline"]
    shown = tl[:TIMELINE_ROWS_SHOWN]
    out.append(Heading(3, f"State timeline ({len(tl):,} changes)", "section-timeline"))
    rows = [[show_time(r["time"]), r["section"], _state(r["state"]), str(r["count"]), r["reason"]] for r in shown]
    note = f"First {len(shown)} of {len(tl):,} changes; the JSON report lists all." if len(tl) > len(shown) else ""
    cols = [("Time", False), ("Section", False), ("State", False), ("Count", True), ("Why", False)]
    out.append(_table(cols, rows, note))
    out.append(Heading(3, f"Count ledger ({len(sec['ledger']):,} axles counted)", "ledger"))
    if sec["ledger_summary"]:
        rows = [
            [
                r["section"],
                r["head"],
                str(r["count_in"]),
                str(r["count_out"]),
                show_time(r["first"]),
                show_time(r["last"]),
            ]
            for r in sec["ledger_summary"]
        ]
        cols = [("Section", False), ("Head", False), ("In", True), ("Out", True), ("First", False), ("Last", False)]
        out.append(_table(cols, rows, "Axles counted in and out of each section at each head; the JSON lists each."))
    else:
        out.append(Para(("No axle was counted into or out of a section.",)))
    out.append(Heading(3, "Reset requests", "resets"))
    if sec["resets"]:
        rows = [
            [
                show_time(r["time"]),
                r["section"],
                Styled("accepted", "ok") if r["accepted"] else Styled("refused", "bad"),
                r["reason"],
            ]
            for r in sec["resets"]
        ]
        out.append(_table([("Time", False), ("Section", False), ("Result", False), ("Why", False)], rows))
    else:
        out.append(Para(("No reset requests in the data.",)))
    return out


def _health_part(doc: dict[str, Any]) -> list[Block]:
    h = doc["health"]
    c = h["counts"]
    out: list[Block] = [
        Heading(2, "6. Health findings", "health"),
        Para((f"{c['critical']} critical, {c['warning']} warning, {c['info']} info (critical first).",)),
    ]
    if h["findings"]:
        rows: list[list[Cell]] = [
            [
                _severity(f["severity"]),
                f["counting_head"] or "–",
                "–" if f["channel"] is None else f"Sys{f['channel']}",
                f["rule"],
                show_time(f["time"]),
                f["message"],
            ]
            for f in h["findings"]
        ]
        cols = [("Severity", False), ("Head / sensor", False), ("Channel", False), ("Rule", False)]
        out.append(_table([*cols, ("Since", False), ("Finding", False)], rows))
    out.append(Heading(3, "Analog values per channel", "analog"))
    if h["analog"]:
        out.append(Figure("analog"))
        rows = [
            [
                a["counting_head"],
                f"Sys{a['channel']}",
                f"{a['address']:03d}",
                f"{a['values']:,}",
                _n(a["min"], "{:.0f}"),
                _n(a["mean"], "{:.0f}"),
                _n(a["max"], "{:.0f}"),
                show_time(a["first"]),
                show_time(a["last"]),
            ]
            for a in h["analog"]
        ]
        cols = [("Head", False), ("Channel", False), ("Adr", False), ("Values", True), ("Min", True)]
        cols += [("Mean", True), ("Max", True), ("First", False), ("Last", False)]
        out.append(_table(cols, rows))
    else:
        out.append(Para(("No analog receiver values (Analogwert registers) in the diagnostic logs.",)))
    return out


def _crossings_part(doc: dict[str, Any]) -> list[Block]:
    out: list[Block] = [Heading(2, "7. Level crossings", "crossings")]
    cr = doc["crossings"]
    if cr is None:
        out.append(Para((doc["notes"].get("crossings", "No level-crossing timelines."),)))
        return out
    tls = cr["timelines"]
    day = _one_day([r[k] for r in tls for k in ("t_on", "t_head_arrival", "t_tail_clear", "t_off")])
    out.append(
        Para(
            (
                f"Times UTC (GNSS){f', on {day}' if day else ''}. Lead = head arrival − warning on; excess = "
                "warning off − tail clear (road closed for nothing). Baseline: a fixed-time switch-off at head "
                "arrival + length / speed + 10 s; 'early' where it would have opened the road with the train on it. "
                f"{cr['violations']} timeline(s) with a safety violation.",
            )
        )
    )
    if not tls:
        out.append(Para(("No train reached a crossing in the telemetry.",)))
    else:
        out.append(Figure("crossings"))
        rows: list[list[Cell]] = []
        for r in tls:
            if r["baseline_early_s"]:
                base: Cell = Styled(f"{r['baseline_early_s']:.0f} s early", "warn")
            elif r["baseline_excess_s"] is not None:
                base = f"+{r['baseline_excess_s']:.0f} s"
            else:
                base = "–"
            rows.append(
                [
                    r["crossing"],
                    r["train"],
                    _clock(r["t_on"], day),
                    _clock(r["t_head_arrival"], day),
                    _clock(r["t_tail_clear"], day),
                    _clock(r["t_off"], day) if r["t_off"] else Styled("held on", "warn"),
                    _n(r["lead_time_s"], "{:.0f}"),
                    _n(r["excess_warning_s"], "{:.0f}"),
                    base,
                    Styled("; ".join(r["violations"]), "unsafe") if r["violations"] else "none",
                ]
            )
        cols = [("Crossing", False), ("Train", False), ("On", False), ("Head arrival", False)]
        cols += [("Tail clear", False), ("Off", False), ("Lead s", True), ("Excess s", True)]
        out.append(_table([*cols, ("Baseline", False), ("Violations", False)], rows))
        out.append(Heading(3, "Why the warning came on and went off", "crossing-why"))
        rows = [[r["crossing"], r["train"], r["reason_on"] or "–", r["reason_off"] or "–"] for r in tls]
        out.append(_table([("Crossing", False), ("Train", False), ("On", False), ("Off", False)], rows))
    alarms = [e for e in cr["events"] if e["kind"] == "alarm"]
    if alarms:
        out.append(Heading(3, f"Alarms ({len(alarms)})", "crossing-alarms"))
        rows = [[show_time(e["time"]), e["crossing"], e["train"], e["reason"]] for e in alarms]
        out.append(_table([("Time", False), ("Crossing", False), ("Train", False), ("Alarm", False)], rows))
    if cr["trains"]:
        out.append(Heading(3, "Trains followed", "crossing-trains"))
        rows = [[t["train"], ", ".join(t["head"]), ", ".join(t["eot"]), _n(t["length_m"])] for t in cr["trains"]]
        out.append(_table([("Train", False), ("Head units", False), ("EOT units", False), ("Length m", True)], rows))
    return out


def outline(doc: dict[str, Any]) -> list[Block]:
    """The report as blocks, in the order every format shows them."""
    s = doc["safety"]
    t = doc["inputs"]["totals"]
    verdict = doc["verdict"]
    summary = {
        UNSAFE: f"{s['unsafe']} unsafe, {s['failing']} failing",
        FAILING: f"{s['failing']} failing, nothing unsafe",
        "ok": "nothing unsafe or failing",
    }[verdict]
    blocks: list[Block] = [
        Heading(1, "trackside report", "top"),
        Para(
            (
                f"Layout: {doc['layout'] or 'none'}. Inputs: {t['files']} files, {t['read']} read. "
                f"trackside {doc['trackside_version']}, schema {doc['schema']}.",
            )
        ),
        Para((Styled(f"Verdict: {verdict.upper()}", f"verdict-{verdict}"), f" ({summary}).")),
    ]
    for part in (_safety_part, _inputs_part, _devices_part, _passages_part, _sections_part, _health_part):
        blocks += part(doc)
    blocks += _crossings_part(doc)
    return blocks
