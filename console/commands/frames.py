"""trackside frames."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from console import exit_codes
from console.commands.common import (
    Console,
    JsonOpt,
    StrictOpt,
    check_inputs,
    guard,
    load_layout,
    print_json,
)


def _is_can_log(path: Path) -> bool:
    """CAN logs by suffix (.asc, .blf) or, for .log, by content (candump lines start with '(')."""
    suffixes = [x.lower() for x in path.suffixes if x.lower() != ".gz"]
    suffix = suffixes[-1] if suffixes else ""
    if suffix in (".asc", ".blf"):
        return True
    if suffix == ".log":
        from parsers.sources import open_input  # one reader: gzip, streams, UTF-16

        stream, raw, _ = open_input(path)
        try:
            head = stream.read(4096)
        finally:
            stream.close()
            raw.close()
        if head.startswith(b"LOGG"):
            return True
        for line in head.splitlines():
            line = line.strip()
            if line and not line.startswith(b"#"):
                return line.startswith(b"(")
    return False


def frames(
    files: Annotated[
        list[Path], typer.Argument(help="Sensor frame files (text) or CAN logs (candump .log, .asc, .blf).")
    ],
    layout: Annotated[
        str | None, typer.Option("--layout", help="Layout: which travel is up for each sensor (3-element heads).")
    ] = None,
    comm_timeout: Annotated[
        float,
        typer.Option("--comm-timeout", help="Seconds without frames from a sensor that mean contact lost.", min=0.1),
    ] = 10.0,
    json_out: JsonOpt = False,
    strict: StrictOpt = False,
) -> None:
    """Intelligent-sensor frames and CAN count frames: decoded, and as axle events."""

    def body() -> int:
        import pandas as pd

        from console.analysis.frame_events import frames_to_events
        from console.analysis.timefmt import iso
        from console.render.diag_tables import parse_report_table, rejections_table
        from console.render.frame_tables import events_table, sensor_summary_table
        from parsers.frames import CAN_COLUMNS, parse_can, parse_frames

        check_inputs(files)
        lay = load_layout(layout) if layout else None
        can_files = [p for p in files if _is_can_log(p)]
        text_files = [p for p in files if p not in can_files]
        tables, reports = [], []
        if text_files:
            tf, tr = parse_frames(text_files)
            tables.append(tf)
            reports.append(tr)
        if can_files:
            cf, cr = parse_can(can_files)
            tables.append(cf)
            reports.append(cr)
        up: dict[str, bool] | bool = True
        if lay is not None:
            up = {h.id: h.up_is_first_channel_first for h in lay.heads}
        events = []
        for table in tables:
            # Each file is its own recording: sequence and count checks run within it.
            for _, part in table.groupby("file", observed=True, sort=False):
                events += frames_to_events(part, up_is_s1_to_s3=up, comm_timeout_s=comm_timeout)
        events.sort(key=lambda e: e.time_ns)
        all_frames = pd.concat(tables, ignore_index=True) if tables else pd.DataFrame()
        rejected = sum(r.rejected for r in reports)
        if json_out:
            rows = []
            if not all_frames.empty:
                keep = [c for c in CAN_COLUMNS if c != "time" and c in all_frames.columns]
                frame_rows = all_frames[keep].astype(object).where(all_frames[keep].notna(), None).to_dict("records")
                for t_ns, rec in zip(all_frames["time"].astype("int64").tolist(), frame_rows, strict=True):
                    rows.append(
                        {"time": iso(t_ns), **{str(k): (v.item() if hasattr(v, "item") else v) for k, v in rec.items()}}
                    )
            print_json(
                {
                    "schema": "trackside.frames/1",
                    "files": [str(p) for p in files],
                    "frames": rows,
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
                }
            )
        else:
            out = Console(highlight=False)
            out.print(sensor_summary_table(all_frames, events))
            out.print(events_table(events))
            for r in reports:
                out.print(parse_report_table(r))
                rej = rejections_table(r)
                if rej is not None:
                    out.print(rej)
        return exit_codes.FINDINGS if strict and rejected else exit_codes.OK

    raise typer.Exit(guard(body))
