"""trackside frames."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.common import (
    Console,
    check_inputs,
    guard,
    load_layout,
    one_json_form,
    print_document,
    refuse_unread,
    refuse_wrong_kind,
)
from console.cli.options import JsonOpt, RecordsJsonlOpt, StrictOpt


def _is_can_log(path: Path) -> bool:
    """A CAN log by its content (candump, ASC, TRC lines, a BLF container: parsers.kinds), whatever its name; by
    its name (.log, .asc, .blf, .trc, maybe .gz) only when the content tells nothing (an empty file)."""
    from parsers.frames.can_format import can_log_format
    from parsers.kinds import classify_file

    kind = classify_file(path).kind
    if kind == "empty":
        return can_log_format(path) in ("asc", "blf", "trc")
    return kind == "can"


# Columns of a frame row that mean something only for a sensor's own (count) frame.
_SENSOR_FIELDS = ("sensor", "status", "byte2", "check", "sys", "ses1", "ses2", "ses3", "der", "err", "t_since_s")
_COUNT_ONLY_FIELDS = (*_SENSOR_FIELDS, "total", "seq")


def _frame_rows(all_frames: Any) -> list[dict[str, Any]]:
    """JSON rows: every frame with its kind; fields of a sensor frame are null on other kinds."""
    import pandas as pd

    from console.analysis.timefmt import iso
    from parsers.frames.can_report import CAN_COLUMNS

    if all_frames.empty:
        return []
    keep = [c for c in CAN_COLUMNS if c not in ("time", "kind") and c in all_frames.columns]
    table = all_frames[keep].astype(object).where(all_frames[keep].notna(), None)
    # A text frame is always a sensor's own frame; concatenated with CAN tables its kind is missing.
    kind = all_frames["kind"] if "kind" in all_frames else pd.Series("count", index=all_frames.index)
    kinds = kind.astype(object).where(kind.notna(), "count").tolist()
    times = all_frames["time"].astype("int64").tolist()
    rows = []
    for t_ns, frame_kind, rec in zip(times, kinds, table.to_dict("records"), strict=True):
        row: dict[str, Any] = {"time": iso(t_ns), "kind": frame_kind}
        for k, v in rec.items():
            row[str(k)] = v.item() if hasattr(v, "item") else v
        if frame_kind != "count":
            row.update(dict.fromkeys(_COUNT_ONLY_FIELDS))
        rows.append(row)
    return rows


def frames(
    files: Annotated[
        list[Path],
        typer.Argument(
            metavar="FILE...",
            help="Sensor frame files (text) or CAN logs (candump, Vector ASC/BLF, PEAK TRC; told by content).",
        ),
    ],
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout", metavar="LAYOUT", help="Layout: which travel is up for each sensor (3-element heads)."
        ),
    ] = None,
    comm_timeout: Annotated[
        float,
        typer.Option(
            "--comm-timeout", metavar="S", help="Seconds without frames from a sensor that mean contact lost.", min=0.1
        ),
    ] = 10.0,
    json_out: JsonOpt = False,
    jsonl: RecordsJsonlOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Intelligent-sensor frames and CAN count frames: decoded, and as axle events."""

    def body() -> int:
        one_json_form(json_out, jsonl)
        import pandas as pd

        from console.analysis.frame_events import events_once, frames_once
        from console.analysis.timefmt import iso
        from console.plural import count
        from console.safe_text import clean
        from console.sinks.tables.diag_tables import parse_report_table, rejections_table
        from console.sinks.tables.frame_tables import (
            can_traffic_table,
            events_table,
            other_frames_table,
            sensor_summary_table,
        )
        from parsers.frames.can import parse_can
        from parsers.frames.sensor import parse_frames

        check_inputs(files)
        refuse_wrong_kind(files, "frames")
        lay = load_layout(layout) if layout else None
        can_files = [p for p in files if _is_can_log(p)]
        text_files = [p for p in files if p not in can_files]
        tables, reports = [], []
        can_report, can_frames = None, pd.DataFrame()
        if text_files:
            tf, tr = parse_frames(text_files)
            tables.append(tf)
            reports.append(tr)
        if can_files:
            can_frames, can_report = parse_can(can_files)
            tables.append(can_frames)
            reports.append(can_report)
        refuse_unread(reports, "frames")
        up: dict[str, bool] | bool = True
        if lay is not None:
            up = {h.id: h.up_is_first_channel_first for h in lay.heads}
            sensors = sorted({str(s) for t in tables if "sensor" in t for s in t["sensor"].dropna().unique()})
            strangers = [s for s in sensors if s not in up]
            if strangers and not (json_out or jsonl):
                Console(stderr=True, highlight=False).print(
                    f"frames: {', '.join(clean(s) for s in strangers)}: not heads of {clean(lay.source)}; "
                    "their axles' direction is unknown",
                    markup=False,
                )
        # Each file is its own recording; the same frames in two files (two formats of one capture) count once.
        events, repeated = events_once(tables, up, comm_timeout)
        all_frames = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
        rejected = sum(r.rejected for r in reports)
        if json_out or jsonl:
            print_document(
                {
                    "schema": "trackside.frames/2",
                    "files": [str(p) for p in files],
                    "frames": _frame_rows(all_frames),
                    "events": [
                        {
                            "time": iso(e.time_ns),
                            "kind": str(e.kind),
                            "sensor": e.head,
                            "direction": e.direction,
                            "channel": e.channel,
                            "source": e.source,
                            "detail": e.detail,
                        }
                        for e in events
                    ],
                    "parse_reports": [r.to_dict() for r in reports],
                    "events_repeated": {f: n for f, n in repeated.items() if n},
                },
                {"frames": "frame", "events": "event", "parse_reports": "parse_report"} if jsonl else None,
            )
        else:
            out = Console(highlight=False)
            out.print(sensor_summary_table(frames_once(tables), events))
            for name, n in repeated.items():
                if n:
                    out.print(
                        f"{clean(name)}: {count(n, 'event')} repeated from another file's frames, counted once",
                        markup=False,
                    )
            out.print(events_table(events))
            if can_report is not None:
                out.print(can_traffic_table(can_report))
                other = other_frames_table(can_frames)
                if other is not None:
                    out.print(other)
            for r in reports:
                if r is not can_report:
                    out.print(parse_report_table(r))
                rej = rejections_table(r)
                if rej is not None:
                    out.print(rej)
        return exit_codes.FINDINGS if strict and rejected else exit_codes.OK

    raise typer.Exit(guard(body))
