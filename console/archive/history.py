"""The archive's history as the analyses' inputs: the report's data for a window, the station's replay.

:func:`report_data` returns the :class:`~console.sinks.report.model.ReportData`
that ``trackside report`` builds from files, built instead from the
archive's records, fixes and frames (optionally cut to a time window, a
counting head, a device), by calling the same analyses the same way:
``DiagAccumulator`` over the records in file and line order, then
``detection_events``, ``health_findings``, ``run_sections`` (preparatory
start), ``frames_to_events``, ``run_crossings``.  The derived tables
(:mod:`console.archive.derive`) are this data written down.

:func:`replay_inputs` gives the station view's replay of a window its
detection events and fixes.  The stored tables are read by
:mod:`console.archive.reader`.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from console.analysis.passages.diag_analysis import DiagAnalysis
from console.archive.history_diag import channel_events, derived_for, history_diag
from console.archive.reader import (
    ArchivedRecords,
    Window,
    cut_fixes,
    frame_window,
    health_records,
    layout_of,
    parse_reports,
    per_file_tables,
    speed_settings,
    user_window,
    window_holds_data,
)
from console.archive.scope import scope_report, window_text
from console.archive.store import ArchiveError, Manifest, archive_dir, read_current
from console.archive.views import require_archive
from console.drivers.batch import DiagJob, ReadOptions, health_findings, no_axles
from parsers.report import ParseReport

if TYPE_CHECKING:
    import pandas as pd

    from console.sinks.report.model import ReportData


def report_data(
    root: Path,
    layout_spec: str | None = None,
    window: Window = Window(),
    manifest: Manifest | None = None,
    *,
    job: DiagJob | Literal["read", "history"] | None = "read",
    streamed: tuple[list[Any], list[str], Any] | None = None,
) -> ReportData:
    """The report's data, from the archive (the inputs listed are the archived files).

    The same steps as :func:`console.sinks.report.collect.collect`, in the same
    order, on the archived tables instead of freshly parsed files.
    ``job``: the diagnostic job when the caller has it (the derivation builds it
    from the per-partition rows, :mod:`console.archive.derive`; the parse
    reports are then not rebuilt); ``"read"``: recomputed from the records;
    ``"history"``: read from the derived tables (:mod:`console.archive.history_diag`;
    the caller checks :func:`~console.archive.history_diag.derived_for` first).
    ``streamed``: the job's events already run (the derivation's bounded-memory
    step): (the channel events health reads, the warnings, the section engine's
    result or None); ``data.events`` is then left empty.
    """
    from console.analysis.health.findings import Finding, sort_findings
    from console.analysis.health.voltage import voltage_margin_findings
    from console.sinks.report.collect import crossings_from_fixes, frames_from_tables, sections_into_report
    from console.sinks.report.model import InputFile, ReportData

    m = manifest if manifest is not None else read_current(root)
    spec = layout_spec if layout_spec is not None else m.derived.get("layout")
    layout = layout_of(spec)
    settings = speed_settings(m, layout)
    active = sorted((e for e in m.files if e.get("active", True)), key=lambda e: int(e["file_seq"]))
    kind_of = {int(e["file_seq"]): str(e["kind"]) for e in active}
    inputs = [InputFile(str(e["path"]), str(e["kind"]), True, "from the archive") for e in active]
    data = ReportData(inputs=inputs, layout=layout, settings=settings)
    reports: dict[str, ParseReport] = parse_reports(root, m) if job in ("read", "history") else defaultdict(ParseReport)

    findings: list[Finding] = []
    if job == "history":
        found = history_diag(root, m, layout, settings, window, reports)
        job = None if found is None else found.job
        if found is not None:
            streamed = (found.channel_events, found.warnings, found.sections)
    elif job == "read":
        # The records again through the pipeline, as the files were (another layout than the derived one).
        job = None
        if m.parts("records"):
            from console.sinks.report.collect import diag_into_report

            findings += diag_into_report(data, ArchivedRecords(root, m, window), True, None, ReadOptions())
    if job is not None:
        data.job = job
        data.reports["diagnostic"] = job.report
        if streamed is not None:
            health_events, ev_warnings, sections = streamed
            if sections is not None:
                data.sections, data.section_source = sections, "diagnostic"
        data.warnings += ev_warnings
        findings += health_findings(job, layout, health_events, None)

    frames = per_file_tables(root, m, "frames")
    text = [df for seq, df in frames if kind_of.get(seq) == "frames"]
    can = [df for seq, df in frames if kind_of.get(seq) == "can"]
    tables: list[pd.DataFrame] = []
    if text:
        tables.append(frame_window(_concat(text), window))
        data.reports["frames"] = reports["frames"]
    if can:
        from parsers.frames.can import count_frames_only  # here: it imports python-can

        tables.append(count_frames_only(frame_window(_concat(can), window)))
        data.reports["can"] = reports["can"]
    frames_from_tables(data, tables)

    volts = per_file_tables(root, m, "voltages")
    if volts:
        data.reports["voltages"] = reports["voltages"]
        findings += voltage_margin_findings(_concat([df for _, df in volts]))
    data.findings = sort_findings(findings)

    sections_into_report(data)
    fixes_parts = per_file_tables(root, m, "fixes")
    if not fixes_parts:
        data.notes["crossings"] = "No level-crossing timelines: no GNSS telemetry among the inputs."
        return data
    fixes = _concat([p for _, p in fixes_parts])
    # parse_gnss sorts the fixes of all its files by time, stably, unknown times last.
    fixes = fixes.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
    data.reports["gnss"] = reports["gnss"]
    crossings_from_fixes(data, cut_fixes(fixes, window))
    return data


def _concat(tables: list[pd.DataFrame]) -> pd.DataFrame:
    import pandas as pd  # here: only an archive with frames, voltages or fixes needs it

    return pd.concat(tables, ignore_index=True)


def archive_collector(
    archive: Path | None,
    layout: str | None,
    start: str | None,
    end: str | None,
    head: str | None,
    device_id: int | None,
) -> Callable[[], ReportData]:
    """For ``report --archive``: a collector giving the report's data from the archive, errors as one line."""
    from console.inputs.recognise import ReportInputError

    root = archive_dir(archive)

    def collector() -> ReportData:
        # Errors raised here reach the report's one-line error handling.
        try:
            window = user_window(start, end, head, device_id)
        except ValueError as exc:
            raise ReportInputError(f"--from/--to: {exc}") from None
        try:
            m = require_archive(root)
            if window.head is None and window.device_id is None and not window_holds_data(root, m, window):
                # A report about nothing would say OK (--head says so of a head with nothing in the window).
                raise ReportInputError(f"--from/--to: the archive holds no record, frame or fix{window_text(window)}")
            # The derived tables when they hold this report (the layout they were derived with), else the records.
            how: Literal["read", "history"] = "history" if derived_for(m, layout) else "read"
            data = report_data(root, layout, window, manifest=m, job=how)
        except ArchiveError as exc:
            raise ReportInputError(str(exc)) from None
        try:
            scope_report(root, m, data, window)  # --head / --device: a report about it
            return data
        except ArchiveError as exc:
            raise ReportInputError(str(exc)) from None

    return collector


def replay_inputs(root: Path, window: Window = Window()) -> tuple[ArchivedRecords | None, pd.DataFrame | None]:
    """For ``station --replay --archive``: (the window's diagnostic records, its GNSS fixes in time order).

    What the station view's ReplaySource reads from files, taken from the archive: the records as they were
    parsed (played through the live engine's pipeline), the archived fixes.
    """
    m = require_archive(root)
    records = ArchivedRecords(root, m, window) if m.parts("records") else None
    fixes = None
    parts = per_file_tables(root, m, "fixes")
    if parts:
        import pandas as pd

        fixes = pd.concat([p for _, p in parts], ignore_index=True)
        fixes = fixes.sort_values("time", kind="stable", na_position="last").reset_index(drop=True)
        fixes = cut_fixes(fixes, window)
    return records, fixes


def at_end_tables(
    root: Path, manifest: Manifest, layout_spec: str | None, warnings: list[str]
) -> dict[str, pd.DataFrame]:
    """The derived tables an ingest computes over the whole archive at its end: health findings (the health
    registers' records and the channel events the pipeline wrote), crossing timelines (the fixes), and the
    sections of sensor frames where there is no diagnostic log."""
    job = None
    diag = bool(manifest.parts("records"))
    if diag:
        report = parse_reports(root, manifest)["diagnostic"]
        analysis = DiagAnalysis(speed_settings(manifest), [], None, no_axles(), 0, 0)
        job = DiagJob([f.file for f in report.files], report, analysis, kept_records=health_records(root, manifest))
    channel = channel_events(root, manifest, Window()) if diag else []
    data = report_data(root, layout_spec, manifest=manifest, job=job, streamed=(channel, warnings, None))
    tables = cross_head_tables(data)
    if diag:  # the pipeline wrote the sections of the diagnostic records as they were ingested
        tables.pop("section_states", None)
        tables.pop("count_ledger", None)
    return tables


def cross_head_tables(data: ReportData) -> dict[str, pd.DataFrame]:
    """Section states, count ledger, health findings and crossing timelines of one ReportData."""
    import pandas as pd

    out: dict[str, pd.DataFrame] = {}
    if data.sections is not None:
        tl = data.sections.timeline.copy()
        tl["time"] = pd.to_datetime(tl["time_ns"], unit="ns")
        out["section_states"] = tl
        led = data.sections.ledger.copy()
        led["time"] = pd.to_datetime(led["time_ns"], unit="ns")
        out["count_ledger"] = led
    if data.findings:
        hf = pd.DataFrame([f.to_dict() for f in data.findings])
        # Integers as integers (a finding of all channels has none), the time as the other tables' times.
        hf["channel"] = hf["channel"].astype("Int8")
        hf["time_ns"] = hf["time_ns"].astype("Int64")
        hf["time"] = pd.to_datetime(hf["time_ns"], unit="ns")
        out["health_findings"] = hf
    if data.crossing is not None and data.crossing.timelines:
        rows = []
        for r in data.crossing.timelines:
            d = dict(r.__dict__)
            d["alarms"] = "; ".join(r.alarms)
            d["violations"] = "; ".join(r.violations)
            late_by = d.get("late_by_s")
            d["late"] = bool(r.violations) or (late_by is not None and late_by > 0)
            rows.append(d)
        ct = pd.DataFrame(rows)
        for c in ("t_on_ns", "t_head_arrival_ns", "t_tail_clear_ns", "t_off_ns", "baseline_off_ns"):
            ct[c] = ct[c].astype("Int64")
            ct[c.replace("_ns", "")] = pd.to_datetime(ct[c], unit="ns")
        out["crossing_timelines"] = ct
    return out
