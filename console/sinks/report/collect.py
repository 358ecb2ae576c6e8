"""Report inputs → :class:`ReportData`: expand directories, recognise each file, run the analyses.

Recognition is by content, by the one recogniser of file kinds
(:func:`parsers.kinds.classify_head`: gzip and UTF-16 are seen through, the
first line that is not blank or a ``#`` comment decides), with what only the
report reads or refuses first:

* ``*.toml`` → a layout (used when no ``--layout`` is given: the first one);
* ``truth.json`` (or a ``trackside.truth/…`` document) → the simulator's
  ground truth: listed, **not read** — a report says what the logs say;
* a report trackside wrote (Markdown, HTML, JSON) → listed, not read;
* then the recogniser's kinds: diagnostic log, CAN log, intelligent-sensor
  frames, voltage table, GNSS (NMEA and receiver packets, gpsd JSON, device
  CSV / JSON lines, GPX tracks, the monitoring-centre table);
* anything else, and empty files, are listed as not read, with the reason.

A directory is read whole, recursively, in sorted order; entries whose
name starts with a dot are skipped (and counted in a warning).  A file
that cannot be opened at all is an error (:class:`ReportInputError`).

The analyses are the ones the other commands run, called the same way:
the pipeline (:func:`console.drivers.batch.read_diag`: passages, sections, each
starting preparatory, and ``health_findings``) for diagnostic logs,
``frames_to_events`` per frame file, ``voltage_margin_findings`` for
voltage tables, ``parse_gnss`` + ``run_crossings`` for GNSS telemetry.
Section events come from the diagnostic logs, or from frames only when no
diagnostic log is given (a simulated run holds both for the same heads, and
counting both would count each axle twice).  Centre-table fixes feed the
crossing controller only when no NMEA or device stream is given (the
centre repeats the head units' positions, under the train's name).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from console.analysis.diag_events import DiagEventSettings
from console.analysis.health.findings import Finding, sort_findings
from console.analysis.health.voltage import voltage_margin_findings
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.engine import run_sections
from console.analysis.sections.state import SectionState
from console.drivers.batch import ChunkSource, LogFiles, ReadOptions, input_bytes, read_diag
from console.engine.pipeline import HEALTH_REGISTERS, PipelineSettings
from console.engine.sinks import Sinks
from console.inputs.recognise import (
    CAN,
    CENTRE,
    DIAGNOSTIC,
    EMPTY,
    FRAMES,
    GNSS_FORMATS,
    LAYOUT,
    TRUTH,
    UNKNOWN,
    VOLTAGES,
    ReportInputError,
    chosen_layout_file,
    expand,
    layout_note,
    recognise,
)
from console.layout import Layout, LayoutError, load_layout
from console.memory import big_read_memory
from console.plural import count
from console.progress import byte_progress
from console.sinks.report.gnss_units import gnss_units_of_columns
from console.sinks.report.model import InputFile, ReportData
from console.sinks.report.spooled import ReportPassages, SectionHistory, report_sink
from console.sinks.tables.section_history import SectionsSink
from parsers.sources import InputError

if TYPE_CHECKING:
    import pandas as pd


DIAG_MMAP_THRESHOLD_BYTES = 512 << 10  # see _analyse
# How a report's reader pairs GNSS devices into trains (the report has no --train: the devices' names).
PAIRING_HINT = "name them <train>-head / <train>-eot"


def _load(spec: str | Path) -> Layout:
    try:
        return load_layout(spec)
    except LayoutError as exc:
        raise ReportInputError(str(exc)) from None


def collect(
    inputs: Sequence[Path],
    layout_spec: str | None,
    *,
    exclude: Path | None = None,
    for_format: str | None = None,
    whole: bool = False,
) -> ReportData:
    """Recognise every input, run every analysis that applies, and return what the report shows.

    A diagnostic log's passages and section history are spooled to disk as it
    is read (:mod:`console.sinks.report.spooled`): :meth:`ReportData.close` removes
    them.  ``for_format``: the one format it is for; what that format does not show
    is not kept (the count ledger's rows but for ``json``, the speed plot's
    numbers but for ``html``).  ``whole``: hold passages and section history in
    memory instead, as tables (the report over an archive does too; tests
    compare the two).
    """
    files, warnings = expand(inputs, exclude)
    recognised = [(p, *recognise(p)) for p in files]
    layout_file = chosen_layout_file(files, layout_spec)
    layout: Layout | None = None
    if layout_spec is not None:
        layout = _load(layout_spec)
    elif layout_file is not None:
        layout = _load(layout_file)

    rows: list[InputFile] = []
    for p, fmt, note in recognised:
        read = fmt not in (LAYOUT, TRUTH, EMPTY, UNKNOWN)
        if fmt == LAYOUT:
            read = p == layout_file
            note = layout_note(p, layout_file, layout_spec)
        rows.append(InputFile(str(p), fmt, read, note))
    if not any(r.read and r.format != LAYOUT for r in rows):
        why = "; ".join(f"{r.path}: {r.note or r.format}" for r in rows[:3]) or "no files"
        raise ReportInputError(f"no input in a format trackside reads ({why})")

    settings = SpeedSettings.of_layout(layout)
    data = ReportData(inputs=rows, layout=layout, settings=settings, warnings=warnings)

    try:
        _analyse(data, recognised, for_format, whole)
        _refuse_nothing_read(data)
    except BaseException:
        data.close()
        raise
    return data


def _refuse_nothing_read(data: ReportData) -> None:
    """ReportInputError when the inputs gave not one record but rejected lines (a log of dates no time can
    hold, a damaged export): a report of nothing would say "Verdict: OK", as analyze would not."""
    reports = list(data.reports.values())
    if any(rep.records for rep in reports):
        return
    rejected = sum(rep.rejected for rep in reports)
    first = next((r for rep in reports for r in rep.rejections), None)
    if rejected and first is not None:
        raise ReportInputError(
            f"nothing readable in the inputs: {count(rejected, 'line')} rejected, none read;"
            f" {first.file} line {first.line}: {first.reason}"
        )


def _analyse(data: ReportData, recognised: list[tuple[Path, str, str]], for_format: str | None, whole: bool) -> None:
    """Every analysis that applies to the recognised inputs, into ``data``."""

    def of(*formats: str) -> list[Path]:
        return [p for p, fmt, _ in recognised if fmt in formats]

    findings: list[Finding] = []
    diag = of(DIAGNOSTIC)
    if diag:
        # Large blocks mapped on their own, as for the GNSS read: a million heads' columns, grown and merged
        # as the log is read, otherwise left ~100 MB of freed heap under the read's end (the report's peak).
        # From 512 kB, not 128 kB: a chunk's smaller columns stay on the heap, reused, where mapping them anew
        # each chunk cost ~15 % more CPU on a 3 M-record log (1 MB: ~10 MB more at a million heads).
        with big_read_memory(diag, DIAG_MMAP_THRESHOLD_BYTES), byte_progress(input_bytes(diag), "parsing") as advance:
            findings += diag_into_report(data, LogFiles(diag), whole, for_format, ReadOptions(on_progress=advance))

    _frames(data, of(FRAMES), of(CAN))

    voltages = of(VOLTAGES)
    if voltages:
        from parsers.voltages import read_voltages

        try:
            table, vreport = read_voltages(voltages)
        except OSError as exc:
            raise InputError(f"voltage table: cannot be read ({exc})") from None
        data.reports["voltages"] = vreport
        findings += voltage_margin_findings(table)
    data.findings = sort_findings(findings)

    sections_into_report(data)
    _crossings(data, of(*GNSS_FORMATS))


def diag_into_report(
    data: ReportData, source: ChunkSource, whole: bool, for_format: str | None, opts: ReadOptions
) -> list[Finding]:
    """A diagnostic source through the pipeline into the report's data: passages, sections, health findings.

    In memory bounded by the heads for one log: passages and the section history go to disk as they
    come (``whole``: held, for callers that compare tables).  Returns the health findings.
    """
    layout = data.layout
    sections_layout = layout if layout is not None and layout.sections else None
    history = None
    if sections_layout is not None:
        history = SectionsSink(keep_all=True) if whole else report_sink(ledger_rows=for_format in (None, "json"))
    data.passage_spool = None if whole else ReportPassages(plot=for_format in (None, "html"))
    pipe = PipelineSettings(
        speed=data.settings,
        events=DiagEventSettings(),
        layout=layout,
        sections=sections_layout,
        keep_registers=HEALTH_REGISTERS,
        health="end",
        axles=whole,  # held with the passages, for callers that compare tables
    )
    opts.hold_passages = whole
    try:
        job = read_diag(source, pipe, Sinks(history, data.passage_spool), opts)
    except BaseException:
        if history is not None:
            history.close()
        raise
    data.job = job
    data.reports["diagnostic"] = job.report
    # The report reads the events only for the time the data ends: the last one stands for them.
    last = job.last_event
    data.events = [last] if last is not None else []
    data.warnings += job.warnings + job.clock_step_warnings  # a report read next morning: stderr is gone
    engine = job.sections
    if engine is not None and history is not None:
        if whole:
            data.sections = engine.result(history.timeline_all, history.ledger_all, history.reset_rows)
        else:
            data.history = SectionHistory(engine.final_states(), history)
        data.section_source = "diagnostic"
    return job.findings


def _frames(data: ReportData, text_files: list[Path], can_files: list[Path]) -> None:
    if not text_files and not can_files:
        return
    from parsers.frames.can import count_frames_only, parse_can
    from parsers.frames.sensor import parse_frames

    tables: list[pd.DataFrame] = []
    if text_files:
        table, report = parse_frames(text_files)
        tables.append(table)
        data.reports["frames"] = report
    if can_files:
        table, report = parse_can(can_files)
        tables.append(count_frames_only(table))  # foreign, remote and error frames are in the parse report
        data.reports["can"] = report
    frames_from_tables(data, tables)


def frames_from_tables(data: ReportData, tables: list[pd.DataFrame]) -> None:
    """Frame tables (already parsed: from files, or from the archive) → frame events and the frames table."""
    if not tables:
        return

    from console.analysis.frame_events import events_once, frames_once

    lay = data.layout
    up: dict[str, bool] | bool = {h.id: h.up_is_first_channel_first for h in lay.heads} if lay is not None else True
    # As `trackside frames`: per file, and the same frames in two files once.
    data.frame_events, _ = events_once(tables, up)
    data.frames = frames_once(tables)[["time", "sensor", "file", "line"]]


def sections_into_report(data: ReportData) -> None:
    """The section states of the report's detection events (or sensor frames), or a note saying why none."""
    lay = data.layout
    if lay is None:
        data.notes["sections"] = "No section states: they need a layout (--layout, or a layout.toml among the inputs)."
        return
    if not lay.sections:
        data.notes["sections"] = f"No section states: the layout {lay.source} has no [[sections]]."
        return
    if data.job is not None and (data.sections is not None or data.history is not None):
        return  # run while the diagnostic log was read (collect)
    if data.job is not None:
        events, data.section_source = data.events, "diagnostic"
    elif data.frames is not None:
        events, data.section_source = data.frame_events, "frames"
    else:
        data.notes["sections"] = "No section states: no diagnostic log or sensor frames among the inputs."
        return
    data.sections = run_sections(lay, events, initial=SectionState.PREPARATORY)


def _crossings(data: ReportData, gnss: list[Path]) -> None:
    if not gnss:
        data.notes["crossings"] = "No level-crossing timelines: no GNSS telemetry among the inputs."
        return
    from parsers.gnss_files import parse_gnss, parse_gnss_columns

    if _runs_crossings(data.layout):
        with big_read_memory(gnss):
            fixes, report, _states = parse_gnss(gnss)
        data.reports["gnss"] = report
        crossings_from_fixes(data, fixes)
        return
    # The unit table is all the fixes are read for: made from the columns it needs, the rest let go first,
    # within the read's memory settings (its Arrow sort on the system allocator, the heap trimmed after).
    with big_read_memory(gnss):
        columns, report = parse_gnss_columns(gnss)
        c = columns
        needed = (c.device_codes, c.device_names, c.valid, c.time_ns, c.role, c.source)
        del c, columns
        data.gnss_units = gnss_units_of_columns(*needed)
        del needed
    data.reports["gnss"] = report
    _no_crossing_note(data)


def _runs_crossings(lay: Layout | None) -> bool:
    return lay is not None and bool(lay.crossings) and len(lay.track) >= 2


def _no_crossing_note(data: ReportData) -> None:
    lay = data.layout
    if lay is None:
        data.notes["crossings"] = "No level-crossing timelines: they need a layout with [[crossings]] and a [[track]]."
    else:
        data.notes["crossings"] = (
            f"No level-crossing timelines: the layout {lay.source} has no [[crossings]] or no [[track]] polyline."
        )


def crossings_from_fixes(data: ReportData, fixes: pd.DataFrame) -> None:
    """Parsed fixes (from files, or from the archive) → the crossing controller's run, with its notes."""
    lay = data.layout
    data.fixes = fixes
    if not _runs_crossings(lay):
        _no_crossing_note(data)
        return
    assert lay is not None
    own = fixes["source"].astype(str) != "centre"
    if own.any() and not own.all():
        note = "crossings use the NMEA and device streams (each unit's own fixes), not the centre's copy"
        data.inputs = [replace(i, note=note) if i.format == CENTRE else i for i in data.inputs]
    from console.analysis.crossing_batch import input_warnings
    from console.drivers.crossings import run_crossings

    run = run_crossings(fixes[own] if own.any() else fixes, lay)
    data.crossing = run
    # The crossing command's words: the report is read without its stderr, so "GNSS" says which inputs.
    data.warnings += [f"GNSS: {w}" for w in input_warnings(run, fixes, trains_named=False, pairing_hint=PAIRING_HINT)]
