"""trackside station."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.commands.common import (
    check_inputs,
    fail,
    guard,
    load_layout,
)


def station(
    layout: Annotated[str, typer.Option("--layout", help="Layout file, or osong / example.")] = "example",
    seed: Annotated[int, typer.Option("--seed", help="Simulation seed.")] = 1,
    speed: Annotated[
        float, typer.Option("--speed", help="Playback speed, 1 to 1000 × real time.", min=1, max=1000)
    ] = 5,
    replay: Annotated[
        bool,
        typer.Option("--replay", help="Replay FILES (diagnostic records, GNSS telemetry) instead of simulating."),
    ] = False,
    files: Annotated[list[Path] | None, typer.Argument(help="Logs to replay (with --replay).")] = None,
) -> None:
    """The live station view: sections, trains, crossings and events, simulated or replayed."""

    def body() -> int:
        from console.tui.app import StationApp
        from console.tui.model import SPEEDS, StationModel
        from console.tui.sources import ReplaySource, SimSource

        lay = load_layout(layout)
        if replay and not files:
            raise fail("--replay needs the logs to replay: trackside station --replay FILES...")
        if files and not replay:
            raise fail("FILES are replayed: add --replay (trackside station --replay FILES...)")
        if files:
            check_inputs(files)
            try:
                source: Any = ReplaySource(files, lay)
            except ValueError as exc:
                raise fail(str(exc)) from None
        else:
            try:
                source = SimSource(lay, seed=seed)
            except ValueError as exc:
                raise fail(str(exc)) from None
        if not (sys.stdin.isatty() and sys.stdout.isatty()):
            # Textual would draw into a pipe and wait for keys that never come.
            raise fail("the station view needs a terminal: run it without pipes or redirection")
        model = StationModel(source)
        model.speed_index = min(range(len(SPEEDS)), key=lambda i: abs(SPEEDS[i] - speed))
        StationApp(model).run()
        return exit_codes.OK

    raise typer.Exit(guard(body))
