"""The `trackside` command line (Typer).

Each command composes parser and analysis calls (console.jobs) and renders
the result as Rich tables or as one JSON document on stdout.  Exit codes:
0 ok, 1 findings under ``--strict``, 2 usage errors and unreadable inputs
(one line on stderr, never a traceback).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console as RichConsole

from console import __version__, exit_codes

app = typer.Typer(
    name="trackside",
    help="Terminal console and log analyzer for railway train detection.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

JSON_SCHEMA_ANALYZE = "trackside.analyze/1"

F = TypeVar("F", bound=Callable[..., Any])

FilesArg = Annotated[
    list[Path],
    typer.Argument(help="Diagnostic log files (plain or .gz).", show_default=False),
]
SpacingOpt = Annotated[
    float, typer.Option("--spacing", help="Coil spacing Sys1–Sys2 of the counting head, m.", min=0.001)
]
TrainLengthOpt = Annotated[
    float, typer.Option("--train-length", help="First-to-last wheel distance of the train, m.", min=0.1)
]
IdleGapOpt = Annotated[
    float, typer.Option("--idle-gap", help="Seconds without records that end a passage (≥ 1).", min=1.0)
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON document on stdout instead of tables.")]
StrictOpt = Annotated[bool, typer.Option("--strict", help="Exit 1 if any input line was rejected.")]


def _fail(message: str, code: int = exit_codes.USAGE) -> typer.Exit:
    """One unwrapped line on stderr (file names may hold anything: escaped)."""
    from console.safe_text import clean

    sys.stderr.write(f"trackside: error: {clean(message)}\n")
    sys.stderr.flush()
    return typer.Exit(code)


def _check_inputs(paths: list[Path]) -> None:
    for p in paths:
        if not p.exists():
            raise _fail(f"{p}: no such file")
        if p.is_dir():
            raise _fail(f"{p}: is a directory, expected a log file")
        if not os.access(p, os.R_OK):
            raise _fail(f"{p}: permission denied")


class Console(RichConsole):
    """Rich's console, but a reader that stops early (``| head``) is not an error:
    Rich exits 1 on a broken pipe; we stop quietly with 0."""

    def on_broken_pipe(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        raise SystemExit(exit_codes.OK)


def _guard(fn: Callable[[], int]) -> int:
    """Run a command body: input errors become one-line messages and exit 2."""
    from parsers.sources import InputError

    try:
        return fn()
    except (typer.Exit, typer.Abort):
        raise
    except InputError as exc:
        raise _fail(str(exc)) from None
    except BrokenPipeError:
        # Output piped into `head` or similar: stop quietly.
        sys.stderr.close()
        return exit_codes.OK
    except MemoryError:
        raise _fail("out of memory") from None
    except Exception as exc:
        if os.environ.get("TRACKSIDE_DEBUG"):
            raise
        raise _fail(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)") from None


def _print_json(doc: dict[str, Any]) -> None:
    from console.jsonout import write

    write(doc, sys.stdout)
    sys.stdout.flush()


def _layout_summary(files: list[Path], lay: Any, spacing: float, length: float, idle_gap: float) -> Any:
    """One pass for `analyze --layout`: the job, section states and health findings."""
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.diagnostics import SpeedSettings
    from console.analysis.sections import run_sections
    from console.jobs import HEALTH_REGISTERS, analyze_files, detection_events, health_findings, input_bytes
    from console.progress import byte_progress

    _check_inputs(files)
    with byte_progress(input_bytes(files), "parsing") as advance:
        job = analyze_files(
            files,
            SpeedSettings(spacing, length, idle_gap),
            on_progress=advance,
            keep_registers=HEALTH_REGISTERS,
            keep_releases=True,
        )
    events, warnings = detection_events(job, lay, DiagEventSettings())
    result = run_sections(lay, events)
    return job, result, health_findings(job, lay, events, None), warnings


def _run_diag(
    files: list[Path], spacing: float, train_length: float, idle_gap: float, keep_releases: bool = False
) -> Any:
    from console.analysis.diagnostics import SpeedSettings
    from console.jobs import analyze_files, input_bytes
    from console.progress import byte_progress

    _check_inputs(files)
    settings = SpeedSettings(spacing_m=spacing, train_length_m=train_length, idle_gap_s=idle_gap)
    with byte_progress(input_bytes(files), "parsing") as advance:
        return analyze_files(files, settings, on_progress=advance, keep_releases=keep_releases)


@app.command()
def analyze(
    files: FilesArg,
    spacing: Annotated[
        float | None,
        typer.Option("--spacing", help="Coil spacing Sys1–Sys2, m [default: the layout's, 0.13]", min=0.001),
    ] = None,
    train_length: Annotated[
        float | None,
        typer.Option(
            "--train-length", help="First-to-last wheel, m [default: the layout's first consist, 28.6]", min=0.1
        ),
    ] = None,
    idle_gap: IdleGapOpt = 10.0,
    layout: Annotated[
        str | None,
        typer.Option("--layout", help="Layout (file or osong, example): adds section and health summaries."),
    ] = None,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Inventory, passages with speeds, and the parse report of diagnostic logs."""

    def body() -> int:
        # Line facts come from the layout; the Osong test line when none is given.
        lay = _load_layout(layout or "osong")
        consist = lay.consist()
        spacing_m = spacing if spacing is not None else lay.heads[0].spacing_m
        length_m = train_length if train_length is not None else (consist.length_m if consist else 28.6)
        summary = _layout_summary(files, lay, spacing_m, length_m, idle_gap) if layout else None
        job = summary[0] if summary else _run_diag(files, spacing_m, length_m, idle_gap)
        if json_out:
            from console.jsonout import RawJSON

            doc = {
                "schema": JSON_SCHEMA_ANALYZE,
                "trackside_version": __version__,
                "files": job.files,
                "parse_report": job.report.to_dict(),
                **job.analysis.to_dict(passages=RawJSON(job.analysis.passages_json_text())),
            }
            if summary:
                from console.render.section_tables import sections_json

                doc["layout"] = lay.source
                doc["sections"] = sections_json(summary[1])["sections"]
                doc["health"] = [f.to_dict() for f in summary[2]]
                doc["warnings"] = summary[3]
            _print_json(doc)
        else:
            from console.render.diag_tables import (
                inventory_table,
                parse_report_table,
                passages_table,
                rejections_table,
            )

            out = Console(highlight=False)
            out.print(inventory_table(job.analysis))
            out.print(passages_table(job.analysis, limit=200))
            out.print(parse_report_table(job.report))
            rej = rejections_table(job.report)
            if rej is not None:
                out.print(rej)
            notes = []
            if job.analysis.overlap_records:
                notes.append(
                    f"{job.analysis.overlap_records} records repeat another file's second"
                    " (overlapping exports) and were counted once"
                )
            if job.analysis.unpaired_detections:
                notes.append(f"{job.analysis.unpaired_detections} wheel detections on one system only (not axles)")
            if job.report.unknown_labels:
                notes.append(
                    f"{sum(job.report.unknown_labels.values())} records with unknown labels: "
                    + ", ".join(sorted(job.report.unknown_labels))
                )
            for n in notes:
                out.print(n, markup=False)
            if summary:
                from console.render.health_tables import findings_view
                from console.render.section_tables import final_states_table

                out.print(final_states_table(summary[1]))
                out.print(findings_view(summary[2], show_info=False, title="Health"))
                for w in summary[3]:
                    out.print(f"warning: {w}", markup=False)
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def speeds(
    files: FilesArg,
    spacing: SpacingOpt = 0.13,
    train_length: TrainLengthOpt = 28.6,
    idle_gap: IdleGapOpt = 10.0,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """The passages table alone: per-second, whole-train and per-axle speeds."""

    def body() -> int:
        job = _run_diag(files, spacing, train_length, idle_gap)
        if json_out:
            from console.jsonout import RawJSON

            text = RawJSON(job.analysis.passages_json_text())
            _print_json({"schema": "trackside.speeds/1", "passages": text})
        else:
            from console.render.diag_tables import passages_table

            Console(highlight=False).print(passages_table(job.analysis))
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(_guard(body))


LayoutOpt = Annotated[
    str,
    typer.Option("--layout", help="Layout TOML file, or a shipped one: osong, example.", show_default=False),
]


def _load_layout(spec: str) -> Any:
    from console.layout import LayoutError, load_layout

    try:
        return load_layout(spec)
    except LayoutError as exc:
        raise _fail(str(exc)) from None


def _parse_resets(values: list[str]) -> list[Any]:
    import pandas as pd

    from console.analysis.events import DetectionEvent, EventKind

    out = []
    for v in values:
        section, sep, when = v.partition("@")
        try:
            t = pd.Timestamp(when) if sep and section else None
        except ValueError:
            t = None
        if t is None or pd.isna(t):
            raise _fail(f"--reset {v!r}: expected SECTION@TIME, e.g. B1@2026-03-02T09:30:00")
        out.append(DetectionEvent(int(t.value), EventKind.RESET, section.strip(), source="operator", detail="--reset"))
    return out


@app.command()
def sections(
    files: FilesArg,
    layout: LayoutOpt,
    reset: Annotated[
        list[str] | None,
        typer.Option(
            "--reset", help="Ask to reset a section at a time: SECTION@TIME (repeatable).", show_default=False
        ),
    ] = None,
    power_gap: Annotated[
        float | None,
        typer.Option(
            "--power-gap", help="Seconds without records from a head that mean power loss (off unless set).", min=1.0
        ),
    ] = None,
    initial: Annotated[
        str, typer.Option("--initial", help="Section state at the start of the log: unknown (until a sweep) or clear.")
    ] = "unknown",
    isolation: Annotated[
        float,
        typer.Option(
            "--isolation", help="Seconds of quiet before and after a lone pulse that make it accidental.", min=1.0
        ),
    ] = 60.0,
    json_out: JsonOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 if a line was rejected or a section ends disturbed.")
    ] = False,
) -> None:
    """Section states from axle counting: state timeline, count ledger, resets."""

    def body() -> int:
        from console.analysis.diag_events import DiagEventSettings, diag_detection_events
        from console.analysis.majority import MajoritySettings
        from console.analysis.sections import SectionState, run_sections
        from console.analysis.wheels import CountingSettings
        from console.render import section_tables as st

        if initial not in ("unknown", "clear"):
            raise _fail(f"--initial: expected unknown or clear, found {initial!r}")
        lay = _load_layout(layout)
        if not lay.sections:
            raise _fail(f"{lay.source}: the layout has no [[sections]]")
        resets = _parse_resets(reset or [])
        job = _run_diag(files, lay.heads[0].spacing_m, 28.6, 10.0, keep_releases=True)
        settings = DiagEventSettings(
            counting=CountingSettings(isolation_s=isolation),
            majority=MajoritySettings(isolation_s=isolation),
            power_gap_s=power_gap,
        )
        events, warnings = diag_detection_events(job.analysis, lay, settings)
        start = SectionState.CLEAR if initial == "clear" else SectionState.PREPARATORY
        result = run_sections(lay, events + resets, initial=start)
        disturbed = [sid for sid, f in result.final.items() if f[0] == SectionState.DISTURBED]
        if json_out:
            _print_json(
                {
                    "schema": "trackside.sections/1",
                    "files": job.files,
                    "layout": lay.source,
                    "parse_report": job.report.to_dict(),
                    "warnings": warnings,
                    **st.sections_json(result),
                }
            )
        else:
            out = Console(highlight=False)
            out.print(st.final_states_table(result))
            out.print(st.timeline_table(result))
            out.print(st.ledger_summary_table(result))
            rt = st.resets_table(result)
            if rt is not None:
                out.print(rt)
            for w in warnings:
                out.print(f"warning: {w}", markup=False)
            if job.report.rejected:
                out.print(f"{job.report.rejected} input lines rejected (trackside analyze lists them)", markup=False)
        return exit_codes.FINDINGS if strict and (job.report.rejected or disturbed) else exit_codes.OK

    raise typer.Exit(_guard(body))


def _worst(findings: list[Any]) -> Any:
    from console.analysis.health import Severity

    return max((f.severity for f in findings), default=Severity.INFO, key=lambda s: s.rank)


@app.command()
def health(
    files: Annotated[
        list[Path] | None, typer.Argument(help="Diagnostic log files (plain or .gz).", show_default=False)
    ] = None,
    layout: Annotated[
        str | None, typer.Option("--layout", help="Layout (analog bands per head): a file or osong, example.")
    ] = None,
    voltages: Annotated[
        list[Path] | None,
        typer.Option("--voltages", help="Receiver voltage table(s): sensor, in-phase mV, anti-phase mV (repeatable)."),
    ] = None,
    fail_on: Annotated[
        str | None,
        typer.Option("--fail-on", help="Exit 1 when a finding reaches this severity: info, warning, critical."),
    ] = None,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Sensor and channel health: analog bands, voltage margins, disturbance rates, faulty channels."""

    def body() -> int:
        from console.analysis.diag_events import DiagEventSettings
        from console.analysis.health import Severity, sort_findings, voltage_margin_findings
        from console.jobs import HEALTH_REGISTERS, analyze_files, detection_events, health_findings, input_bytes
        from console.progress import byte_progress
        from console.render.health_tables import findings_view
        from parsers.voltages import read_voltages

        if not files and not voltages:
            raise _fail("give diagnostic log files, --voltages tables, or both")
        threshold = None
        if fail_on is not None:
            try:
                threshold = Severity.parse(fail_on)
            except ValueError as exc:
                raise _fail(f"--fail-on: {exc}") from None
        lay = _load_layout(layout) if layout else None
        findings: list[Any] = []
        reports: list[Any] = []
        warnings: list[str] = []
        if files:
            _check_inputs(files)
            from console.analysis.diagnostics import SpeedSettings

            with byte_progress(input_bytes(files), "parsing") as advance:
                job = analyze_files(
                    files, SpeedSettings(), on_progress=advance, keep_registers=HEALTH_REGISTERS, keep_releases=True
                )
            events, warnings = detection_events(job, lay, DiagEventSettings())
            findings += health_findings(job, lay, events, None)
            reports.append(job.report)
        if voltages:
            _check_inputs(voltages)
            table, vreport = read_voltages(voltages)
            findings += voltage_margin_findings(table)
            reports.append(vreport)
        findings = sort_findings(findings)
        rejected = sum(r.rejected for r in reports)
        if json_out:
            _print_json(
                {
                    "schema": "trackside.health/1",
                    "files": [str(p) for p in (files or [])],
                    "voltages": [str(p) for p in (voltages or [])],
                    "findings": [f.to_dict() for f in findings],
                    "parse_reports": [r.to_dict() for r in reports],
                    "warnings": warnings,
                }
            )
        else:
            out = Console(highlight=False)
            out.print(findings_view(findings))
            for w in warnings:
                out.print(f"warning: {w}", markup=False)
            if rejected:
                out.print(f"{rejected} input lines rejected (--json lists them)", markup=False)
        failing = threshold is not None and any(f.severity >= threshold for f in findings)
        return exit_codes.FINDINGS if failing or (strict and rejected) else exit_codes.OK

    raise typer.Exit(_guard(body))


def _is_can_log(path: Path) -> bool:
    """CAN logs by suffix (.asc, .blf) or, for .log, by content (candump lines start with '(')."""
    suffixes = [x.lower() for x in path.suffixes if x.lower() != ".gz"]
    suffix = suffixes[-1] if suffixes else ""
    if suffix in (".asc", ".blf"):
        return True
    if suffix == ".log":
        with path.open("rb") as f:
            head = f.read(4096)
        if head.startswith(b"LOGG"):
            return True
        for line in head.splitlines():
            line = line.strip()
            if line and not line.startswith(b"#"):
                return line.startswith(b"(")
    return False


@app.command()
def frames(
    files: Annotated[
        list[Path], typer.Argument(help="Sensor frame files (text) or CAN logs (candump .log, .asc, .blf).")
    ],
    layout: Annotated[
        str | None, typer.Option("--layout", help="Layout: which travel is up for each sensor (3-element heads).")
    ] = None,
    comm_timeout: Annotated[
        float,
        typer.Option("--comm-timeout", help="Seconds without frames from a sensor that mean contact lost.", min=0.1),
    ] = 10.0,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Intelligent-sensor frames and CAN count frames: decoded, and as axle events."""

    def body() -> int:
        import pandas as pd

        from console.analysis.frame_events import frames_to_events
        from console.analysis.timefmt import iso
        from console.render.diag_tables import parse_report_table, rejections_table
        from console.render.frame_tables import events_table, sensor_summary_table
        from parsers.frames import CAN_COLUMNS, parse_can, parse_frames

        _check_inputs(files)
        lay = _load_layout(layout) if layout else None
        can_files = [p for p in files if _is_can_log(p)]
        text_files = [p for p in files if p not in can_files]
        tables, reports = [], []
        if text_files:
            tf, tr = parse_frames(text_files)
            tables.append(tf)
            reports.append(tr)
        if can_files:
            cf, cr = parse_can(can_files)
            tables.append(cf)
            reports.append(cr)
        up: dict[str, bool] | bool = True
        if lay is not None:
            up = {h.id: h.up_is_first_channel_first for h in lay.heads}
        events = []
        for table in tables:
            # Each file is its own recording: sequence and count checks run within it.
            for _, part in table.groupby("file", observed=True, sort=False):
                events += frames_to_events(part, up_is_s1_to_s3=up, comm_timeout_s=comm_timeout)
        events.sort(key=lambda e: e.time_ns)
        all_frames = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
        rejected = sum(r.rejected for r in reports)
        if json_out:
            rows = []
            if not all_frames.empty:
                keep = [c for c in CAN_COLUMNS if c != "time" and c in all_frames.columns]
                frame_rows = all_frames[keep].astype(object).where(all_frames[keep].notna(), None).to_dict("records")
                for t_ns, rec in zip(all_frames["time"].astype("int64").tolist(), frame_rows, strict=True):
                    rows.append(
                        {"time": iso(t_ns), **{str(k): (v.item() if hasattr(v, "item") else v) for k, v in rec.items()}}
                    )
            _print_json(
                {
                    "schema": "trackside.frames/1",
                    "files": [str(p) for p in files],
                    "frames": rows,
                    "events": [
                        {
                            "time": iso(e.time_ns),
                            "kind": str(e.kind),
                            "sensor": e.head,
                            "direction": e.direction,
                            "channel": e.channel,
                            "source": e.source,
                            "detail": e.detail,
                        }
                        for e in events
                    ],
                    "parse_reports": [r.to_dict() for r in reports],
                }
            )
        else:
            out = Console(highlight=False)
            out.print(sensor_summary_table(all_frames, events))
            out.print(events_table(events))
            for r in reports:
                out.print(parse_report_table(r))
                rej = rejections_table(r)
                if rej is not None:
                    out.print(rej)
        return exit_codes.FINDINGS if strict and rejected else exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def approach(
    files: FilesArg,
    layout: Annotated[
        str, typer.Option("--layout", help="Layout with [[work_sites]] (file or osong, example).")
    ] = "osong",
    head: Annotated[str | None, typer.Option("--head", help="Approach counting head of an ad-hoc site.")] = None,
    distance: Annotated[
        float | None, typer.Option("--distance", help="Metres from the head to the site: + up the line, − down.")
    ] = None,
    warning_time: Annotated[
        float, typer.Option("--warning-time", help="Seconds of warning the workers need.", min=1)
    ] = 30.0,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Track-worker approach warnings: alarm from detection vs from the speed measured at the head."""

    def body() -> int:
        from console.analysis.approach import approach_timeline
        from console.layout import WorkSite
        from console.render.approach_tables import approach_table

        lay = _load_layout(layout)
        sites = list(lay.work_sites)
        if head is not None or distance is not None:
            if head is None or distance is None or distance == 0:
                raise _fail("an ad-hoc site needs both --head and a non-zero --distance")
            if not lay.has_head(head):
                raise _fail(f"--head {head}: not a counting head of {lay.source}")
            sites = [WorkSite("site", head, distance, warning_time)]
        if not sites:
            raise _fail(f"{lay.source} has no [[work_sites]]: give --head and --distance")
        spacing = lay.heads[0].spacing_m
        consist = lay.consist()
        job = _run_diag(files, spacing, consist.length_m if consist else 28.6, 10.0)
        rows = [r for site in sites for r in approach_timeline(job.analysis.passages, lay, site)]
        if json_out:
            _print_json(
                {
                    "schema": "trackside.approach/1",
                    "files": job.files,
                    "layout": lay.source,
                    "warnings": [r.to_dict() for r in rows],
                    "parse_report": job.report.to_dict(),
                }
            )
        else:
            Console(highlight=False).print(approach_table(rows))
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(_guard(body))


GnssFilesArg = Annotated[
    list[Path],
    typer.Argument(
        help="GNSS telemetry: NMEA, device streams (CSV, JSON lines), monitoring-centre tables.", show_default=False
    ),
]


@app.command()
def gnss(files: GnssFilesArg, json_out: JsonOpt = False, strict: StrictOpt = False) -> None:
    """Decoded GNSS fixes per device, and the parse report."""

    def body() -> int:
        from console.render.diag_tables import parse_report_table, rejections_table
        from console.render.gnss_tables import devices_table, fixes_table, gnss_json
        from parsers.gnss import parse_gnss

        _check_inputs(files)
        fixes, report, _states = parse_gnss(files)
        if json_out:
            _print_json({"schema": "trackside.gnss/1", "files": [str(p) for p in files], **gnss_json(fixes, report)})
        else:
            out = Console(highlight=False)
            out.print(devices_table(fixes))
            out.print(fixes_table(fixes))
            out.print(parse_report_table(report))
            rej = rejections_table(report)
            if rej is not None:
                out.print(rej)
        return exit_codes.FINDINGS if strict and report.rejected else exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def crossing(
    files: GnssFilesArg,
    layout: Annotated[str, typer.Option("--layout", help="Layout with [[crossings]] and a [[track]] polyline.")],
    train: Annotated[
        list[str] | None,
        typer.Option("--train", help="TRAIN=HEAD_DEVICE,EOT_DEVICE[,LENGTH_M] (repeatable; default: by role or name)."),
    ] = None,
    json_out: JsonOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 on a safety violation or a rejected input line.")
    ] = False,
) -> None:
    """Level-crossing warning timelines from head and end-of-train telemetry (seed 004)."""

    def body() -> int:
        from console.analysis.crossing_batch import parse_train_option, run_crossings
        from console.analysis.timefmt import iso
        from console.render.crossing_tables import reasons_view, timeline_table, violations_view
        from parsers.gnss import parse_gnss

        _check_inputs(files)
        lay = _load_layout(layout)
        if not lay.crossings:
            raise _fail(f"{lay.source}: the layout has no [[crossings]]")
        if len(lay.track) < 2:
            raise _fail(f"{lay.source}: the layout has no [[track]] polyline to place fixes on")
        consist = lay.consist()
        default_len = consist.length_m if consist else 100.0
        try:
            trains = [parse_train_option(t, default_len) for t in (train or [])]
        except ValueError as exc:
            raise _fail(str(exc)) from None
        fixes, report, _states = parse_gnss(files)
        run = run_crossings(fixes, lay, trains)
        violations = sum(1 for r in run.timelines if r.violations)
        warnings = []
        if run.off_track:
            warnings.append(f"{run.off_track} fixes more than 100 m from the track were set aside")
        if run.unassigned_devices:
            warnings.append("devices in no train: " + ", ".join(run.unassigned_devices))
        if not run.trains:
            warnings.append("no head or EOT device found: give --train TRAIN=HEAD,EOT")
        if json_out:
            _print_json(
                {
                    "schema": "trackside.crossing/1",
                    "files": [str(p) for p in files],
                    "layout": lay.source,
                    "violations": violations,
                    "timelines": [r.to_dict() for r in run.timelines],
                    "events": [
                        {
                            "time": iso(e.t_ns),
                            "crossing": e.crossing,
                            "train": e.train,
                            "kind": e.kind,
                            "reason": e.reason,
                        }
                        for e in run.events
                    ],
                    "trains": [
                        {"train": t.train, "head": list(t.head), "eot": list(t.eot), "length_m": t.length_m}
                        for t in run.trains
                    ],
                    "warnings": warnings,
                    "parse_report": report.to_dict(),
                }
            )
        else:
            out = Console(highlight=False)
            v = violations_view(run.timelines)
            if v is not None:
                out.print(v)
            out.print(timeline_table(run.timelines))
            out.print(reasons_view(run.timelines, run.events))
            for w in warnings:
                out.print(f"warning: {w}", markup=False)
            if report.rejected:
                out.print(f"{report.rejected} input lines rejected (trackside gnss lists them)", markup=False)
        return exit_codes.FINDINGS if strict and (violations or report.rejected) else exit_codes.OK

    raise typer.Exit(_guard(body))


def _parse_fault(text: str) -> Any:
    """``KIND:TARGET:START[:END[:CHANNEL]]`` (times like 90s, 30m) → a simulator Fault."""
    from console.analysis.timefmt import parse_duration
    from console.sim.station import FAULT_KINDS, Fault

    parts = text.split(":")
    if len(parts) < 3 or parts[0] not in FAULT_KINDS:
        raise _fail(
            f"--fault {text!r}: expected KIND:TARGET:START[:END[:CHANNEL]] with KIND one of {', '.join(FAULT_KINDS)}"
        )
    try:
        start = parse_duration(parts[2])
        end = parse_duration(parts[3]) if len(parts) > 3 and parts[3] else float("inf")
        channel = int(parts[4]) if len(parts) > 4 else 2
    except ValueError as exc:
        raise _fail(f"--fault {text!r}: {exc}") from None
    return Fault(parts[0], parts[1], start, end, channel)


@app.command()
def simulate(
    output: Annotated[Path, typer.Option("-o", "--output", help="Directory to write the run into.")],
    layout: Annotated[str, typer.Option("--layout", help="Layout file, or osong / example.")] = "example",
    duration: Annotated[str, typer.Option("--duration", help="Simulated time: 90s, 30m, 2h, 1h30m.")] = "2h",
    seed: Annotated[int, typer.Option("--seed", help="Random seed: the same seed gives the same run.")] = 1,
    trains_per_hour: Annotated[float, typer.Option("--trains-per-hour", min=0.1, max=60)] = 6.0,
    spreading_factor: Annotated[
        int,
        typer.Option(
            "--sf", help="LoRa spreading factor of the GNSS units (7-12): sets their report period.", min=7, max=12
        ),
    ] = 7,
    fault: Annotated[
        list[str] | None,
        typer.Option("--fault", help="KIND:TARGET:START[:END[:CHANNEL]], e.g. dead_channel:WS3:20m (repeatable)."),
    ] = None,
    json_out: JsonOpt = False,
) -> None:
    """Simulate a line: trains, counting heads, GNSS units and faults, written as real logs with a truth."""

    def body() -> int:
        from console.analysis.timefmt import parse_duration
        from console.progress import byte_progress
        from console.sim.radio import LoRaLink
        from console.sim.station import SimConfig, StationSim
        from console.sim.writers import write_run

        try:
            seconds = parse_duration(duration)
        except ValueError as exc:
            raise _fail(f"--duration: {exc}") from None
        lay = _load_layout(layout)
        faults = tuple(_parse_fault(f) for f in (fault or []))
        for f in faults:
            known = {h.id for h in lay.heads} if f.kind not in ("eot_loss", "head_loss") else None
            if known is not None and f.target not in known:
                raise _fail(f"--fault {f.kind}: {f.target} is not a counting head of {lay.source}")
        if output.exists() and not output.is_dir():
            raise _fail(f"{output}: exists and is not a directory")
        config = SimConfig(
            seed=seed, trains_per_hour=trains_per_hour, radio=LoRaLink(spreading_factor=spreading_factor), faults=faults
        )
        try:
            sim = StationSim(lay, config)
        except ValueError as exc:
            raise _fail(str(exc)) from None
        # The bar counts simulated milliseconds (it only shows on a terminal, for long runs).
        with byte_progress(int(seconds * 1000) if seconds >= 600 else 0, "simulating") as advance:
            last = [0.0]

            def tick(t_s: float) -> None:
                if advance is not None:
                    advance(int((t_s - last[0]) * 1000))
                    last[0] = t_s

            sim.run(seconds, on_step=tick)
        counts = write_run(sim, output)
        sim_sections = {
            s: {"console": str(sim.engine.state(s)), "true_count": sim.true_count(s)} for s in sim.engine.sections
        }
        summary = {
            "schema": "trackside.simulate/1",
            "output": str(output),
            "layout": lay.source,
            "seed": seed,
            "duration_s": seconds,
            "trains": len(sim.trains),
            "axles": len(sim.truth_axles),
            "report_period_s": round(sim.period_s, 2),
            "written": counts,
            "sections": {
                s: {"console": str(sim.engine.state(s)), "true_count": sim.true_count(s)} for s in sim.engine.sections
            },
        }
        if json_out:
            _print_json(summary)
        else:
            out = Console(highlight=False)
            out.print(
                f"simulated {duration} on {lay.name} (seed {seed}): {len(sim.trains)} trains, "
                f"{len(sim.truth_axles)} axle passages; GNSS every {sim.period_s:.1f} s (LoRa SF{spreading_factor})",
                markup=False,
            )
            for name, n in counts.items():
                out.print(f"  {output / name}: {n}", markup=False)
            for sid, st in sim_sections.items():
                out.print(
                    f"  section {sid}: console {st['console']}, axles really inside {st['true_count']}", markup=False
                )
        return exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def ato(
    controller: Annotated[str, typer.Option("--controller", help="pid, fuzzy, fuzzy-d or all.")] = "all",
    plant: Annotated[
        str, typer.Option("--plant", help="force (our train model), linear (the paper's G(s)) or both.")
    ] = "force",
    plot: Annotated[bool, typer.Option("--plot", help="Draw speed against distance in the terminal.")] = False,
    json_out: JsonOpt = False,
) -> None:
    """Seed 001's automatic train operation run: PID, fuzzy and Fuzzy-D beside the paper's figures."""

    def body() -> int:
        from console.render.ato_view import ato_json, ato_plot, ato_table
        from console.sim.ato import run_scenario
        from console.sim.control import CONTROLLER_NAMES

        names = list(CONTROLLER_NAMES) if controller == "all" else [controller]
        if any(n not in CONTROLLER_NAMES for n in names):
            raise _fail(f"--controller: expected pid, fuzzy, fuzzy-d or all, found {controller!r}")
        plants = ["force", "linear"] if plant == "both" else [plant]
        if any(p not in ("force", "linear") for p in plants):
            raise _fail(f"--plant: expected force, linear or both, found {plant!r}")
        results = [run_scenario(n, p) for p in plants for n in names]
        if json_out:
            doc = ato_json(results)
            sys.stdout.write(__import__("json").dumps(doc, ensure_ascii=True, allow_nan=False) + "\n")
        else:
            out = Console(highlight=False)
            out.print(ato_table(results))
            if plot:
                for p in plants:
                    out.print(ato_plot(results, width=min(out.width, 100), height=20, plant=p))
        return exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def station(
    layout: Annotated[str, typer.Option("--layout", help="Layout file, or osong / example.")] = "example",
    seed: Annotated[int, typer.Option("--seed", help="Simulation seed.")] = 1,
    speed: Annotated[
        float, typer.Option("--speed", help="Playback speed, 1 to 1000 × real time.", min=1, max=1000)
    ] = 5,
    replay: Annotated[
        bool,
        typer.Option("--replay", help="Replay FILES (diagnostic records, GNSS telemetry) instead of simulating."),
    ] = False,
    files: Annotated[list[Path] | None, typer.Argument(help="Logs to replay (with --replay).")] = None,
) -> None:
    """The live station view: sections, trains, crossings and events, simulated or replayed."""

    def body() -> int:
        from console.tui.app import StationApp
        from console.tui.model import SPEEDS, StationModel
        from console.tui.sources import ReplaySource, SimSource

        lay = _load_layout(layout)
        if replay and not files:
            raise _fail("--replay needs the logs to replay: trackside station --replay FILES...")
        if files and not replay:
            raise _fail("FILES are replayed: add --replay (trackside station --replay FILES...)")
        if files:
            _check_inputs(files)
            try:
                source: Any = ReplaySource(files, lay)
            except ValueError as exc:
                raise _fail(str(exc)) from None
        else:
            try:
                source = SimSource(lay, seed=seed)
            except ValueError as exc:
                raise _fail(str(exc)) from None
        if not (sys.stdin.isatty() and sys.stdout.isatty()):
            # Textual would draw into a pipe and wait for keys that never come.
            raise _fail("the station view needs a terminal: run it without pipes or redirection")
        model = StationModel(source)
        model.speed_index = min(range(len(SPEEDS)), key=lambda i: abs(SPEEDS[i] - speed))
        StationApp(model).run()
        return exit_codes.OK

    raise typer.Exit(_guard(body))


@app.command()
def report(
    inputs: Annotated[
        list[Path], typer.Argument(help="Log files or directories (a `trackside simulate` output reads whole).")
    ],
    layout: Annotated[
        str | None,
        typer.Option("--layout", help="Layout file, or osong / example (default: a layout.toml among the inputs)."),
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="md, html or json.")] = "md",
    output: Annotated[
        Path | None, typer.Option("-o", "--output", help="Write here (atomically) instead of to stdout.")
    ] = None,
    fail_on: Annotated[
        str | None,
        typer.Option("--fail-on", help="Exit 1 when a finding reaches this severity (info, warning, critical)."),
    ] = None,
) -> None:
    """A report for people (Markdown, HTML) or scripts (JSON): unsafe first, then failing, then the rest."""
    from console.report import run_report

    raise typer.Exit(run_report(inputs, layout, fmt, output, fail_on))


def _version(value: bool) -> None:
    if value:
        print(f"trackside {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")
    ] = False,
) -> None:
    """Terminal console and log analyzer for railway train detection."""
