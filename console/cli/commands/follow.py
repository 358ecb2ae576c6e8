"""trackside follow: live sources → passages, section changes, crossing warnings, health, as they happen."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.common import fail, guard, load_layout
from console.cli.options import IdleGapOpt, IncludeStatusOpt
from console.plural import count

MetricsOpt = Annotated[
    str | None,
    typer.Option(
        "--metrics",
        metavar="HOST:PORT",
        help="Serve Prometheus metrics on HOST:PORT (that address only), e.g. 127.0.0.1:9108 (docs/monitoring.md).",
        show_default=False,
    ),
]

SourcesArg = Annotated[
    list[str],
    typer.Argument(
        metavar="SOURCE...",
        help="Sources: file:PATH (or a path: a diagnostic, NMEA, gpsd JSON, GNSS device CSV/JSON lines, CAN or"
        " sensor frame log, told by its content), - (standard input: a pipe, read to its end; a FIFO path too),"
        " gpsd://HOST:PORT[/DEVICE], mqtt[s]://HOST:PORT/TOPIC, can:IFACE[:CHANNEL].",
        show_default=False,
    ),
]


def _line(ev: dict[str, Any]) -> str:
    """One human line per event; log content escaped (it is data, never terminal codes)."""
    from console.safe_text import clean

    kind = ev.get("type")
    if kind == "passage":
        speed = ev.get("speed_kmh_whole_train")
        sp = f"{speed:.1f} km/h" if isinstance(speed, int | float) else "no speed"
        axles = "– axles" if ev.get("axles_unknown_reason") else count(ev["axles"], "axle")
        text = f"passage  {ev['counting_head']}  {ev['start']} → {ev['end']}  {axles}  {sp}"
    elif kind == "section":
        text = f"section  {ev['section']}  {ev['state']}  count {ev['count']}  {ev['time']}  {ev['reason']}"
    elif kind == "crossing":
        text = f"crossing {ev['crossing']}  {ev['kind']}  train {ev['train']}  {ev['time']}  {ev['reason']}"
    elif kind == "integrity":
        why = "; ".join(ev["evidence"])
        text = f"integrity train {ev['train']}  {ev['state']}  {ev['time']}  {why}"
    elif kind == "health":
        text = f"health   {ev['severity']}  {ev['rule']}  {ev['counting_head']}  {ev['message']}"
    elif kind == "source":
        if ev.get("kind") == "rejected":
            text = f"rejected {ev['file']}:{ev['line']}: {ev['reason']}: {ev.get('text', '')}"
        else:
            text = f"source   {ev.get('source', '')}  {ev.get('kind')}  {ev.get('detail', '')}"
    else:
        text = json.dumps(ev)
    return clean(text)


def _tell(message: str) -> None:
    sys.stderr.write(f"follow: {message}\n")
    sys.stderr.flush()


def _summary_lines(summary: dict[str, Any]) -> list[str]:
    from console.safe_text import clean

    out = [
        f"followed: {count(summary['passages'], 'passage')}, {count(summary['section_changes'], 'section change')}, "
        f"{count(summary['crossing_events'], 'crossing event')}, "
        f"{count(summary.get('integrity_events', 0), 'integrity change')}, "
        f"{count(summary['health_findings'], 'health finding')}"
    ]
    if summary.get("status_only_passages"):
        n = summary["status_only_passages"]
        # Not "of them": the passages counted above exclude these.
        out[0] += f"; {count(n, 'status-only record burst')} (no wheel onset) not listed (--include-status lists them)"
    if summary.get("gnss_fixes_bad_clock"):
        n = summary["gnss_fixes_bad_clock"]
        out.append(f"  {count(n, 'GNSS fix', 'GNSS fixes')} set aside: stamped over a day from the console's clock")
    for f in summary["files"]:
        unread = f" + {f['unrecognised']} unrecognised (not read)" if "unrecognised" in f else ""
        out.append(
            clean(
                f"  {f['file']}: {count(f['lines_read'], 'line')} = {count(f['records'], 'record')}"
                f" + {f['blank']} blank"
                f" + {f['rejected']} rejected{unread}"
            )
        )
    why = "(stopped at a second interrupt)"
    for f in summary.get("not_analysed", []):
        out.append(clean(f"  {f['file']}: not analysed from line {f['from_line']} on {why}"))
    if summary.get("items_not_analysed"):
        out.append(f"  {count(summary['items_not_analysed'], 'item')} read but not analysed {why}")
    for s in summary["sources"]:
        out.append(
            clean(
                f"  {s['uri']}: {count(s['messages'], 'message')}, {s['lost']} lost, {s['malformed']} malformed,"
                f" {count(s['duplicates'], 'duplicate')} ({s['detail']})"
            )
        )
    for sid, st in summary["sections"].items():
        out.append(clean(f"  section {sid}: {st['state']} (count {st['count']})"))
    if summary.get("archive_repeated_lines"):
        out.append(
            f"  --archive: {count(summary['archive_repeated_lines'], 'line')} an earlier run had archived, read again:"
            " not stored twice"
        )
    for error in summary.get("archive_spool_errors", []):
        out.append(clean(f"  --archive: {error}"))
    if summary.get("archive_lines_not_spooled"):
        out.append(f"  --archive: {count(summary['archive_lines_not_spooled'], 'line')} not archived")
    for error in summary.get("archive_errors", []):
        out.append(clean(f"  --archive: not ingested: {error} (kept in the spool for the next ingest)"))
    return out


def follow(
    sources: SourcesArg,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="Layout (file or osong, example): adds section states and crossing warnings.",
        ),
    ] = None,
    jsonl: Annotated[bool, typer.Option("--jsonl", help="One JSON object per line, with a `type` field.")] = False,
    from_start: Annotated[
        bool, typer.Option("--from-start", help="Read followed files from their start, not their end.")
    ] = False,
    poll: Annotated[bool, typer.Option("--poll", help="Poll files instead of inotify (network filesystems).")] = False,
    idle_gap: IdleGapOpt = 10.0,
    archive: Annotated[
        Path | None,
        typer.Option(
            "--archive", metavar="DIR", help="Also ingest what is followed into this archive (spooled in DIR.live)."
        ),
    ] = None,
    duration: Annotated[
        str | None,
        typer.Option(
            "--duration",
            metavar="DURATION",
            help="Stop after this long: 90s, 30m, 2h or seconds, as simulate takes it (default: until Ctrl-C).",
        ),
    ] = None,
    idle_exit: Annotated[
        float | None,
        typer.Option(
            "--idle-exit",
            metavar="S",
            help=(
                "Stop when nothing has arrived for this many seconds (after the first record); a followed file "
                "still absent after this long, nothing read: an error, exit 2."
            ),
            min=0.1,
        ),
    ] = None,
    strict: Annotated[
        bool, typer.Option("--strict", help="Exit 1 if any line of a followed file was rejected.")
    ] = False,
    include_status: IncludeStatusOpt = False,
    metrics: MetricsOpt = None,
) -> None:
    """Follow live sources and report what happens as it happens; Ctrl-C ends with a summary (exit 130), and so
    does the end of every stream given (`… | trackside follow -`; exit 0)."""

    def body() -> int:
        from console.analysis.passages.speed_settings import SpeedSettings
        from console.analysis.timefmt import parse_duration

        try:
            duration_s = None if duration is None else parse_duration(duration)
        except ValueError as exc:
            raise fail(f"--duration: {exc}") from None
        if duration_s is not None and duration_s > 1e9:
            raise fail(f"--duration: {duration!r} is more than 31 years")
        from console.archive.store import ArchiveError
        from console.inputs.base import SourceError
        from console.inputs.uri import open_sources
        from console.live.archive import LiveArchiver
        from console.live.engine import LiveEngine, run_sources

        lay = load_layout(layout) if layout else None
        try:
            srcs = open_sources(sources, from_start=from_start, force_polling=poll)
        except SourceError as exc:
            raise fail(str(exc)) from None
        out = sys.stdout
        sink = metrics_sink(metrics, lay, srcs)

        def emit(ev: dict[str, Any]) -> None:
            if sink is not None:
                sink(ev)
            if jsonl:
                out.write(json.dumps(ev, ensure_ascii=False, default=str) + "\n")
            elif ev.get("type") == "source" and ev.get("kind") == "disconnected":
                # A source that cannot open or lost its feed is a problem, not an event: told on stderr.
                sys.stderr.write(_line(ev) + "\n")
                sys.stderr.flush()
                return
            else:
                out.write(_line(ev) + "\n")
            out.flush()  # a reader downstream sees each event at once

        settings = SpeedSettings.of_layout(lay, idle_gap_s=idle_gap)
        try:
            archiver = LiveArchiver(archive, layout) if archive is not None else None
        except ArchiveError as exc:
            raise fail(f"--archive: {exc}") from None
        engine = LiveEngine(lay, emit, settings, archiver=archiver, include_status=include_status)
        started = time.monotonic()
        last = [started, engine.items]
        data_items = [0]
        absent: list[str] = []

        def idle() -> bool:
            # Counted from the first record or message: a follower started before its
            # writer waits for it (notes such as "connected" do not count).
            if idle_exit is None:
                return False
            # Lines a source read count too: a big followed file may give few items while it is read.
            n = engine.items - sum(engine.notes.values()) + sum(s.message_count for s in srcs)
            if n != last[1]:
                last[:] = [time.monotonic(), n]
                data_items[0] = n
                return False
            if data_items[0] == 0 and time.monotonic() - started >= idle_exit:
                # Nothing yet, and a file to wait for is not there (never was, or deleted), or a source never
                # came up (gpsd, a broker): waiting for its first record would be forever, which --idle-exit
                # asked not to do.
                absent[:] = missing_files(srcs)
                return bool(absent)
            return data_items[0] > 0 and time.monotonic() - last[0] >= idle_exit

        # Ctrl-C and SIGTERM (a service stopping) end it cleanly: the summary, then 130 or 143, as for
        # every command, so a script can tell an interrupted follow from one that ran its --duration.
        import signal

        try:
            stopped_by = run_sources(engine, srcs, until=idle, duration_s=duration_s, tell=_tell)
        finally:
            if sink is not None:
                sink.close()
        if absent:
            raise fail(f"{absent[0]} (nothing arrived within --idle-exit {idle_exit:g} s)")
        summary = engine.summary(srcs)
        if jsonl:
            emit(summary)
        else:
            sys.stderr.write("\n".join(_summary_lines(summary)) + "\n")
        rejected = sum(f["rejected"] for f in summary["files"])  # diagnostic, GNSS, CAN and frame logs
        if stopped_by == signal.SIGTERM:
            return exit_codes.TERMINATED
        if stopped_by == signal.SIGINT:
            return exit_codes.INTERRUPTED
        return exit_codes.FINDINGS if strict and rejected else exit_codes.OK

    raise typer.Exit(guard(body))


def missing_files(sources: list[Any]) -> list[str]:
    """The followed files (``file:PATH``) not on disk now, and the other sources never connected, each with
    why."""
    from console.inputs.follow import FileSource

    out = []
    for s in sources:
        if isinstance(s, FileSource):
            if not s.path.exists():
                out.append(f"{s.path}: no such file")
        elif not s.ever_connected:
            out.append(f"{s.uri}: never connected: {s.status().detail.removesuffix('; retrying')}")
    return out


def metrics_sink(address: str | None, layout: Any, sources: list[Any]) -> Any:
    """The Prometheus sink serving on ``address`` (None: no metrics); the serving address on stderr."""
    if address is None:
        return None
    from console.sinks.metrics import MetricsError, MetricsSink

    sink = MetricsSink(layout, lambda: [s.status() for s in sources])
    try:
        host, port = sink.serve(address)
    except MetricsError as exc:
        raise fail(str(exc)) from None
    where = f"[{host}]" if ":" in host else host
    sys.stderr.write(f"metrics on http://{where}:{port}/metrics\n")
    sys.stderr.flush()
    return sink
