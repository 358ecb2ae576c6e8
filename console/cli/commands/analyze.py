"""trackside analyze."""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Annotated

import typer

from console import __version__, exit_codes
from console.cli.common import (
    JSON_SCHEMA_ANALYZE,
    guard,
    load_layout,
    one_json_form,
    print_json,
    read_logs,
    status_only_note,
)
from console.cli.options import (
    REJECTIONS_LISTED,
    FilesArg,
    IdleGapOpt,
    IncludeStatusOpt,
    JsonlOpt,
    JsonOpt,
    RejectedAllOpt,
    SpacingOpt,
    StrictOpt,
    TrainLengthOpt,
)
from console.plural import count
from console.safe_text import clean

PASSAGES_SHOWN = 200  # rows of the text table; --json has all


def analyze(
    files: FilesArg,
    spacing: SpacingOpt = None,
    train_length: TrainLengthOpt = None,
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
        from console.analysis.passages.speed_settings import SpeedSettings
        from console.engine.pipeline import HEALTH_REGISTERS, PipelineSettings
        from console.sinks.tables.diag_stream import JsonLinesOut, status_json, summary_doc
        from console.sinks.tables.passage_spool import FirstPassages, PassageSpool

        one_json_form(json_out, jsonl)
        # Line facts come from the layout; the Osong test line when none is given.
        lay = load_layout(layout or "osong")
        settings = PipelineSettings(
            speed=SpeedSettings.of_layout(lay, spacing, train_length, idle_gap), include_status=include_status
        )
        if layout:
            from console.analysis.diag_events import DiagEventSettings
            from console.sinks.tables.section_tables import sections_summary

            # With a layout: the section states and the health findings too, from the same read.
            settings = replace(
                settings,
                events=DiagEventSettings(),
                layout=lay,
                sections=lay if lay.sections else None,
                keep_registers=HEALTH_REGISTERS,
                health="end",
            )
        lines = JsonLinesOut(sys.stdout, None if rejected_all else REJECTIONS_LISTED) if jsonl else None
        # Passages go to a spool for --json, and only the first rows shown are kept for the text tables.
        first = FirstPassages(PASSAGES_SHOWN) if not (json_out or jsonl) else None
        spool = PassageSpool() if json_out else None
        job = read_logs(files, settings, spool or first, jsonl=lines, rejected_all=rejected_all)
        findings = job.findings
        engine = job.sections
        final = engine.final_states() if engine is not None else {}
        if lines is not None:
            summary = summary_doc(job, JSON_SCHEMA_ANALYZE)
            if layout:
                summary.update(layout=lay.source, **sections_summary(final), warnings=job.warnings)
            lines.finish((d.to_dict() for d in job.analysis.devices), summary, findings)
        elif json_out:
            from console.jsonout import array_parts

            assert spool is not None
            devices = array_parts(d.to_dict() for d in job.analysis.devices)  # encoded as written
            doc = {
                "schema": JSON_SCHEMA_ANALYZE,
                "trackside_version": __version__,
                "files": job.files,
                "parse_report": job.report.to_dict(),
                **job.analysis.to_dict(passages=spool.json_parts(), devices=devices),
            }
            if job.status is not None:
                doc["status_passages"] = status_json(job.status, job.analysis.heads)
            if layout:
                doc["layout"] = lay.source
                doc.update(sections_summary(final))
                doc["health"] = [f.to_dict() for f in findings]
                doc["warnings"] = job.warnings
            print_json(doc)
            spool.close()
        else:
            from console.cli.common import Console  # Rich: loaded for the tables only, not for --json
            from console.sinks.tables.diag_tables import (
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
                    f" (overlapping exports) and {'was' if n == 1 else 'were'} counted once;"
                    " per file in the parse report"
                )
            if job.report.unknown_labels:
                notes.append(
                    f"{count(sum(job.report.unknown_labels.values()), 'record')} with unknown labels: "
                    + ", ".join(sorted(job.report.unknown_labels))
                )
            if job.status is not None and job.status.passages.sum():
                notes.append(status_only_note(int(job.status.passages.sum())))
            for n in notes:
                out.print(clean(n), markup=False)
            if layout:
                from console.sinks.tables.health_tables import findings_view
                from console.sinks.tables.section_tables import final_states_view

                out.print(final_states_view(final))
                out.print(findings_view(findings, show_info=False, title="Health"))
                for w in job.warnings:
                    out.print(clean(f"warning: {w}"), markup=False)
        return exit_codes.FINDINGS if strict and job.report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
