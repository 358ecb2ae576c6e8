"""trackside simulate."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from console import exit_codes
from console.cli.common import Console, fail, guard, load_layout, print_json
from console.cli.options import JsonOpt
from console.plural import count, plural

# The stepped run keeps its whole truth in memory until it writes: longer runs are --days.
MAX_DURATION_S = 2 * 86_400.0
# The faults a --health-only run honours: the slow wear of the heads' registers (console.sim.slow_faults).
HEALTH_REGISTER_FAULTS = ("analog_drift", "disturbance_growth")


def _parse_fault(text: str) -> Any:
    """``KIND:TARGET:START[:END[:CHANNEL[:RATE]]]`` (times like 90s, 30m, 3d) → a simulator Fault."""
    from console.analysis.timefmt import parse_duration
    from console.sim.faults import FAULT_KINDS, SLOW_FAULT_KINDS, Fault
    from console.sim.slow_faults import check_rate

    parts = text.split(":")
    if len(parts) < 3 or len(parts) > 6 or parts[0] not in FAULT_KINDS:
        raise fail(
            f"--fault {text!r}: expected KIND:TARGET:START[:END[:CHANNEL[:RATE]]] with KIND one of "
            f"{', '.join(FAULT_KINDS)}"
        )
    try:
        start = parse_duration(parts[2])
        end = parse_duration(parts[3]) if len(parts) > 3 and parts[3] else float("inf")
        if end <= start:
            raise ValueError("END must come after START (a fault repaired before it begins never shows)")
        channel_text = parts[4] if len(parts) > 4 and parts[4] else "2"
        channel = int(channel_text) if channel_text.strip().lstrip("+").isdecimal() else 0
        if channel not in (1, 2):  # said here: int() would say "invalid literal for int() with base 10"
            raise ValueError(f"channel must be 1 or 2, found {channel_text!r}")
        rate = None
        if len(parts) > 5:
            if parts[0] not in SLOW_FAULT_KINDS:
                raise ValueError(f"a RATE is for the slow faults ({', '.join(SLOW_FAULT_KINDS)})")
            try:
                rate = float(parts[5])
            except ValueError:
                raise ValueError(f"RATE: expected a number, found {parts[5]!r}") from None
            check_rate(parts[0], rate)
    except ValueError as exc:
        raise fail(f"--fault {text!r}: {exc}") from None
    return Fault(parts[0], parts[1], start, end, channel, rate=rate)


def _is_trainset(name: str, fleet: int) -> bool:
    """``name`` is one of the fleet's trainsets T1..T{fleet} (read off the name: --fleet may be huge)."""
    number = name[1:]
    return name[:1] == "T" and number.isascii() and number.isdigit() and number[0] != "0" and int(number) <= fleet


def _check_targets(faults: tuple[Any, ...], lay: Any, fleet: int, health_only: bool) -> None:
    from console.sim.faults import TRAIN_FAULTS

    heads = {h.id for h in lay.heads}
    for f in faults:
        if f.kind == "gnss_decay":
            train, _, role = f.target.rpartition("-")
            if role not in ("head", "eot") or not train:
                raise fail(f"--fault gnss_decay: {f.target} is not a GNSS unit (TRAIN-head or TRAIN-eot, e.g. T1-eot)")
            if fleet and not _is_trainset(train, fleet):
                raise fail(f"--fault gnss_decay: {f.target}: the fleet's trainsets are T1 to T{fleet}")
            if health_only:
                raise fail("--fault gnss_decay: --health-only runs no trains, so no GNSS unit reports")
        elif f.kind in TRAIN_FAULTS:
            if fleet and not _is_trainset(f.target, fleet):
                raise fail(f"--fault {f.kind}: {f.target}: the fleet's trainsets are T1 to T{fleet}")
        elif f.target not in heads:
            raise fail(f"--fault {f.kind}: {f.target} is not a counting head of {lay.source}")
        if health_only and f.kind not in HEALTH_REGISTER_FAULTS:
            # Nothing else reaches the registers: the fault would be listed in the truth yet change nothing.
            raise fail(
                f"--fault {f.kind}: --health-only writes only the heads' health registers, which only "
                f"{' and '.join(HEALTH_REGISTER_FAULTS)} change"
            )


def simulate(
    output: Annotated[
        Path,
        typer.Option(
            "-o",
            "--output",
            metavar="DIR",
            help="Directory to write the run into: new or empty (an earlier run's with --replace).",
        ),
    ],
    layout: Annotated[
        str, typer.Option("--layout", metavar="LAYOUT", help="Layout file, or osong / example.")
    ] = "example",
    duration: Annotated[
        str | None,
        typer.Option(
            "--duration",
            metavar="DURATION",
            help="Simulated time: 90s, 30m, 2h, 1h30m (a bare number is seconds).  [default: 2h]",
        ),
    ] = None,
    seed: Annotated[
        int, typer.Option("--seed", metavar="N", help="Random seed: the same seed gives the same run.")
    ] = 1,
    trains_per_hour: Annotated[
        float,
        typer.Option(
            "--trains-per-hour",
            metavar="N",
            help="Trains entering the line an hour, on average (each interval varies by ±20 %).",
            min=0.1,
            max=60,
        ),
    ] = 6.0,
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
            metavar="KIND:TARGET:START[:END[:CH[:RATE]]]",
            help="KIND:TARGET:START[:END[:CHANNEL[:RATE]]], e.g. dead_channel:WS3:20m, train_parting:T2:14m,"
            " analog_drift:WS3:2d::1,"
            " gnss_decay:T2-eot:0s::2:0.02 (repeatable).",
        ),
    ] = None,
    days: Annotated[
        float | None,
        typer.Option(
            "--days",
            metavar="N",
            help="Simulate this many days (instead of --duration), from midnight: a directory of logs per day.",
            min=0.01,
            max=3650,
        ),
    ] = None,
    one_log: Annotated[
        bool, typer.Option("--one-log", help="With --days: one set of growing logs instead of one per day.")
    ] = False,
    health_only: Annotated[
        bool,
        typer.Option(
            "--health-only",
            help="Only the heads' health registers (1-edge counters, analog values): no trains; weeks in seconds.",
        ),
    ] = False,
    health_every: Annotated[
        str | None,
        typer.Option(
            "--health-every",
            metavar="DURATION",
            help="Write each head's health registers this often (default 15m with --days or a slow fault).",
        ),
    ] = None,
    fleet: Annotated[
        int | None,
        typer.Option(
            "--fleet",
            metavar="N",
            help="Trains are N trainsets T1..TN making trip after trip (default 3 with --days).",
            min=1,
        ),
    ] = None,
    json_out: JsonOpt = False,
    replace: Annotated[
        bool,
        typer.Option(
            "--replace", help="DIR holds an earlier run (its truth.json): replace it; every file in DIR goes."
        ),
    ] = False,
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
        from console.live.simulated import SimulatedConsole
        from console.output_path import (
            OutputError,
            check_output_directory,
            check_run_directory,
            files_below,
            remove_files,
            staged_directory,
        )
        from console.progress import byte_progress
        from console.safe_text import clean, show_path
        from console.sim.line_values import SimConfig
        from console.sim.radio import LoRaLink
        from console.sim.station import StationSim
        from console.sim.writers import write_run

        if days is not None and duration is not None:
            raise fail("--days runs whole days from midnight, --duration a stretch of time: give one or the other")
        duration_text = duration or "2h"
        try:
            seconds = parse_duration(duration_text) if days is None else days * 86_400.0
            health_period = None if health_every is None else parse_duration(health_every)
        except ValueError as exc:
            raise fail(f"--duration/--health-every: {exc}") from None
        if days is None and not 0 < seconds <= MAX_DURATION_S and not (live or mqtt):
            # The stepped run keeps its whole truth until it writes: longer runs go a day at a time (--days).
            raise fail("--duration: between 1s and 2d (longer runs: --days N, written a day at a time)")
        if days is None and (live or mqtt) and seconds <= 0:
            raise fail("--duration: a live run lasts more than 0s")  # it wrote its first records and stopped
        if health_period is not None and not 1 <= health_period <= 86_400:
            raise fail("--health-every: between 1s and 1d")
        if days is None and (one_log or health_only):
            raise fail("--one-log and --health-only go with --days N")
        if days is not None and (live or mqtt):
            raise fail("--days writes finished logs; --live and --mqtt run now: give one or the other")
        lay = load_layout(layout, said_here=("head_off_track",))  # said below, in its words
        faults = tuple(_parse_fault(f) for f in (fault or []))
        trainsets = fleet if fleet is not None else (3 if days is not None else 0)
        _check_targets(faults, lay, trainsets, health_only)
        _check_fault_times(faults, fault or [], seconds, duration_text if days is None else f"{days:g}d")
        if not health_only:
            _warn_heads_off_the_track(lay)
        layout_file = Path(layout)
        inputs = [layout_file] if layout_file.is_file() else []
        writes_run = live or not mqtt  # --mqtt alone publishes and writes nothing
        try:
            if writes_run:
                earlier = files_below(output) if check_run_directory(output, replace) else []
            else:
                check_output_directory(output, what="run")
                earlier = []
        except OutputError as exc:
            raise fail(str(exc)) from None
        config = SimConfig(
            seed=seed,
            trains_per_hour=trains_per_hour,
            radio=LoRaLink(spreading_factor=spreading_factor),
            faults=faults,
            health_period_s=health_period if health_period is not None else (900.0 if days is not None else None),
            fleet=trainsets,
        )
        if days is not None:
            import dataclasses

            from console.sim.days import midnight_ns

            config = dataclasses.replace(config, start_ns=midnight_ns(config.start_ns))
        if live or mqtt:  # a live run happens now: the units' clocks and the console's agree
            import dataclasses
            import time

            config = dataclasses.replace(config, start_ns=time.time_ns() // 10**9 * 10**9)
        try:
            sim = StationSim(lay, config)
        except ValueError as exc:
            raise fail(str(exc)) from None
        # The station's console watches the run (its final section states, its warnings in the centre table).
        console = None if health_only else SimulatedConsole(sim)
        if live or mqtt:
            from console.cli.commands.simulate_live import run_live_command

            if live:
                remove_files(earlier)  # a live run grows its files in place: the earlier run goes first
            return run_live_command(sim, seconds, live_speed, output if live else None, mqtt, json_out)
        if days is not None:
            return _run_days(sim, days, output, inputs, earlier, one_log, health_only, json_out, seed)
        # The bar counts simulated milliseconds (it only shows on a terminal, for long runs).
        with byte_progress(int(seconds * 1000) if seconds >= 600 else 0, "simulating") as advance:
            last = [0.0]

            def tick(t_s: float) -> None:
                if advance is not None:
                    advance(int((t_s - last[0]) * 1000))
                    last[0] = t_s

            sim.run(seconds, on_step=tick)
        _warn_unmet_train_faults(sim, faults)
        try:
            # Written into a hidden stage first: an interrupted run leaves no half-written log behind.
            with staged_directory(output, inputs, what="run", replace=earlier) as stage:
                counts = write_run(sim, stage)
        except OutputError as exc:
            raise fail(str(exc)) from None
        assert console is not None  # --health-only goes with --days
        sim_sections = {
            s: {"console": state, "true_count": sim.true_count(s)} for s, state in console.section_states().items()
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
            "sections": sim_sections,
        }
        if json_out:
            print_json(summary)
        else:
            bare = duration_text.strip().replace(".", "", 1).isdecimal()
            shown = f"{duration_text.strip()}s" if bare else duration_text  # a bare number is seconds: said so
            out = Console(highlight=False)
            out.print(
                f"simulated {shown} on {clean(lay.name)} (seed {seed}): {count(len(sim.trains), 'train')}, "
                f"{count(len(sim.truth_axles), 'axle passage')};"
                f" GNSS every {sim.period_s:.1f} s (LoRa SF{spreading_factor})",
                markup=False,
            )
            for line in _written_lines(output, counts):
                out.print(line, markup=False, soft_wrap=True)  # a path is not cut across lines
            for sid, st in sim_sections.items():
                out.print(
                    f"  section {sid}: console {st['console']}, axles really inside {st['true_count']}", markup=False
                )
        return exit_codes.OK

    raise typer.Exit(guard(body))


def _check_fault_times(faults: tuple[Any, ...], texts: list[str], seconds: float, run: str) -> None:
    """A fault that starts after the run ends never shows: refused, so the run is not taken for one with it."""
    for f, text in zip(faults, texts, strict=True):
        if f.start_s >= seconds:
            raise fail(f"--fault {text!r}: starts after the run ends ({run}): it would never show")


def _warn_heads_off_the_track(lay: Any) -> None:
    """A head beyond the [[track]] polyline is never passed (the trains run the polyline): said, so a run
    of no axle passages is not taken for a quiet line (a track in km beside heads in m, say)."""
    from console.safe_text import clean

    off = lay.heads_off_track()  # none without a track: the simulator refuses that layout, with its reason
    if off:
        low, high = lay.track[0].chainage_m, lay.track[-1].chainage_m
        shown = ", ".join(clean(h) for h in off[:5]) + (", …" if len(off) > 5 else "")
        sys.stderr.write(
            f"trackside: warning: {count(len(off), 'counting head')} outside the track ({low:g} to {high:g} m),"
            f" which no simulated train passes: {shown}\n"
        )


def _warn_unmet_train_faults(sim: Any, faults: tuple[Any, ...]) -> None:
    """A fault aimed at a train that never ran does nothing: said, so the run is not taken for one with it."""
    from console.analysis.timefmt import display
    from console.safe_text import clean
    from console.sim.faults import TRAIN_FAULTS
    from parsers.units import NS

    ran = sorted({str(tr.id) for tr in sim.trains})
    parted = {p.train for p in sim.truth_partings}
    for f in faults:
        # gnss_decay's target is a train's unit (T3-eot): its train must have run too.
        train = f.target.rpartition("-")[0] if f.kind == "gnss_decay" else f.target
        if (f.kind in TRAIN_FAULTS or f.kind == "gnss_decay") and train not in ran:
            sys.stderr.write(
                f"trackside: warning: --fault {f.kind}:{clean(f.target)}: no train {clean(train)} ran "
                f"({', '.join(ran) or 'none'}); nothing was injected\n"
            )
        elif f.kind in ("eot_loss", "head_loss") and not sim.reports_lost.get((f.target, f.kind[:-5])):
            # The unit sends nothing while the train is off the line: a window with no report in it.
            when = display(sim.cfg.start_ns + round(f.start_s * NS))
            unit = "EOT" if f.kind == "eot_loss" else "head"
            sys.stderr.write(
                f"trackside: warning: --fault {f.kind}:{clean(f.target)}: {clean(f.target)} was not running from "
                f"{when} to the fault's end, no {unit} report to lose; nothing was injected\n"
            )
        elif f.kind == "train_parting" and f.target not in parted:
            # It parts at START or the first moment after it the train runs: it had left the line by then.
            when = display(sim.cfg.start_ns + round(f.start_s * NS))
            sys.stderr.write(
                f"trackside: warning: --fault train_parting:{clean(f.target)}: {clean(f.target)} did not run at "
                f"or after {when}; nothing was injected\n"
            )


# What each count of a written file counts.
_UNITS = {"diagnostic.log": "line", "centre.tsv": "row", "sensor_frames.txt": "frame"}


def _written_lines(output: Path, counts: dict[str, Any]) -> list[str]:
    """The run's files, each with what it holds in words (``--json`` has the counts as they are)."""
    from console.safe_text import show_path

    lines = []
    for name, n in counts.items():
        where = show_path(output / name)
        if name == "nmea":
            units = ", ".join(f"{dev} {count(k, 'fix')}" for dev, k in n.items())
            lines.append(f"  {where}/: {units or 'no fix (no train reported in time)'}")
        elif name == "truth.json":
            lines.append(
                f"  {where}: the truth ({count(n.get('axles', 0), 'axle passage')}, "
                f"{count(n.get('crossings', 0), 'train at a crossing', 'trains at a crossing')})"
            )
        else:
            lines.append(f"  {where}: {count(n, _UNITS.get(name, 'item'))}")
    for extra in sorted(p.name for p in output.iterdir() if p.is_file() and p.name not in counts):
        lines.append(f"  {show_path(output / extra)}")  # the layout used, the GNSS units' export
    return lines


def _run_days(
    sim: Any,
    days: float,
    output: Path,
    inputs: list[Path],
    earlier: list[Path],
    one_log: bool,
    health_only: bool,
    json_out: bool,
    seed: int,
) -> int:
    from console.output_path import OutputError, staged_directory
    from console.progress import byte_progress
    from console.safe_text import clean, show_path
    from console.sim.days import run_days
    from console.sim.faults import SLOW_FAULT_KINDS

    with byte_progress(int(days * 86_400), "simulating days") as advance:
        last = [0.0]

        def tick(t_s: float) -> None:
            if advance is not None:
                advance(int(t_s - last[0]))
                last[0] = t_s

        try:
            with staged_directory(output, inputs, what="run", replace=earlier) as stage:
                written = run_days(sim, days, stage, one_log=one_log, health_only=health_only, on_step=tick)
        except OutputError as exc:
            raise fail(str(exc)) from None
    summary = {
        "schema": "trackside.simulate-days/1",
        "output": show_path(output),
        "layout": sim.layout.source,
        "seed": seed,
        "days": days,
        "one_log": one_log,
        "health_only": health_only,
        "trains": len(sim.trains),
        "heads_with_health_registers": len(sim.health.heads) if sim.health is not None else 0,
        "slow_faults": sum(1 for f in sim.faults if f.kind in SLOW_FAULT_KINDS),
        "written": written,
    }
    if json_out:
        print_json(summary)
    else:
        out = Console(highlight=False)
        what = "health registers of" if health_only else "trains, GNSS units and"
        out.print(
            f"simulated {days:g} {plural(days, 'day')} of {what} {count(len(sim.layout.heads), 'head')} on "
            f"{clean(sim.layout.name)} (seed {seed}): {count(len(sim.trains), 'trip')}; "
            f"{count(len(written['days']), 'day')} written into {show_path(output)}"
            f"{' as one growing log' if one_log else ', a directory per day'}",
            markup=False,
        )
    return exit_codes.OK
