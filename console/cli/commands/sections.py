"""trackside sections."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.common import Console, fail, guard, load_layout, one_json_form, read_logs, rejected_note
from console.cli.options import FilesArg, JsonOpt, LayoutOpt, RecordsJsonlOpt
from console.plural import count
from console.safe_text import clean


def _parse_resets(values: list[str], sections: set[str]) -> list[Any]:
    """``SECTION@DATE-TIME`` → reset events; a one-line usage error for anything else, before any reading."""
    import datetime as dt

    from console.analysis.events.detection import DetectionEvent, EventKind
    from console.analysis.timefmt import parse_time, time_ns

    example = "e.g. B1@2026-03-02T09:30:00"
    out = []
    for v in values:
        section, sep, when = (x.strip() for x in v.partition("@"))
        if not (sep and section and when):
            raise fail(f"--reset {v!r}: expected SECTION@DATE-TIME, {example}")
        if section not in sections:
            raise fail(f"--reset {v!r}: no section {section!r} in the layout (it has {', '.join(sorted(sections))})")
        try:
            t = parse_time(when)
        except ValueError:
            # A time alone would be taken on the machine's day, not the log's: the date is asked for.
            raise fail(f"--reset {v!r}: {when!r} is not a date and time, {example}") from None
        if not dt.datetime(1970, 1, 1) <= t < dt.datetime(2262, 1, 1):
            raise fail(f"--reset {v!r}: {when!r} is outside 1970-2261, the times a log can hold")
        out.append(DetectionEvent(time_ns(t), EventKind.RESET, section, source="operator", detail="--reset"))
    return out


def _resets_outside(resets: list[Any], job: Any) -> list[str]:
    """Warnings for reset requests outside the records' span: a mistyped date is decided all the same (before
    the log it moves the sections' start there, after it overrides their end state), so it is said."""
    from console.analysis.timefmt import iso

    devices = job.analysis.devices
    if not devices:
        return []
    first, last = min(d.first_ns for d in devices), max(d.last_ns for d in devices)
    return [
        f"--reset {r.head}@{iso(r.time_ns)}: {'before the first' if r.time_ns < first else 'after the last'}"
        f" record of the logs ({iso(first)} to {iso(last)})"
        for r in resets
        if not first <= r.time_ns <= last
    ]


def _document_head(job: Any, lay: Any, warnings: list[str]) -> dict[str, Any]:
    """What ``sections_json`` says before its rows (``--jsonl``: its summary line)."""
    return {
        "schema": "trackside.sections/1",
        "files": job.files,
        "layout": lay.source,
        "parse_report": job.report.to_dict(),
        "warnings": warnings,
    }


def _write_json(job: Any, lay: Any, final: dict[str, Any], sink: Any, warnings: list[str]) -> None:
    """The document of ``sections_json``, its timeline and ledger copied in from the sink's spill files."""
    import sys

    from console.jsonout import dumps
    from console.sinks.tables.section_tables import sections_summary

    head = dumps(_document_head(job, lay, warnings) | sections_summary(final))
    out = sys.stdout
    out.write(head[:-1] + ",")
    sink.write_json_arrays(out)
    out.write("}\n")
    out.flush()


def _write_jsonl(job: Any, lay: Any, final: dict[str, Any], sink: Any, warnings: list[str]) -> None:
    """``sections_json``'s rows as JSON lines: each section's end state, state changes, ledger rows, resets, then
    a summary."""
    import sys

    from console.jsonout import RawJSON, dumps, typed_line
    from console.sinks.tables.section_tables import sections_summary

    out = sys.stdout
    for row in sections_summary(final)["sections"]:
        out.write(typed_line("section_end", row) + "\n")
    for kind, text in sink.json_items():
        out.write(typed_line(kind, RawJSON(text)) + "\n")
    out.write(typed_line("summary", RawJSON(dumps(_document_head(job, lay, warnings)))) + "\n")
    out.flush()


def _print_tables(job: Any, final: dict[str, Any], sink: Any, warnings: list[str]) -> None:
    from console.analysis.sections.engine import SectionsResult, ledger_summary_frame
    from console.sinks.tables import section_tables as st

    head = job.sections.result(sink.timeline_first, [], sink.reset_rows)
    result = SectionsResult(head.timeline, head.ledger, head.resets, final, ledger_summary_frame(sink.ledger_totals))
    out = Console(highlight=False)
    out.print(st.final_states_table(result))
    timeline = st.timeline_table(result)
    # The table shows the first rows kept; title and caption count them all.
    limit, n = 200, sink.timeline_rows
    timeline.title = f"State timeline ({count(n, 'change')})"
    timeline.caption = f"first {limit} of {n}; --json has all" if n > limit else None
    out.print(timeline)
    out.print(st.ledger_summary_table(result))
    rt = st.resets_table(result)
    if rt is not None:
        out.print(rt)
    for w in warnings:
        out.print(clean(f"warning: {w}"), markup=False)
    if job.report.rejected:
        out.print(rejected_note(job.report.rejected), markup=False)


def sections(
    files: FilesArg,
    layout: LayoutOpt,
    reset: Annotated[
        list[str] | None,
        typer.Option(
            "--reset",
            metavar="SECTION@DATE-TIME",
            help="Ask to reset a section at a time: SECTION@DATE-TIME, e.g. B1@2026-03-02T09:30 (repeatable).",
            show_default=False,
        ),
    ] = None,
    power_gap: Annotated[
        float | None,
        typer.Option(
            "--power-gap",
            metavar="S",
            help="Seconds without records from a head that mean power loss (off unless set).",
            min=1.0,
        ),
    ] = None,
    initial: Annotated[
        str,
        typer.Option(
            "--initial",
            metavar="unknown|clear",
            help="Section state at the start of the log: unknown (until a sweep) or clear.",
        ),
    ] = "unknown",
    isolation: Annotated[
        float,
        typer.Option(
            "--isolation",
            metavar="S",
            help="Seconds of quiet before and after a lone pulse that make it accidental.",
            min=1.0,
        ),
    ] = 60.0,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 if a line was rejected or a section ends disturbed.")
    ] = False,
) -> None:
    """Section states from axle counting: state timeline, count ledger, resets."""

    def body() -> int:
        from console.analysis.counting.majority import MajoritySettings
        from console.analysis.counting.wheels import CountingSettings
        from console.analysis.diag_events import DiagEventSettings
        from console.analysis.passages.speed_settings import SpeedSettings
        from console.analysis.sections.state import SectionState
        from console.engine.pipeline import PipelineSettings
        from console.sinks.tables.section_history import SectionsSink

        one_json_form(json_out, jsonl)
        if initial not in ("unknown", "clear"):
            raise fail(f"--initial: expected unknown or clear, found {initial!r}")
        lay = load_layout(layout)
        if not lay.sections:
            raise fail(f"{lay.source}: the layout has no [[sections]]")
        resets = _parse_resets(reset or [], {s.id for s in lay.sections})
        events = DiagEventSettings(
            counting=CountingSettings(isolation_s=isolation),
            majority=MajoritySettings(isolation_s=isolation),
            power_gap_s=power_gap if power_gap is not None else lay.power_gap_s,
        )
        settings = PipelineSettings(
            speed=SpeedSettings.of_layout(lay, train_length_m=SpeedSettings.train_length_m),
            events=events,
            layout=lay,
            sections=lay,
            initial=SectionState.CLEAR if initial == "clear" else SectionState.PREPARATORY,
            resets=tuple(resets),
        )
        sink = SectionsSink(spill=json_out or jsonl)
        try:
            job = read_logs(files, settings, sink)
            assert job.sections is not None
            final = job.sections.final_states()
            warnings = [*job.warnings, *_resets_outside(resets, job)]
            disturbed = [sid for sid, f in final.items() if f[0] == SectionState.DISTURBED]
            if json_out:
                _write_json(job, lay, final, sink, warnings)
            elif jsonl:
                _write_jsonl(job, lay, final, sink, warnings)
            else:
                _print_tables(job, final, sink, warnings)
        finally:
            sink.close()
        return exit_codes.FINDINGS if strict and (job.report.rejected or disturbed) else exit_codes.OK

    raise typer.Exit(guard(body))
