"""trackside speeds."""

from __future__ import annotations

import typer

from console import exit_codes
from console.commands.common import (
    Console,
    FilesArg,
    IdleGapOpt,
    JsonOpt,
    SpacingOpt,
    StrictOpt,
    TrainLengthOpt,
    guard,
    print_json,
    run_diag,
)


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
        job = run_diag(files, spacing, train_length, idle_gap)
        if json_out:
            from console.jsonout import RawJSON

            text = RawJSON(job.analysis.passages_json_text())
            print_json({"schema": "trackside.speeds/1", "passages": text})
        else:
            from console.render.diag_tables import passages_table

            Console(highlight=False).print(passages_table(job.analysis))
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
