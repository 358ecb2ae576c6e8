"""trackside simulate."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.commands.common import (
    Console,
    JsonOpt,
    fail,
    guard,
    load_layout,
    print_json,
)
from console.plural import count


def _parse_fault(text: str) -> Any:
    """``KIND:TARGET:START[:END[:CHANNEL]]`` (times like 90s, 30m) → a simulator Fault."""
    from console.analysis.timefmt import parse_duration
    from console.sim.station import FAULT_KINDS, Fault

    parts = text.split(":")
    if len(parts) < 3 or parts[0] not in FAULT_KINDS:
        raise fail(
            f"--fault {text!r}: expected KIND:TARGET:START[:END[:CHANNEL]] with KIND one of {', '.join(FAULT_KINDS)}"
        )
    try:
        start = parse_duration(parts[2])
        end = parse_duration(parts[3]) if len(parts) > 3 and parts[3] else float("inf")
        channel = int(parts[4]) if len(parts) > 4 else 2
    except ValueError as exc:
        raise fail(f"--fault {text!r}: {exc}") from None
    return Fault(parts[0], parts[1], start, end, channel)


def simulate(
    output: Annotated[
        Path,
        typer.Option(
            "-o", "--output", metavar="DIR", help="Directory to write the run into (created; never over an input)."
        ),
    ],
    layout: Annotated[
        str, typer.Option("--layout", metavar="LAYOUT", help="Layout file, or osong / example.")
    ] = "example",
    duration: Annotated[
        str, typer.Option("--duration", metavar="DURATION", help="Simulated time: 90s, 30m, 2h, 1h30m.")
    ] = "2h",
    seed: Annotated[
        int, typer.Option("--seed", metavar="N", help="Random seed: the same seed gives the same run.")
    ] = 1,
    trains_per_hour: Annotated[float, typer.Option("--trains-per-hour", metavar="N", min=0.1, max=60)] = 6.0,
    spreading_factor: Annotated[
        int,
        typer.Option(
            "--sf",
            metavar="7-12",
            help="LoRa spreading factor of the GNSS units (7-12): sets their report period.",
            min=7,
            max=12,
        ),
    ] = 7,
    fault: Annotated[
        list[str] | None,
        typer.Option(
            "--fault",
            metavar="KIND:TARGET:START[:END[:CH]]",
            help="KIND:TARGET:START[:END[:CHANNEL]], e.g. dead_channel:WS3:20m (repeatable).",
        ),
    ] = None,
    json_out: JsonOpt = False,
    live: Annotated[
        bool,
        typer.Option(
            "--live", metavar="SOURCE", help="Write the logs as growing files in (scaled) real time, for `follow`."
        ),
    ] = False,
    live_speed: Annotated[
        float,
        typer.Option(
            "--speed", metavar="X", help="With --live/--mqtt: simulated seconds per real second.", min=0.1, max=1000
        ),
    ] = 1.0,
    mqtt: Annotated[
        str | None,
        typer.Option(
            "--mqtt", metavar="URL", help="Publish the GNSS units' uplinks (ChirpStack v4 JSON) to mqtt://HOST:PORT."
        ),
    ] = None,
) -> None:
    """Simulate a line: trains, counting heads, GNSS units and faults, written as real logs with a truth."""

    def body() -> int:
        from console.analysis.timefmt import parse_duration
        from console.output_path import OutputError, check_output_directory, staged_directory
        from console.progress import byte_progress
        from console.safe_text import show_path
        from console.sim.radio import LoRaLink
        from console.sim.station import SimConfig, StationSim
        from console.sim.writers import write_run

        try:
            seconds = parse_duration(duration)
        except ValueError as exc:
            raise fail(f"--duration: {exc}") from None
        lay = load_layout(layout)
        faults = tuple(_parse_fault(f) for f in (fault or []))
        for f in faults:
            known = {h.id for h in lay.heads} if f.kind not in ("eot_loss", "head_loss") else None
            if known is not None and f.target not in known:
                raise fail(f"--fault {f.kind}: {f.target} is not a counting head of {lay.source}")
        layout_file = Path(layout)
        inputs = [layout_file] if layout_file.is_file() else []
        try:
            check_output_directory(output, what="run")
        except OutputError as exc:
            raise fail(str(exc)) from None
        config = SimConfig(
            seed=seed, trains_per_hour=trains_per_hour, radio=LoRaLink(spreading_factor=spreading_factor), faults=faults
        )
        if live or mqtt:  # a live run happens now: the units' clocks and the console's agree
            import dataclasses
            import time

            config = dataclasses.replace(config, start_ns=time.time_ns() // 10**9 * 10**9)
        try:
            sim = StationSim(lay, config)
        except ValueError as exc:
            raise fail(str(exc)) from None
        if live or mqtt:
            from console.commands.simulate_live import run_live_command

            return run_live_command(sim, seconds, live_speed, output if live else None, mqtt, json_out)
        # The bar counts simulated milliseconds (it only shows on a terminal, for long runs).
        with byte_progress(int(seconds * 1000) if seconds >= 600 else 0, "simulating") as advance:
            last = [0.0]

            def tick(t_s: float) -> None:
                if advance is not None:
                    advance(int((t_s - last[0]) * 1000))
                    last[0] = t_s

            sim.run(seconds, on_step=tick)
        try:
            # Written into a hidden stage first: an interrupted run leaves no half-written log behind.
            with staged_directory(output, inputs, what="run") as stage:
                counts = write_run(sim, stage)
        except OutputError as exc:
            raise fail(str(exc)) from None
        sim_sections = {
            s: {"console": str(sim.engine.state(s)), "true_count": sim.true_count(s)} for s in sim.engine.sections
        }
        summary = {
            "schema": "trackside.simulate/1",
            "output": show_path(output),
            "layout": lay.source,
            "seed": seed,
            "duration_s": seconds,
            "trains": len(sim.trains),
            "axles": len(sim.truth_axles),
            "report_period_s": round(sim.period_s, 2),
            "written": counts,
            "sections": {
                s: {"console": str(sim.engine.state(s)), "true_count": sim.true_count(s)} for s in sim.engine.sections
            },
        }
        if json_out:
            print_json(summary)
        else:
            out = Console(highlight=False)
            out.print(
                f"simulated {duration} on {lay.name} (seed {seed}): {count(len(sim.trains), 'train')}, "
                f"{count(len(sim.truth_axles), 'axle passage')};"
                f" GNSS every {sim.period_s:.1f} s (LoRa SF{spreading_factor})",
                markup=False,
            )
            for name, n in counts.items():
                out.print(f"  {show_path(output / name)}: {n}", markup=False)
            for sid, st in sim_sections.items():
                out.print(
                    f"  section {sid}: console {st['console']}, axles really inside {st['true_count']}", markup=False
                )
        return exit_codes.OK

    raise typer.Exit(guard(body))
