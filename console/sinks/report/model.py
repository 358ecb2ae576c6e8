"""What a report holds (:class:`ReportData`) and its JSON form (schema ``trackside.report/1``).

:func:`document` turns the analyses into JSON values, in the order
the report presents them (docs/report-schema.md), a long list read from its
spool as it is written (:class:`~console.sinks.report.jsonwrite.Rows`);
:mod:`console.sinks.report.outline` turns that document into the blocks the
Markdown and HTML faces render, so the three formats cannot disagree.  Nothing
here computes what the analysis modules compute: it selects, groups and
names.

Safety classes (the report's first part):

* **unsafe** (counted as ``critical`` by ``--fail-on``): a level-crossing
  timeline with a safety violation (the road open with the train on it, or
  a late warning: on less than the crossing's warning time before the head
  arrived, with how late and, where the data show it, why),
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
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from console import __version__
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.health.findings import Finding, Severity
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.passages.status import STATUS_KIND
from console.analysis.passages.stream import take_passages
from console.analysis.sections.engine import SectionsResult
from console.analysis.sections.state import SectionState
from console.analysis.timefmt import iso
from console.drivers.batch import DiagJob
from console.inputs.recognise import NUMBER_PARTS, natural_key
from console.layout import Layout
from console.sinks.report.jsonwrite import Rows
from console.sinks.report.spooled import (
    LedgerFrameRows,
    PassageColumnRows,
    PassageFrameRows,
    ReportPassages,
    SectionHistory,
)
from console.sinks.report.unit_codes import first_last_ns, sorted_codes, sorted_name_codes, sorted_positions
from console.sinks.tables.section_tables import sections_json
from parsers.report import ParseReport

if TYPE_CHECKING:  # the crossing modules load only when GNSS telemetry is read (collect)
    # pandas too is imported where it is used: a report on a GNSS file reads its fixes first, and pandas
    # loaded before that read sat under its peak (~35 MB of a million-device CSV's 255 MB).
    import pandas as pd

    from console.analysis.crossing.timeline import TimelineRow
    from console.analysis.crossing_batch import CrossingRun
    from console.analysis.inventory import DeviceInventory

SCHEMA = "trackside.report/1"


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
    topic: str  # crossing | integrity | health | section | reset
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
    # The GNSS unit table, when the fixes were read for it alone (no crossing run): they are not kept.
    gnss_units: GnssUnits | None = None
    crossing: CrossingRun | None = None
    reports: dict[str, ParseReport] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: dict[str, str] = field(default_factory=dict)  # part → why it is empty
    # Daily trends (console.archive.trends): only a report from the archive has history.
    trends: dict[str, Any] | None = None
    # Condition forecasts (console.sinks.report.forecast): from the archive's daily figures too.
    forecast: dict[str, Any] | None = None
    # A diagnostic log read as a stream (console.sinks.report.spooled): its passages and section history
    # kept on disk, not in ``job`` and ``sections``.
    passage_spool: ReportPassages | None = None
    history: SectionHistory | None = None
    # What a report scoped to a head or device is about (console.archive.scope); None: everything read.
    scope: str | None = None

    def attention(self) -> list[Attention]:
        """Unsafe items first, then failing ones; each in time order."""
        items: list[Attention] = []
        if self.crossing is not None:
            for tl_row in self.crossing.timelines:
                for v in tl_row.violations:
                    if v.startswith("late") and tl_row.late_cause:
                        v = f"{v} ({tl_row.late_cause})"
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
        if self.crossing is not None:
            for ev in self.crossing.integrity:
                if ev.state == "parted":
                    why = "train parted: " + "; ".join(ev.evidence)
                    items.append(Attention(Severity.CRITICAL, UNSAFE, "integrity", f"train {ev.train}", ev.t_ns, why))
        for f in self.findings:
            if f.severity is Severity.CRITICAL:
                items.append(Attention(f.severity, UNSAFE, "health", _where(f), f.time_ns, f.message))
        items += self._section_items()
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

    def _section_items(self) -> list[Attention]:
        """Sections that ended disturbed (since they last became so) and refused resets."""
        resets: Iterable[Any]
        since: Callable[[str, str], int | None]
        if self.history is not None:
            final, resets, since = self.history.final, self.history.resets(), self.history.since_ns
        elif self.sections is not None:
            tl = self.sections.timeline
            final, resets = self.sections.final, self.sections.resets.itertuples(index=False)

            def since(sid: str, state: str) -> int | None:
                rows = tl[(tl["section"] == sid) & (tl["state"] == state)]
                return int(rows["time_ns"].iloc[-1]) if len(rows) else None
        else:
            return []
        items = [
            Attention(
                Severity.WARNING,
                FAILING,
                "section",
                f"section {sid}",
                since(sid, state),
                f"ended the log disturbed (count {count}): {reason}; needs a reset and a sweep train",
            )
            for sid, (state, count, _in, _out, reason) in final.items()
            if state == SectionState.DISTURBED
        ]
        r: Any
        for r in resets:
            if not r.accepted:
                why = f"reset refused: {r.reason}"
                items.append(Attention(Severity.WARNING, FAILING, "reset", f"section {r.section}", int(r.time_ns), why))
        return items

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
        span = self.history.span_ns() if self.history is not None else None
        if span is not None:
            ends.append(span[1])
        if self.sections is not None and len(self.sections.timeline):
            ends.append(int(self.sections.timeline["time_ns"].max()))
        return max(ends) if ends else None

    def close(self) -> None:
        """Remove the spool files (a streamed report: once it is written)."""
        if self.passage_spool is not None:
            self.passage_spool.close()
        if self.history is not None:
            self.history.close()


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


def _natural_order(names: pd.Index | Sequence[str]) -> np.ndarray:
    """Positions of ``names`` in :func:`natural_key` order (ties keep their order), one sort key
    string per name: runs of digits length-prefixed, so that plain string order is the natural one."""
    return sorted_positions(names, lambda x: NUMBER_PARTS.sub(_padded_number, str(x).casefold()))


def _padded_number(m: re.Match[str]) -> str:
    digits = m.group().lstrip("0") or "0"
    # "\x00" sorts the number before any letter, as natural_key's int part before a text part.
    return f"\x00{len(digits):06d}{digits}"


def _value_sets(code: np.ndarray, values: pd.Series, n: int) -> tuple[np.ndarray, list[str]]:
    """Per device, the set of ``values`` it has, as a bit mask over the distinct values (few: roles,
    sources), and those values: flat, not a set object per device."""
    vcode, vnames = sorted_codes(values)
    if len(vnames) > 64:  # never for roles or sources; keep the first 64 rather than fail
        vcode = np.where(vcode < 64, vcode, 63)
    # The narrowest mask that holds them (a byte per device for the few roles or sources).
    bits = next(t for t in (np.uint8, np.uint16, np.uint32, np.uint64) if np.iinfo(t).bits >= len(vnames))
    mask = np.zeros(n, bits)
    np.bitwise_or.at(mask, code, np.left_shift(bits(1), vcode.astype(bits)))
    return mask, [str(v) for v in vnames[:64]]


@dataclass
class GnssUnits:
    """The GNSS unit table as flat columns, one entry per device (``names`` in string order), and the
    devices' natural order: what the report shows of the fixes, without them."""

    names: pd.Index | Sequence[str]
    order: np.ndarray  # positions in ``names``, in natural_key order
    count: np.ndarray
    n_valid: np.ndarray
    first_ns: np.ndarray
    last_ns: np.ndarray
    roles: np.ndarray  # bit masks over role_names
    role_names: list[str]
    sources: np.ndarray  # bit masks over source_names
    source_names: list[str]


def gnss_units_of_columns(
    device_codes: np.ndarray,
    device_names: Sequence[str],
    valid: np.ndarray,
    time_ns: np.ndarray,
    role: np.ndarray,
    source: np.ndarray,
) -> GnssUnits:
    """:class:`GnssUnits` of the fix columns it reads (:class:`~parsers.gnss.fix_table.FixColumns`' fields
    of those names; ``role``/``source`` codes into ROLES/SOURCES): the device names stay flat."""
    import pandas as pd

    from parsers.gnss.fix_table import ROLES, SOURCES

    code, names = sorted_name_codes(device_codes, device_names)
    role_column = pd.Series(pd.Categorical.from_codes(role, dtype=pd.CategoricalDtype(list(ROLES))))
    source_column = pd.Series(pd.Categorical.from_codes(source, dtype=pd.CategoricalDtype(list(SOURCES))))
    return _units(code, names, valid.astype(bool), time_ns, role_column, source_column)


def _units(
    code: np.ndarray,
    names: pd.Index | Sequence[str],
    valid: np.ndarray,
    times_ns: np.ndarray,
    role_column: pd.Series,
    source_column: pd.Series,
) -> GnssUnits:
    n = len(names)
    # The natural order first: its sort keys (~30 MB a million devices) are made before the columns below.
    order = _natural_order(names).astype(np.int32)
    # Counts as int32 (a device's fixes are rows of one table) and positions too: kept until written.
    count = np.bincount(code, minlength=n).astype(np.int32)
    n_valid = np.bincount(code, weights=valid, minlength=n).astype(np.int32)
    first, last = first_last_ns(code, times_ns, n)
    roles, role_names = _value_sets(code, role_column, n)
    sources, source_names = _value_sets(code, source_column, n)
    return GnssUnits(names, order, count, n_valid, first, last, roles, role_names, sources, source_names)


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
        units = _units(code, names, valid, times_ns, fixes["role"], fixes["source"])
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


def analog_series(data: ReportData) -> pd.DataFrame:
    """The analog receiver values (``analog_value`` registers) as time_ns, head, channel, address, value."""
    import pandas as pd

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
    if data.job is None or data.job.kept_nothing:
        return []  # no record kept: no table made
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
    from console.analysis.integrity.monitor import timelines as integrity_timelines

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
            "analog": _analog(data),
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
