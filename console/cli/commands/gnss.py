"""trackside gnss."""

from __future__ import annotations

import typer

from console import exit_codes
from console.cli.common import Console, check_inputs, fail, guard, one_json_form, print_document
from console.cli.options import GnssFilesArg, JsonOpt, RecordsJsonlOpt, StrictOpt


def gnss(
    files: GnssFilesArg, json_out: JsonOpt = False, jsonl: RecordsJsonlOpt = False, strict: StrictOpt = False
) -> None:
    """Decoded GNSS fixes per device, and the parse report."""

    def body() -> int:
        from console.memory import big_read_memory
        from console.sinks.tables.diag_tables import parse_report_table, rejections_table
        from console.sinks.tables.gnss_tables import (
            devices_table,
            fix_rows,
            fixes_table,
            gnss_json_parts,
            skipped_table,
        )
        from parsers.gnss_files import nothing_read, parse_gnss_columns
        from parsers.kinds import not_gnss_reason

        one_json_form(json_out, jsonl)
        check_inputs(files)
        for path in files:
            wrong = not_gnss_reason(path)
            if wrong is not None:
                raise fail(f"{path}: nothing readable as GNSS: {wrong}")
        with big_read_memory(files):
            fixes, report = parse_gnss_columns(files)  # numpy columns: no pandas for the tables
        unread = nothing_read(report)
        if unread:
            raise fail(unread[0])
        head = {"schema": "trackside.gnss/1", "files": [str(p) for p in files]}
        if json_out:
            print_document(head | gnss_json_parts(fixes, report), None)
        elif jsonl:
            rows = {"fixes": fix_rows(fixes), "parse_report": report.to_dict()}
            print_document(head | rows, {"fixes": "fix"})
        else:
            out = Console(highlight=False)
            out.print(devices_table(fixes))
            out.print(fixes_table(fixes))
            out.print(parse_report_table(report))
            skipped = skipped_table(report)
            if skipped is not None:
                out.print(skipped)
            rej = rejections_table(report)
            if rej is not None:
                out.print(rej)
        return exit_codes.FINDINGS if strict and report.rejected else exit_codes.OK

    raise typer.Exit(guard(body))
