"""The option and argument types the commands share (Typer ``Annotated`` types)."""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

STDIN = "-"  # a file argument that means standard input

FilesArg = Annotated[
    list[Path],
    typer.Argument(
        metavar="FILE...", help="Diagnostic log files (plain or .gz; - reads standard input).", show_default=False
    ),
]
SpacingOpt = Annotated[
    float, typer.Option("--spacing", metavar="M", help="Coil spacing Sys1–Sys2 of the counting head, m.", min=0.001)
]
TrainLengthOpt = Annotated[
    float, typer.Option("--train-length", metavar="M", help="First-to-last wheel distance of the train, m.", min=0.1)
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


# Every number option of every command, checked once here: Click's FloatRange lets nan through, and inf or
# 1e308 pass an open bound, then overflow a time in nanoseconds deep in a command (an internal error).  No
# option means anything beyond 1e9 (31 years in seconds, a million km in metres).
MAX_OPTION_NUMBER = 1e9


def finite_numbers(command: Callable[..., Any]) -> Callable[..., Any]:
    """``command`` refusing a number option that is not finite or beyond :data:`MAX_OPTION_NUMBER`: one line
    naming the option, exit 2, before any work."""
    names = _option_names(command)

    @functools.wraps(command)
    def checked(*args: Any, **kwargs: Any) -> Any:
        for key, value in kwargs.items():
            for v in value if isinstance(value, list | tuple) else (value,):
                if isinstance(v, float) and not (math.isfinite(v) and abs(v) <= MAX_OPTION_NUMBER):
                    from console.cli.common import fail

                    raise fail(
                        f"{names.get(key, key)}: expected a finite number of at most {MAX_OPTION_NUMBER:g}, got {v!r}"
                    )
        return command(*args, **kwargs)

    return checked


def _option_names(command: Callable[..., Any]) -> dict[str, str]:
    """Parameter name → its longest option name (``idle_gap`` → ``--idle-gap``)."""
    out: dict[str, str] = {}
    for name, param in inspect.signature(command, eval_str=True).parameters.items():
        for meta in getattr(param.annotation, "__metadata__", ()):
            # Inside Annotated, typer.Option("--idle-gap", ...) keeps its first name where a default would go.
            given = (getattr(meta, "default", None), *(getattr(meta, "param_decls", ()) or ()))
            decls = [d for d in given if isinstance(d, str) and d.startswith("--")]
            if decls:
                out[name] = max(decls, key=len)
    return out
