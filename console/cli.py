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
from rich.console import Console

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


def _run_diag(files: list[Path], spacing: float, train_length: float, idle_gap: float) -> Any:
    from console.analysis.diagnostics import SpeedSettings
    from console.jobs import analyze_files, input_bytes
    from console.progress import byte_progress

    _check_inputs(files)
    settings = SpeedSettings(spacing_m=spacing, train_length_m=train_length, idle_gap_s=idle_gap)
    with byte_progress(input_bytes(files), "parsing") as advance:
        return analyze_files(files, settings, on_progress=advance)


@app.command()
def analyze(
    files: FilesArg,
    spacing: SpacingOpt = 0.13,
    train_length: TrainLengthOpt = 28.6,
    idle_gap: IdleGapOpt = 10.0,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Inventory, passages with speeds, and the parse report of diagnostic logs."""

    def body() -> int:
        job = _run_diag(files, spacing, train_length, idle_gap)
        if json_out:
            from console.analysis.diagnostics import passages_json_text
            from console.jsonout import RawJSON

            doc = {
                "schema": JSON_SCHEMA_ANALYZE,
                "trackside_version": __version__,
                "files": job.files,
                "parse_report": job.report.to_dict(),
                **job.analysis.to_dict(passages=RawJSON(passages_json_text(job.analysis.passages))),
            }
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
            from console.analysis.diagnostics import passages_json_text
            from console.jsonout import RawJSON

            text = RawJSON(passages_json_text(job.analysis.passages))
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
        job = _run_diag(files, lay.heads[0].spacing_m, 28.6, 10.0)
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
