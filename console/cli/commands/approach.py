"""trackside approach."""

from __future__ import annotations

from dataclasses import replace
from typing import Annotated

import typer

from console import exit_codes
from console.cli.common import (
    Console,
    fail,
    guard,
    load_layout,
    one_json_form,
    print_document,
    read_logs,
    rejected_note,
)
from console.cli.options import FilesArg, JsonOpt, RecordsJsonlOpt, StrictOpt
from console.layout import MAX_CHAINAGE_M, MAX_TIME_S


def approach(
    files: FilesArg,
    # Required, as in sections and crossing: a site is a distance from a head of one line, and the shipped
    # osong layout it defaulted to read another line's log silently (example_station's WS4 is not Osong's).
    layout: Annotated[
        str,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="The line's layout: its [[work_sites]], or the heads --head names (file, or osong / example).",
            show_default=False,
        ),
    ],
    head: Annotated[
        str | None, typer.Option("--head", metavar="HEAD", help="Approach counting head of an ad-hoc site.")
    ] = None,
    distance: Annotated[
        float | None,
        typer.Option("--distance", metavar="M", help="Metres from the head to the site: + up the line, − down."),
    ] = None,
    warning_time: Annotated[
        float | None,
        typer.Option(
            "--warning-time",
            metavar="S",
            help=(
                "Seconds of warning the workers need, at every site (default: each layout site's own "
                "warning_time_s; 30 for an ad-hoc site)."
            ),
            min=1,
            max=MAX_TIME_S,
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Track-worker approach warnings: alarm from detection vs from the speed measured at the head.

    --layout is required: the sites are its [[work_sites]] (osong and example ship some), or one ad-hoc site
    given by --head and --distance on its heads."""

    def body() -> int:
        one_json_form(json_out, jsonl)
        from console.analysis.crossing.approach import approach_timeline
        from console.layout import WorkSite
        from console.sinks.tables.approach_tables import approach_table

        lay = load_layout(layout)
        sites = list(lay.work_sites)
        if head is not None or distance is not None:
            if head is None or distance is None or distance == 0:
                raise fail("an ad-hoc site needs both --head and a non-zero --distance")
            if abs(distance) > MAX_CHAINAGE_M:  # as a layout's distance_m
                raise fail(f"--distance: expected at most {MAX_CHAINAGE_M:g} m either way, got {distance:g}")
            if not lay.has_head(head):
                raise fail(f"--head {head}: not a counting head of {lay.source}")
            sites = [WorkSite("site", head, distance)]
        if not sites:
            raise fail(f"{lay.source} has no [[work_sites]]: give --head and --distance")
        if warning_time is not None:  # it was read for an ad-hoc site only: a layout's sites ignored it unsaid
            sites = [replace(site, warning_time_s=warning_time) for site in sites]
        from console.analysis.passages.speed_settings import SpeedSettings
        from console.engine.pipeline import PipelineSettings

        job = read_logs(files, PipelineSettings(speed=SpeedSettings.of_layout(lay)), hold_passages=True)
        rows = [r for site in sites for r in approach_timeline(job.analysis.passages, lay, site)]
        if json_out or jsonl:
            print_document(
                {
                    "schema": "trackside.approach/1",
                    "files": job.files,
                    "layout": lay.source,
                    "warnings": [r.to_dict() for r in rows],
                    "parse_report": job.report.to_dict(),
                },
                {"warnings": "approach_warning"} if jsonl else None,
            )
        else:
            out = Console(highlight=False)
            out.print(approach_table(rows))
            if job.report.rejected:  # a rejected line may be a detection the table lacks
                out.print(rejected_note(job.report.rejected), markup=False)
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
