"""trackside sections."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from console import exit_codes
from console.commands.common import (
    Console,
    FilesArg,
    JsonOpt,
    LayoutOpt,
    fail,
    guard,
    load_layout,
    print_json,
    run_diag,
)
from console.safe_text import clean


def _parse_resets(values: list[str]) -> list[Any]:
    import pandas as pd

    from console.analysis.events import DetectionEvent, EventKind

    out = []
    for v in values:
        section, sep, when = v.partition("@")
        try:
            t = pd.Timestamp(when) if sep and section else None
        except ValueError:
            t = None
        if t is None or pd.isna(t):
            raise fail(f"--reset {v!r}: expected SECTION@TIME, e.g. B1@2026-03-02T09:30:00")
        out.append(DetectionEvent(int(t.value), EventKind.RESET, section.strip(), source="operator", detail="--reset"))
    return out


def sections(
    files: FilesArg,
    layout: LayoutOpt,
    reset: Annotated[
        list[str] | None,
        typer.Option(
            "--reset", help="Ask to reset a section at a time: SECTION@TIME (repeatable).", show_default=False
        ),
    ] = None,
    power_gap: Annotated[
        float | None,
        typer.Option(
            "--power-gap", help="Seconds without records from a head that mean power loss (off unless set).", min=1.0
        ),
    ] = None,
    initial: Annotated[
        str, typer.Option("--initial", help="Section state at the start of the log: unknown (until a sweep) or clear.")
    ] = "unknown",
    isolation: Annotated[
        float,
        typer.Option(
            "--isolation", help="Seconds of quiet before and after a lone pulse that make it accidental.", min=1.0
        ),
    ] = 60.0,
    json_out: JsonOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 if a line was rejected or a section ends disturbed.")
    ] = False,
) -> None:
    """Section states from axle counting: state timeline, count ledger, resets."""

    def body() -> int:
        from console.analysis.diag_events import DiagEventSettings, diag_detection_events
        from console.analysis.majority import MajoritySettings
        from console.analysis.sections import SectionState, run_sections
        from console.analysis.wheels import CountingSettings
        from console.render import section_tables as st

        if initial not in ("unknown", "clear"):
            raise fail(f"--initial: expected unknown or clear, found {initial!r}")
        lay = load_layout(layout)
        if not lay.sections:
            raise fail(f"{lay.source}: the layout has no [[sections]]")
        resets = _parse_resets(reset or [])
        job = run_diag(files, lay.heads[0].spacing_m, 28.6, 10.0, keep_releases=True)
        settings = DiagEventSettings(
            counting=CountingSettings(isolation_s=isolation),
            majority=MajoritySettings(isolation_s=isolation),
            power_gap_s=power_gap,
        )
        events, warnings = diag_detection_events(job.analysis, lay, settings)
        start = SectionState.CLEAR if initial == "clear" else SectionState.PREPARATORY
        result = run_sections(lay, events + resets, initial=start)
        disturbed = [sid for sid, f in result.final.items() if f[0] == SectionState.DISTURBED]
        if json_out:
            print_json(
                {
                    "schema": "trackside.sections/1",
                    "files": job.files,
                    "layout": lay.source,
                    "parse_report": job.report.to_dict(),
                    "warnings": warnings,
                    **st.sections_json(result),
                }
            )
        else:
            out = Console(highlight=False)
            out.print(st.final_states_table(result))
            out.print(st.timeline_table(result))
            out.print(st.ledger_summary_table(result))
            rt = st.resets_table(result)
            if rt is not None:
                out.print(rt)
            for w in warnings:
                out.print(clean(f"warning: {w}"), markup=False)
            if job.report.rejected:
                out.print(f"{job.report.rejected} input lines rejected (trackside analyze lists them)", markup=False)
        return exit_codes.FINDINGS if strict and (job.report.rejected or disturbed) else exit_codes.OK

    raise typer.Exit(guard(body))
