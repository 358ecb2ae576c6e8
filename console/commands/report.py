"""trackside report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from console.commands.common import guard


def report(
    inputs: Annotated[
        list[Path],
        typer.Argument(help="Log files or directories (a `trackside simulate` output reads whole); - reads stdin."),
    ],
    layout: Annotated[
        str | None,
        typer.Option("--layout", help="Layout file, or osong / example (default: a layout.toml among the inputs)."),
    ] = None,
    fmt: Annotated[str, typer.Option("--format", help="md, html or json.")] = "md",
    output: Annotated[
        Path | None,
        typer.Option(
            "-o",
            "--output",
            help="Write here (atomically; never over an input; a device or FIFO written through) instead of stdout.",
        ),
    ] = None,
    fail_on: Annotated[
        str | None,
        typer.Option("--fail-on", help="Exit 1 when a finding reaches this severity (info, warning, critical)."),
    ] = None,
) -> None:
    """A report for people (Markdown, HTML) or scripts (JSON): unsafe first, then failing, then the rest."""

    def body() -> int:
        from console.report import run_report

        return run_report(inputs, layout, fmt, output, fail_on)

    raise typer.Exit(guard(body))
