"""trackside station."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.commands.follow import MetricsOpt
from console.cli.common import check_inputs, fail, guard, load_layout


def station(
    layout: Annotated[
        str, typer.Option("--layout", metavar="LAYOUT", help="Layout file, or osong / example.")
    ] = "example",
    seed: Annotated[int, typer.Option("--seed", metavar="N", help="Simulation seed.")] = 1,
    speed: Annotated[
        float,
        typer.Option(
            "--speed",
            metavar="X",
            # The view steps through console.tui.model.SPEEDS (its + and - keys): X starts at the nearest.
            help="Playback speed × real time: 1, 2, 5, 10, 20, 50, 100, 200, 500 or 1000 (another X: the nearest).",
            min=1,
            max=1000,
        ),
    ] = 5,
    replay: Annotated[
        bool,
        typer.Option("--replay", help="Replay FILES (diagnostic records, GNSS telemetry) instead of simulating."),
    ] = False,
    # Text, not paths: after --live they may be URIs, whose "//" a Path would fold.
    args: Annotated[
        list[str] | None,
        typer.Argument(help="Logs to replay (with --replay), or more live sources (after --live).", metavar="FILES"),
    ] = None,
    live: Annotated[
        list[str] | None,
        typer.Option(
            "--live",
            metavar="SOURCE",
            help="Follow live sources (file:PATH, gpsd://…, mqtt[s]://…/TOPIC, can:…): --live A --live B, --live A B.",
        ),
    ] = None,
    archive: Annotated[
        Path | None,
        typer.Option(
            "--archive", metavar="DIR", help="With --replay: replay history from this archive (see trackside ingest)."
        ),
    ] = None,
    start: Annotated[
        str | None, typer.Option("--from", metavar="TIME", help="With --replay --archive: from this time (ISO).")
    ] = None,
    end: Annotated[
        str | None, typer.Option("--to", metavar="TIME", help="With --replay --archive: up to this time (ISO).")
    ] = None,
    serve: Annotated[
        bool,
        typer.Option(
            "--serve",
            help="Serve the view to a browser (textual-serve): each tab starts its own view, behind textual-serve's"
            " splash for a few seconds; it ends when its tab closes or the server stops.",
        ),
    ] = False,
    host: Annotated[
        str, typer.Option("--host", metavar="HOST", help="With --serve: address to listen on.")
    ] = "127.0.0.1",
    port: Annotated[
        int, typer.Option("--port", metavar="PORT", help="With --serve: port to listen on.", min=1, max=65535)
    ] = 8000,
    metrics: MetricsOpt = None,
) -> None:
    """The live station view: sections, trains, crossings and events, simulated, replayed or live."""

    files = [Path(a) for a in args or []]

    def body() -> int:
        if metrics is not None and (serve or not live):
            raise fail("--metrics goes with --live (with --serve each browser runs its own view: use follow --metrics)")
        if not serve:
            from console.tui.serve_guard import guard_served_app

            guard_served_app()  # an app started by station --serve: it goes with its tab and its server
        if serve or live:
            from console.cli.commands.station_live import live_uris, run_live_station

            uris = live_uris(live or [], args or [], replay)
            if serve and not uris:
                # What every browser tab will run: refused here in one line, not in each tab once it is served.
                view_source(load_layout(layout), files, replay, archive, start, end, seed)
            elif archive is not None or start or end:
                raise fail("--archive/--from/--to replay history, not live sources: give --replay or --live")
            return run_live_station(
                layout,
                uris,
                serve,
                host,
                port,
                seed,
                speed,
                replay,
                files,
                metrics,
                archive=archive,
                start=start,
                end=end,
            )
        from console.tui.app import StationApp
        from console.tui.model import SPEEDS, StationModel

        source = view_source(load_layout(layout), files, replay, archive, start, end, seed)
        if not (sys.stdin.isatty() and sys.stdout.isatty()) and "TEXTUAL_DRIVER" not in os.environ:
            # Textual would draw into a pipe and wait for keys that never come.
            raise fail("the station view needs a terminal: run it without pipes or redirection")
        model = StationModel(source)
        model.speed_index = min(range(len(SPEEDS)), key=lambda i: abs(SPEEDS[i] - speed))
        StationApp(model).run()
        return exit_codes.OK

    raise typer.Exit(guard(body))


def view_source(
    lay: Any, files: list[Path], replay: bool, archive: Path | None, start: str | None, end: str | None, seed: int
) -> Any:
    """The station view's source: the replay of FILES or of the archive's history, else the simulation; one line,
    exit 2, on any usage or input error (before a terminal view or a server starts)."""
    from console.tui.replay_source import ReplaySource
    from console.tui.sim_source import SimSource

    from_archive = archive is not None or bool(start) or bool(end)
    if from_archive and not replay:
        raise fail("--archive/--from/--to replay history: add --replay (trackside station --replay --archive DIR)")
    if from_archive and files:
        raise fail("replay either FILES or --archive, not both")
    if replay and not files and not from_archive:
        raise fail("--replay needs the logs to replay: trackside station --replay FILES... (or --archive DIR)")
    if files and not replay:
        raise fail("FILES are replayed: add --replay (trackside station --replay FILES...)")
    if from_archive:
        return archive_replay_source(archive, lay, start, end)
    if files:
        if any(os.fsdecode(f) == "-" for f in files):
            # The view reads its keys from standard input: the log must come another way.
            raise fail("--replay -: the station view reads keys from standard input; give a file or <(zcat …)")
        check_inputs(files)
        try:
            return ReplaySource(files, lay)
        except ValueError as exc:
            raise fail(str(exc)) from None
    try:
        return SimSource(lay, seed=seed)
    except ValueError as exc:
        raise fail(str(exc)) from None


def archive_replay_source(archive: Path | None, lay: Any, start: str | None, end: str | None) -> Any:
    """The station view's replay source over the archive's history in [--from, --to): one line on any error."""
    from console.archive.history import replay_inputs
    from console.archive.reader import user_window
    from console.archive.store import ArchiveError, archive_dir
    from console.tui.replay_source import ReplaySource

    try:
        window = user_window(start, end)
    except ValueError as exc:
        raise fail(f"--from/--to: {exc}") from None
    try:
        records, fixes = replay_inputs(archive_dir(archive), window)
        return ReplaySource.from_parts(lay, records, fixes)
    except ArchiveError as exc:
        raise fail(str(exc)) from None
    except ValueError as exc:  # nothing to replay in that window
        raise fail(f"archive: {exc}") from None
