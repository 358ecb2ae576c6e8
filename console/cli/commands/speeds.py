"""trackside speeds."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from console import exit_codes
from console.cli.common import (
    Console,
    guard,
    load_layout,
    one_json_form,
    print_json,
    read_logs,
    rejected_note,
    status_only_note,
)
from console.cli.options import (
    REJECTIONS_LISTED,
    FilesArg,
    IdleGapOpt,
    IncludeStatusOpt,
    JsonlOpt,
    JsonOpt,
    SpacingOpt,
    StrictOpt,
    TrainLengthOpt,
)


def speeds(
    files: FilesArg,
    spacing: SpacingOpt = None,
    train_length: TrainLengthOpt = None,
    idle_gap: IdleGapOpt = 10.0,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="Layout (file or osong, example): each head's coil spacing, the first consist's length.",
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: JsonlOpt = False,
    include_status: IncludeStatusOpt = False,
    strict: StrictOpt = False,
) -> None:
    """The passages table alone: per-second, whole-train and per-axle speeds."""

    def body() -> int:
        from console.analysis.passages.speed_settings import SpeedSettings
        from console.engine.pipeline import PipelineSettings
        from console.sinks.tables.diag_stream import JsonLinesOut, status_json, summary_doc
        from console.sinks.tables.passage_spool import PassageSpool

        one_json_form(json_out, jsonl)
        lines = JsonLinesOut(sys.stdout, REJECTIONS_LISTED) if jsonl else None
        spool = PassageSpool() if json_out else None
        lay = load_layout(layout) if layout else None
        speed = SpeedSettings.of_layout(lay, spacing, train_length, idle_gap)
        settings = PipelineSettings(speed=speed, include_status=include_status)
        # The text table lists every passage: held as one table.
        job = read_logs(files, settings, spool, jsonl=lines, hold_passages=not (json_out or jsonl))
        if lines is not None:
            lines.finish([], summary_doc(job, "trackside.speeds/1"))
        elif json_out:
            assert spool is not None
            doc = {"schema": "trackside.speeds/1", "passages": spool.json_parts()}
            if job.status is not None:
                doc["status_passages"] = status_json(job.status, job.analysis.heads)
            print_json(doc)
            if spool is not None:
                spool.close()
        else:
            from console.sinks.tables.diag_tables import passages_table

            out = Console(highlight=False)
            out.print(passages_table(job.analysis, unpaired=job.analysis.unpaired_detections))
            # Said, as analyze says them: a rejected line is a record the per-second count lacks, and a log of
            # status records alone would otherwise be an empty table without a word.
            if job.status is not None and job.status.passages.sum():
                out.print(status_only_note(int(job.status.passages.sum())), markup=False)
            if job.report.rejected:
                out.print(rejected_note(job.report.rejected), markup=False)
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
