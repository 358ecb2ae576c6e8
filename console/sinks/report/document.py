"""The report's JSON form (schema ``trackside.report/1``): :func:`document` and its parts.

:func:`document` turns the analyses (:class:`~console.sinks.report.model.ReportData`) into JSON values, in the order
the report presents them (docs/report-schema.md), a long list read from its
spool as it is written (:class:`~console.sinks.report.jsonwrite.Rows`);
:mod:`console.sinks.report.outline` turns that document into the blocks the
Markdown and HTML faces render, so the three formats cannot disagree.  Nothing
here computes what the analysis modules compute: it selects, groups and
names.
"""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from console import __version__
from console.analysis.events.detection import EventKind
from console.analysis.passages.status import STATUS_KIND
from console.analysis.passages.stream import take_passages
from console.analysis.sections.engine import SectionsResult
from console.analysis.timefmt import iso
from console.inputs.recognise import natural_key
from console.sinks.report.analog import analog_table
from console.sinks.report.gnss_units import units_of_codes
from console.sinks.report.jsonwrite import Rows
from console.sinks.report.model import FAILING, UNSAFE, ReportData, timeline_order
from console.sinks.report.spooled import LedgerFrameRows, PassageColumnRows, PassageFrameRows
from console.sinks.report.unit_codes import sorted_codes
from console.sinks.tables.section_tables import sections_json

if TYPE_CHECKING:
    from console.analysis.inventory import DeviceInventory

SCHEMA = "trackside.report/1"


# Parse reports by kind, in the order the report lists them.
REPORT_KINDS = ("diagnostic", "gnss", "frames", "can", "voltages")

SECTION_INITIAL = "unknown"  # each section starts preparatory: the log does not say the line was empty


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


def _gnss_units(data: ReportData) -> list[dict[str, Any]] | Rows:
    units = data.gnss_units
    if units is None:
        fixes = data.fixes
        if fixes is None or fixes.empty:
            return []
        # Grouped reductions into flat columns, and one row made at a time as the report is written:
        # a file may hold a million devices.
        code, names = sorted_codes(fixes["device"])
        times = fixes["time"]
        if getattr(times.dt, "tz", None) is not None:
            times = times.dt.tz_convert(None)
        times_ns = np.asarray(times.to_numpy("datetime64[ns]")).view(np.int64)
        valid = fixes["valid"].astype(bool).to_numpy()
        units = units_of_codes(code, names, valid, times_ns, fixes["role"], fixes["source"])
    if not len(units.names):
        return []
    u = units

    def members(mask: int, values: list[str], cache: dict[int, list[str]]) -> list[str]:
        got = cache.get(mask)
        if got is None:
            got = cache[mask] = [v for b, v in enumerate(values) if mask >> b & 1]
        return got

    def rows() -> Iterator[dict[str, Any]]:
        role_cache: dict[int, list[str]] = {}
        source_cache: dict[int, list[str]] = {}
        nat = np.iinfo(np.int64).min
        # A block of positions at a time: a Python int per device for all of them weighed ~36 MB.
        for start in range(0, len(u.order), 65_536):
            for i in u.order[start : start + 65_536].tolist():
                role = [r for r in members(int(u.roles[i]), u.role_names, role_cache) if r]
                t_first, t_last = int(u.first_ns[i]), int(u.last_ns[i])
                yield {
                    "device": str(u.names[i]),
                    "role": "/".join(role) or None,
                    "sources": list(members(int(u.sources[i]), u.source_names, source_cache)),
                    "fixes": int(u.count[i]),
                    "valid": int(u.n_valid[i]),
                    "first": None if t_first == nat else iso(t_first),
                    "last": None if t_last == nat else iso(t_last),
                }

    return Rows(len(u.names), rows)


def _devices(devices: Sequence[DeviceInventory]) -> Rows:
    # A row made as it is written: a log where every record names its own head has a million heads in them.
    return Rows(len(devices), lambda: (d.to_dict() for d in devices))


def _passages(data: ReportData) -> tuple[list[dict[str, Any]] | Rows, int]:
    if data.passage_spool is not None:
        return data.passage_spool.rows(), data.passage_spool.status
    if data.job is None:
        return [], 0
    analysis = data.job.analysis
    cols = analysis.passage_columns
    if cols is not None and "passages" not in analysis.__dict__:  # the columns, not made a table for this
        status_rows = cols["kind"] == STATUS_KIND
        n_status = int(status_rows.sum())
        if n_status:
            cols = take_passages(cols, np.flatnonzero(~status_rows))
        return PassageColumnRows(cols, analysis.heads), n_status
    p = analysis.passages
    status = int((p["kind"] == "status").sum()) if len(p) else 0
    shown = p[p["kind"] != "status"] if status else p
    # The same passage objects as `trackside analyze --json`, written from the table.
    return PassageFrameRows(shown), status


def _ledger_summary(result: SectionsResult) -> list[dict[str, Any]]:
    return [
        {
            "section": section,
            "head": head,
            "count_in": int(n_in),
            "count_out": int(n_out),
            "first": iso(int(first)),
            "last": iso(int(last)),
        }
        for section, head, n_in, n_out, first, last in result.ledger_summary().itertuples(index=False, name=None)
    ]


def _sections(data: ReportData) -> dict[str, Any] | None:
    h = data.history
    if h is not None:
        return {
            "initial": SECTION_INITIAL,
            "events_from": data.section_source,
            "final": [
                {"section": sid, "state": st, "count": c, "count_in": i, "count_out": o, "reason": why}
                for sid, (st, c, i, o, why) in h.final.items()
            ],
            "timeline": h.timeline(),
            "ledger_summary": h.ledger_summary(),
            "ledger": h.ledger(),
            "resets": [
                {"section": r.section, "accepted": r.accepted, "reason": r.reason, "time": iso(r.time_ns)}
                for r in h.resets()
            ],
        }
    if data.sections is None:
        return None
    # The ledger (a row per counted axle) is written from its table, not made a dict per row.
    body = sections_json(replace(data.sections, ledger=data.sections.ledger.iloc[:0]))
    return {
        "initial": SECTION_INITIAL,
        "events_from": data.section_source,
        "final": body["sections"],
        "timeline": body["timeline"],
        "ledger_summary": _ledger_summary(data.sections),
        "ledger": LedgerFrameRows(data.sections.ledger),
        "resets": body["resets"],
    }


def _crossings(data: ReportData) -> dict[str, Any] | None:
    run = data.crossing
    if run is None:
        return None
    from console.analysis.integrity.values import timelines as integrity_timelines

    return {
        "violations": run.violations,
        "late_warnings": run.late_warnings,
        "position_jumps": run.position_jumps,
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
        "integrity": integrity_timelines(run.integrity),
    }


def document(data: ReportData) -> dict[str, Any]:
    """The report as JSON values (schema ``trackside.report/1``), in presentation order.

    A streamed log's long lists (passages, the section timeline and ledger) are
    :class:`~console.sinks.report.jsonwrite.Rows`, read from their spools as they are
    written; otherwise every value is a plain JSON value.
    """
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
        "settings": {**s.to_json(), "section_initial": SECTION_INITIAL},
        **({"scope": data.scope} if data.scope is not None else {}),
        "verdict": UNSAFE if unsafe else FAILING if failing else "ok",
        "worst_severity": None if worst is None else str(worst),
        "safety": {"unsafe": unsafe, "failing": failing, "items": [a.to_dict() for a in attention]},
        "inputs": _inputs(data),
        "devices": _devices(analysis.devices) if analysis is not None else [],
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
            "analog": analog_table(data),
        },
        "crossings": _crossings(data),
        **({"trends": data.trends} if data.trends is not None else {}),
        **({"forecast": data.forecast} if data.forecast is not None else {}),
        "warnings": list(data.warnings),
        "notes": dict(sorted(data.notes.items())),
    }


def json_text(doc: dict[str, Any]) -> str:
    """Indented, ASCII-only, key order as built: the same document gives the same bytes.

    For a document of plain values; :func:`console.sinks.report.jsonwrite.write_json` writes the
    same bytes piece by piece, and also a document with :class:`~console.sinks.report.jsonwrite.Rows`.
    """
    return json.dumps(doc, ensure_ascii=True, indent=1, allow_nan=False) + "\n"
