"""trackside health."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.common import (
    Console,
    check_inputs,
    fail,
    guard,
    load_layout,
    one_json_form,
    print_document,
    read_logs,
    refuse_unread,
    refuse_wrong_kind,
    rejected_note,
)
from console.cli.options import JsonOpt, RecordsJsonlOpt, StrictOpt
from console.safe_text import clean


def _worst(findings: list[Any]) -> Any:
    from console.analysis.health.findings import Severity

    return max((f.severity for f in findings), default=Severity.INFO, key=lambda s: s.rank)


def health(
    files: Annotated[
        list[Path] | None,
        typer.Argument(metavar="FILE...", help="Diagnostic log files (plain or .gz).", show_default=False),
    ] = None,
    layout: Annotated[
        str | None,
        typer.Option("--layout", metavar="LAYOUT", help="Layout (analog bands per head): a file or osong, example."),
    ] = None,
    voltages: Annotated[
        list[Path] | None,
        typer.Option(
            "--voltages",
            metavar="CSV",
            help="Receiver voltage table(s): sensor, in-phase mV, anti-phase mV (repeatable).",
        ),
    ] = None,
    fail_on: Annotated[
        str | None,
        typer.Option(
            "--fail-on",
            metavar="info|warning|critical",
            help="Exit 1 when a finding reaches this severity: info, warning, critical.",
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Sensor and channel health: analog bands, voltage margins, disturbance rates, faulty channels."""

    def body() -> int:
        from console.analysis.diag_events import DiagEventSettings
        from console.analysis.health.findings import Severity, sort_findings
        from console.analysis.health.voltage import voltage_margin_findings
        from console.sinks.tables.health_tables import findings_view
        from parsers.voltages import read_voltages

        one_json_form(json_out, jsonl)
        if not files and not voltages:
            raise fail("give diagnostic log files, --voltages tables, or both")
        threshold = None
        if fail_on is not None:
            try:
                threshold = Severity.parse(fail_on)
            except ValueError as exc:
                raise fail(f"--fail-on: {exc}") from None
        lay = load_layout(layout) if layout else None
        findings: list[Any] = []
        reports: list[Any] = []
        warnings: list[str] = []
        if files:
            from console.engine.pipeline import HEALTH_REGISTERS, PipelineSettings

            # In bounded memory: only the channel-fault events and the health registers' records are kept.
            settings = PipelineSettings(
                events=DiagEventSettings(), layout=lay, keep_registers=HEALTH_REGISTERS, health="end"
            )
            job = read_logs(files, settings)
            warnings = job.warnings
            findings += job.findings
            reports.append(job.report)
        if voltages:
            check_inputs(voltages)
            refuse_wrong_kind(voltages, "voltages")
            table, vreport = read_voltages(voltages)
            refuse_unread(vreport, "voltages")
            findings += voltage_margin_findings(table)
            reports.append(vreport)
        findings = sort_findings(findings)
        rejected = sum(r.rejected for r in reports)
        if json_out or jsonl:
            print_document(
                {
                    "schema": "trackside.health/1",
                    "files": [str(p) for p in (files or [])],
                    "voltages": [str(p) for p in (voltages or [])],
                    "findings": [f.to_dict() for f in findings],
                    "parse_reports": [r.to_dict() for r in reports],
                    "warnings": warnings,
                },
                {"findings": "finding", "parse_reports": "parse_report"} if jsonl else None,
            )
        else:
            out = Console(highlight=False)
            out.print(findings_view(findings))
            for w in warnings:
                out.print(f"warning: {clean(w)}", markup=False)  # names from the input: escaped
            if rejected:
                out.print(rejected_note(rejected, "--json lists them"), markup=False)
        failing = threshold is not None and any(f.severity >= threshold for f in findings)
        return exit_codes.FINDINGS if failing or (strict and rejected) else exit_codes.OK

    raise typer.Exit(guard(body))
