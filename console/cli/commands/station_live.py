"""`trackside station --live SOURCE` and `--serve`: the station view on live feeds, and in a browser."""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

from console import exit_codes
from console.cli.common import fail, load_layout

_CLI = "from console.cli.app import app; app()"
WEB_DRIVER_ENV = "TEXTUAL_DRIVER"  # set by textual-serve for the app it runs


def served_command(
    layout: str,
    live: list[str],
    seed: int,
    speed: float,
    replay: bool,
    files: list[Path],
    archive: Path | None = None,
    start: str | None = None,
    end: str | None = None,
) -> list[str]:
    """The command textual-serve runs for each browser: this station view, without --serve."""
    cmd = [sys.executable, "-c", _CLI, "station", "--layout", layout]
    for s in live:
        cmd += ["--live", s]
    if not live:
        cmd += ["--seed", str(seed), "--speed", str(speed)]
        if replay:
            cmd += ["--replay", *(str(f) for f in files)]
            for option, value in (("--archive", archive), ("--from", start), ("--to", end)):
                if value is not None:
                    cmd += [option, str(value)]
    return cmd


def live_uris(live: list[str], args: list[str], replay: bool) -> list[str]:
    """The sources of ``--live A --live B`` and of ``--live A B`` (B arrives as a positional argument)."""
    if live and replay:
        raise fail("--live follows sources as they grow; --replay plays files back: give one or the other")
    if args and not live and not replay:
        raise fail("FILES are replayed: add --replay (trackside station --replay FILES...), or follow them with --live")
    return [*live, *args] if live else []


def run_live_station(
    layout: str,
    live: list[str],
    serve: bool,
    host: str,
    port: int,
    seed: int,
    speed: float,
    replay: bool,
    files: list[Path],
    metrics: str | None = None,
    *,
    archive: Path | None = None,
    start: str | None = None,
    end: str | None = None,
) -> int:
    from console.inputs.base import SourceError
    from console.inputs.stream import STDIN
    from console.inputs.uri import open_sources, parse_uri

    lay = load_layout(layout)
    try:
        if any(u.scheme == "file" and u.path == STDIN for u in map(parse_uri, live)):
            # The view reads its keys there (and a served view's browsers each run one): as --replay - says.
            raise fail("--live -: the station view reads keys from standard input; give a FIFO (mkfifo) or a file")
        sources = open_sources(live)
    except SourceError as exc:
        raise fail(str(exc)) from None
    if serve:
        from console.tui.served import StationServer

        argv = served_command(layout, live, seed, speed, replay, files, archive, start, end)
        server = StationServer(argv, host=host, port=port, title="trackside station")
        server.serve()
        stopped = {signal.SIGINT: exit_codes.INTERRUPTED, signal.SIGTERM: exit_codes.TERMINATED}
        return stopped.get(server.stopped_by, exit_codes.OK)  # type: ignore[call-overload]
    if not (sys.stdin.isatty() and sys.stdout.isatty()) and WEB_DRIVER_ENV not in os.environ:
        raise fail("the station view needs a terminal: run it without pipes or redirection (or use --serve)")
    from console.cli.commands.follow import metrics_sink
    from console.tui.live_app import LiveStationApp
    from console.tui.live_source import LiveSource

    sink = metrics_sink(metrics, lay, sources)
    try:
        LiveStationApp(LiveSource(lay, sources, sink=sink)).run()
    finally:
        if sink is not None:
            sink.close()
    return exit_codes.OK
