"""trackside crossing."""

from __future__ import annotations

from typing import Annotated

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
    refuse_unread,
    refuse_wrong_kind,
    rejected_note,
)
from console.cli.options import GnssFilesArg, JsonOpt, RecordsJsonlOpt
from console.safe_text import clean

# How a user of this command pairs devices into trains (the input warnings' advice).
PAIRING_HINT = "give --train TRAIN=HEAD,EOT for each train"

CROSSING_LINES = {"timelines": "timeline", "events": "event", "trains": "train", "integrity": "integrity"}


def crossing(
    files: GnssFilesArg,
    layout: Annotated[
        str, typer.Option("--layout", metavar="LAYOUT", help="Layout with [[crossings]] and a [[track]] polyline.")
    ],
    train: Annotated[
        list[str] | None,
        typer.Option(
            "--train",
            metavar="TRAIN=HEAD,EOT[,LENGTH_M]",
            help="TRAIN=HEAD_DEVICE,EOT_DEVICE[,LENGTH_M] (repeatable; default: by role or name).",
        ),
    ] = None,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 on a safety violation or a rejected input line.")
    ] = False,
) -> None:
    """Level-crossing warning timelines from head and end-of-train telemetry (Co Nhu Van, TCSJ 2026).

    Per warning: when it came on and went off, its lead against the crossing's warning time, and
    the spare split into physics (what the unit's bounds cost even knowing the motion, judged in
    hindsight from all the fixes) and doubt (no speed, stale units, jumps, sparse fixes).  A
    warning released before the train arrived (proven out of reach) is counted.
    """

    def body() -> int:
        one_json_form(json_out, jsonl)
        from console.analysis.crossing_batch import (
            input_warnings,
            parse_train_options,
        )
        from console.analysis.integrity.values import timelines
        from console.analysis.timefmt import iso
        from console.drivers.crossings import run_crossings
        from console.sinks.tables.crossing_tables import reasons_view, spare_view, timeline_table, violations_view
        from console.sinks.tables.integrity_tables import integrity_table
        from parsers.gnss_files import parse_gnss

        check_inputs(files)
        refuse_wrong_kind(files, "gnss")
        lay = load_layout(layout)
        if not lay.crossings:
            raise fail(f"{lay.source}: the layout has no [[crossings]]")
        if len(lay.track) < 2:
            raise fail(f"{lay.source}: the layout has no [[track]] polyline to place fixes on")
        consist = lay.consist()
        default_len = consist.length_m if consist else 100.0
        try:
            trains = parse_train_options(train or [], default_len)
        except ValueError as exc:
            raise fail(str(exc)) from None
        fixes, report, _states = parse_gnss(files)
        # A file of which every line was rejected is refused, as gnss does: not an empty table and exit 0.
        refuse_unread(report, "gnss")
        present = set(fixes["device"].astype(str).unique()) if len(fixes) else set()
        named = [d for t in trains for d in (*t.head, *t.eot)]
        absent = [d for d in dict.fromkeys(named) if d not in present]
        if named and len(absent) == len(set(named)):
            there = ", ".join(sorted(present)) or "none"
            raise fail(  # fail escapes the names
                f"--train: no fix from {', '.join(absent)} in the inputs "
                f"(their devices: {there}); name devices as the gnss command lists them"
            )
        run = run_crossings(fixes, lay, trains)
        violations = run.violations
        warnings = input_warnings(run, fixes, trains_named=bool(trains), pairing_hint=PAIRING_HINT)
        if absent:
            warnings.append(f"--train names {', '.join(absent)}: no fix from {'it' if len(absent) == 1 else 'them'}")
        if json_out or jsonl:
            print_document(
                {
                    "schema": "trackside.crossing/1",
                    "files": [str(p) for p in files],
                    "layout": lay.source,
                    "violations": violations,
                    "late_warnings": run.late_warnings,
                    "position_jumps": run.position_jumps,
                    # Rows with a violation first (late warnings lead their own lists), then the rest.
                    "timelines": [r.to_dict() for r in sorted(run.timelines, key=lambda r: not r.violations)],
                    "events": [
                        {
                            "time": iso(e.t_ns),
                            "crossing": e.crossing,
                            "train": e.train,
                            "kind": e.kind,
                            "reason": e.reason,
                        }
                        for e in run.events
                    ],
                    "trains": [
                        {"train": t.train, "head": list(t.head), "eot": list(t.eot), "length_m": t.length_m}
                        for t in run.trains
                    ],
                    "integrity": timelines(run.integrity),
                    "warnings": warnings,
                    "parse_report": report.to_dict(),
                },
                CROSSING_LINES if jsonl else None,
            )
        else:
            out = Console(highlight=False)
            v = violations_view(run.timelines)
            if v is not None:
                out.print(v)
            out.print(timeline_table(run.timelines))
            out.print(reasons_view(run.timelines, run.events))
            if (sv := spare_view(run.timelines)) is not None:
                out.print(sv)
            if run.integrity:
                out.print(integrity_table(timelines(run.integrity)))
            for w in warnings:
                out.print(f"warning: {clean(w)}", markup=False)  # names from the input: escaped
            if report.rejected:
                out.print(rejected_note(report.rejected, "trackside gnss lists them"), markup=False)
        return exit_codes.FINDINGS if strict and (violations or report.rejected) else exit_codes.OK

    raise typer.Exit(guard(body))
