"""What the commands share: option types, one-line errors, the guard that turns
input errors into exit 2, JSON output, layouts and the diagnostic job."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console as RichConsole

from console import exit_codes

JSON_SCHEMA_ANALYZE = "trackside.analyze/1"

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


LayoutOpt = Annotated[
    str,
    typer.Option("--layout", help="Layout TOML file, or a shipped one: osong, example.", show_default=False),
]

GnssFilesArg = Annotated[
    list[Path],
    typer.Argument(
        help="GNSS telemetry: NMEA, device streams (CSV, JSON lines), monitoring-centre tables.", show_default=False
    ),
]


def fail(message: str, code: int = exit_codes.USAGE) -> typer.Exit:
    """One unwrapped line on stderr (file names may hold anything: escaped)."""
    from console.safe_text import clean

    sys.stderr.write(f"trackside: error: {clean(message)}\n")
    sys.stderr.flush()
    return typer.Exit(code)


def check_inputs(paths: list[Path]) -> None:
    for p in paths:
        if not p.exists():
            raise fail(f"{p}: no such file")
        if p.is_dir():
            raise fail(f"{p}: is a directory, expected a log file")
        if not os.access(p, os.R_OK):
            raise fail(f"{p}: permission denied")


class Console(RichConsole):
    """Rich's console, but a reader that stops early (``| head``) is not an error:
    Rich exits 1 on a broken pipe; we stop quietly with 0."""

    def on_broken_pipe(self) -> None:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        raise SystemExit(exit_codes.OK)


def guard(fn: Callable[[], int]) -> int:
    """Run a command body: input errors become one-line messages and exit 2."""
    from parsers.sources import InputError

    try:
        return fn()
    except (typer.Exit, typer.Abort):
        raise
    except InputError as exc:
        raise fail(str(exc)) from None
    except BrokenPipeError:
        # Output piped into `head` or similar: stop quietly.
        sys.stderr.close()
        return exit_codes.OK
    except MemoryError:
        raise fail("out of memory") from None
    except Exception as exc:
        if os.environ.get("TRACKSIDE_DEBUG"):
            raise
        raise fail(f"internal error: {type(exc).__name__}: {exc} (set TRACKSIDE_DEBUG=1 for details)") from None


def print_json(doc: dict[str, Any]) -> None:
    from console.jsonout import write

    write(doc, sys.stdout)
    sys.stdout.flush()


def layout_summary(files: list[Path], lay: Any, spacing: float, length: float, idle_gap: float) -> Any:
    """One pass for `analyze --layout`: the job, section states and health findings."""
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.diagnostics import SpeedSettings
    from console.analysis.sections import run_sections
    from console.jobs import HEALTH_REGISTERS, analyze_files, detection_events, health_findings, input_bytes
    from console.progress import byte_progress

    check_inputs(files)
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


def run_diag(
    files: list[Path], spacing: float, train_length: float, idle_gap: float, keep_releases: bool = False
) -> Any:
    from console.analysis.diagnostics import SpeedSettings
    from console.jobs import analyze_files, input_bytes
    from console.progress import byte_progress

    check_inputs(files)
    settings = SpeedSettings(spacing_m=spacing, train_length_m=train_length, idle_gap_s=idle_gap)
    with byte_progress(input_bytes(files), "parsing") as advance:
        return analyze_files(files, settings, on_progress=advance, keep_releases=keep_releases)


def load_layout(spec: str) -> Any:
    from console.layout import LayoutError, load_layout

    try:
        return load_layout(spec)
    except LayoutError as exc:
        raise fail(str(exc)) from None
