"""trackside report."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from console.cli.common import fail, guard
from console.fleet.options import EngineOpt, SchedulerOpt, WorkersOpt


def report(
    inputs: Annotated[
        list[Path] | None,
        typer.Argument(
            metavar="INPUT...",
            help="Log files or directories (a `trackside simulate` output reads whole); - reads stdin.",
        ),
    ] = None,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="Layout file, or osong / example (default: a layout.toml among the inputs).",
        ),
    ] = None,
    fmt: Annotated[str, typer.Option("--format", metavar="md|html|json", help="md, html or json.")] = "md",
    output: Annotated[
        Path | None,
        typer.Option(
            "-o",
            "--output",
            metavar="FILE",
            help="Write here (atomically; never over an input; a device or FIFO written through) instead of stdout.",
        ),
    ] = None,
    fail_on: Annotated[
        str | None,
        typer.Option(
            "--fail-on",
            metavar="info|warning|critical",
            help="Exit 1 when a finding reaches this severity (info, warning, critical).",
        ),
    ] = None,
    archive: Annotated[
        Path | None,
        typer.Option(
            "--archive", metavar="DIR", help="Report from this archive instead of files (see trackside ingest)."
        ),
    ] = None,
    start: Annotated[
        str | None, typer.Option("--from", metavar="TIME", help="With --archive: from this time (ISO).")
    ] = None,
    end: Annotated[
        str | None, typer.Option("--to", metavar="TIME", help="With --archive: up to this time (ISO, excluded).")
    ] = None,
    head: Annotated[
        str | None, typer.Option("--head", metavar="HEAD", help="With --archive: one counting head.")
    ] = None,
    device: Annotated[int | None, typer.Option("--device", metavar="ID", help="With --archive: one device id.")] = None,
    engine: EngineOpt = "local",
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
) -> None:
    """A report for people (Markdown, HTML) or scripts (JSON): unsafe first, then failing, then the rest."""

    def body() -> int:
        from console.cli.commands.engine import checked_spec, engine_failure
        from console.sinks.report.command import run_report

        spec = checked_spec(engine, workers, scheduler)
        on_archive = archive is not None or start or end or head or device is not None
        if spec.kind != "local" and not on_archive:
            raise fail("--engine dask needs --archive (a report on files runs here)")
        if on_archive:
            from console.archive.history import archive_collector

            if inputs and archive is None:
                window = (("--from", start), ("--to", end), ("--head", head), ("--device", device))
                given = next(name for name, value in window if value is not None and value != "")
                raise fail(f"{given} goes with --archive DIR (a report on files covers them whole): drop it")
            if inputs:
                raise fail("give input files or --archive, not both")
            if archive is not None and output is not None and os.fsdecode(output) != "-":
                from console.output_path import OutputError, check_outside

                try:
                    check_outside(output, archive, what="report")  # never a file among the archive's own
                except OutputError as exc:
                    raise fail(str(exc)) from None
            from console.archive.health_days import with_trends_and_forecast
            from console.cli.common import Console
            from console.fleet import engine_scope
            from console.fleet.options import FleetError

            collector = with_trends_and_forecast(
                archive_collector(archive, layout, start, end, head, device), archive, start, end, head, device
            )
            from console.archive.store import archive_dir
            from console.archive.views import one_connection

            err = Console(stderr=True, highlight=False)
            try:
                # The archive's partitions the report computes run on the engine (a LocalCluster lives as long);
                # the report's reads of the archive share one DuckDB database.
                with (
                    engine_scope(spec, say=lambda line: err.print(line, markup=False, soft_wrap=True), console=err),
                    one_connection(archive_dir(archive)),
                ):
                    return run_report([], layout, fmt, output, fail_on, collector=collector)
            except FleetError as exc:
                raise engine_failure(exc) from None
        return run_report(inputs or [], layout, fmt, output, fail_on)

    raise typer.Exit(guard(body))
