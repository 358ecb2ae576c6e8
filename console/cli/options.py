"""The option and argument types the commands share (Typer ``Annotated`` types)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

STDIN = "-"  # a file argument that means standard input

FilesArg = Annotated[
    list[Path],
    typer.Argument(
        metavar="FILE...", help="Diagnostic log files (plain or .gz; - reads standard input).", show_default=False
    ),
]
SpacingOpt = Annotated[
    float | None,
    typer.Option(
        "--spacing",
        metavar="M",
        help="Coil spacing Sys1–Sys2 of every head, m [default: each head's from the layout, 0.13]",
        min=0.001,
    ),
]
TrainLengthOpt = Annotated[
    float | None,
    typer.Option(
        "--train-length",
        metavar="M",
        help="First-to-last wheel, m [default: the layout's first consist, 28.6]",
        min=0.1,
    ),
]
IdleGapOpt = Annotated[
    float, typer.Option("--idle-gap", metavar="S", help="Seconds without records that end a passage (≥ 1).", min=1.0)
]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON document on stdout instead of tables.")]
StrictOpt = Annotated[bool, typer.Option("--strict", help="Exit 1 if any input line was rejected.")]

# The commands that compute a whole document (JSONL: its records, then a summary line).
RecordsJsonlOpt = Annotated[
    bool,
    typer.Option(
        "--jsonl", help="JSON lines on stdout: one object per record, its `type` saying which, then a summary."
    ),
]
JsonlOpt = Annotated[
    bool,
    typer.Option("--jsonl", help="JSON lines on stdout, each written as found: rejected, passage, device, summary."),
]
IncludeStatusOpt = Annotated[
    bool,
    typer.Option(
        "--include-status",
        help="List the status-only record bursts (no wheel onset) as passages (default: counted per head).",
    ),
]
RejectedAllOpt = Annotated[
    bool, typer.Option("--rejected-all", help="List every rejected line (default: all counted, the first 100 listed).")
]
# Rejected lines listed (and held) by default; all are counted.
REJECTIONS_LISTED = 100


LayoutOpt = Annotated[
    str,
    typer.Option(
        "--layout", metavar="LAYOUT", help="Layout TOML file, or a shipped one: osong, example.", show_default=False
    ),
]

GnssFilesArg = Annotated[
    list[Path],
    typer.Argument(
        metavar="FILE...",
        help="GNSS telemetry: NMEA, device streams (CSV, JSON lines), monitoring-centre tables; - reads stdin.",
        show_default=False,
    ),
]
