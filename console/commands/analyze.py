"""trackside analyze."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from console import __version__, exit_codes
from console.commands.common import (
    JSON_SCHEMA_ANALYZE,
    REJECTIONS_LISTED,
    Console,
    FilesArg,
    IdleGapOpt,
    IncludeStatusOpt,
    JsonlOpt,
    JsonOpt,
    RejectedAllOpt,
    StrictOpt,
    fail,
    guard,
    layout_summary,
    load_layout,
    print_json,
    run_diag_stream,
)
from console.plural import count
from console.safe_text import clean

PASSAGES_SHOWN = 200  # rows of the text table; --json has all


def analyze(
    files: FilesArg,
    spacing: Annotated[
        float | None,
        typer.Option(
            "--spacing", metavar="M", help="Coil spacing Sys1–Sys2, m [default: the layout's, 0.13]", min=0.001
        ),
    ] = None,
    train_length: Annotated[
        float | None,
        typer.Option(
            "--train-length",
            metavar="M",
            help="First-to-last wheel, m [default: the layout's first consist, 28.6]",
            min=0.1,
        ),
    ] = None,
    idle_gap: IdleGapOpt = 10.0,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout", metavar="LAYOUT", help="Layout (file or osong, example): adds section and health summaries."
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: JsonlOpt = False,
    include_status: IncludeStatusOpt = False,
    rejected_all: RejectedAllOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Inventory, passages with speeds, and the parse report of diagnostic logs."""

    def body() -> int:
        from console.analysis.stream import FirstPassages
        from console.jobs import summarise_status, summary_doc
        from console.render.diag_stream import JsonLinesOut
        from console.render.passage_spool import PassageSpool

        if json_out and jsonl:
            raise fail("--json and --jsonl: choose one")
        if jsonl and layout:
            raise fail("--jsonl is not available with --layout yet; use --json")
        # Line facts come from the layout; the Osong test line when none is given.
        lay = load_layout(layout or "osong")
        consist = lay.consist()
        spacing_m = spacing if spacing is not None else lay.heads[0].spacing_m
        length_m = train_length if train_length is not None else (consist.length_m if consist else 28.6)
        summary = layout_summary(files, lay, spacing_m, length_m, idle_gap) if layout else None
        lines = JsonLinesOut(sys.stdout, None if rejected_all else REJECTIONS_LISTED) if jsonl else None
        # Passages go to a spool for --json, and only the first rows shown are kept for the text tables.
        first = FirstPassages(PASSAGES_SHOWN) if not (json_out or jsonl or summary) else None
        spool = PassageSpool() if json_out and not summary else None
        if summary:
            job = summary[0]
            if not include_status:
                summarise_status(job)
        else:
            job = run_diag_stream(
                files, spacing_m, length_m, idle_gap, include_status, rejected_all, lines, spool or first
            )
        if lines is not None:
            lines.finish((d.to_dict() for d in job.analysis.devices), summary_doc(job, JSON_SCHEMA_ANALYZE))
        elif json_out:
            from console.jobs import status_json
            from console.jsonout import RawJSON, array_parts

            passages = spool.json_parts() if spool is not None else RawJSON(job.analysis.passages_json_text())
            devices = array_parts(d.to_dict() for d in job.analysis.devices)  # encoded as written
            doc = {
                "schema": JSON_SCHEMA_ANALYZE,
                "trackside_version": __version__,
                "files": job.files,
                "parse_report": job.report.to_dict(),
                **job.analysis.to_dict(passages=passages, devices=devices),
            }
            if job.status is not None:
                doc["status_passages"] = status_json(job.status, job.analysis.heads)
            if summary:
                from console.render.section_tables import sections_json

                doc["layout"] = lay.source
                doc["sections"] = sections_json(summary[1])["sections"]
                doc["health"] = [f.to_dict() for f in summary[2]]
                doc["warnings"] = summary[3]
            print_json(doc)
            if spool is not None:
                spool.close()
        else:
            from console.render.diag_tables import (
                inventory_table,
                parse_report_table,
                passages_table,
                rejections_table,
            )

            out = Console(highlight=False)
            out.print(inventory_table(job.analysis))
            # Its caption says why axles are "–" and counts the wheel detections on one system only.
            out.print(
                passages_table(
                    job.analysis, limit=PASSAGES_SHOWN, first=first, unpaired=job.analysis.unpaired_detections
                )
            )
            out.print(parse_report_table(job.report))
            rej = rejections_table(job.report)
            if rej is not None:
                out.print(rej)
            notes = []
            if job.analysis.overlap_records:
                n = job.analysis.overlap_records
                notes.append(
                    f"{count(n, 'record')} {'repeats' if n == 1 else 'repeat'} another file's records"
                    " (overlapping exports) and were counted once; per file in the parse report"
                )
            if job.report.unknown_labels:
                notes.append(
                    f"{count(sum(job.report.unknown_labels.values()), 'record')} with unknown labels: "
                    + ", ".join(sorted(job.report.unknown_labels))
                )
            if job.status is not None and job.status.passages.sum():
                notes.append(
                    f"{count(int(job.status.passages.sum()), 'passage of status records only')} (no wheel onset)"
                    " not listed;"
                    " --include-status lists them"
                )
            for n in notes:
                out.print(clean(n), markup=False)
            if summary:
                from console.render.health_tables import findings_view
                from console.render.section_tables import final_states_table

                out.print(final_states_table(summary[1]))
                out.print(findings_view(summary[2], show_info=False, title="Health"))
                for w in summary[3]:
                    out.print(clean(f"warning: {w}"), markup=False)
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
