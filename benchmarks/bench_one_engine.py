"""Issue 22's targets: `ingest` against `analyze --json` on the same log, and `report --format json`'s peak.

Each command runs as a fresh process (wall, CPU and peak RSS from ``os.wait4``, as
bench_memory_commands.py); the commands alternate within each round, so a change of load hits them
alike.  ``ingest`` writes a fresh archive each time (no layout: records, passages and axles), and the
archive is removed after the round.  ``--baseline DIR`` runs ``analyze --json`` and ``ingest`` from
another checkout too, each just before this tree's (``git archive a140356 | tar -x -C DIR``), for "no slower
than today" and for an A/B of an ingest change.  Each row shows the 1-minute load average as it ended: on a
shared machine the wall times are only comparable within a round; CPU (user + system) is the steadier figure.

    python benchmarks/gen_realistic_diag.py 3000000 /work/bench_data/r3m.log
    python benchmarks/gen_realistic_diag.py 12000000 /work/bench_data/r12m.log
    python -m benchmarks.bench_one_engine /work/bench_data/r3m.log /work/bench_data/r12m.log --repeat 2

Targets: ingest wall ≤ 1.3 × analyze --json wall and peak ≤ 256 MB at both sizes; report --format json
≤ 256 MB at 12 M records; ``follow --from-start`` (``--commands follow-from-start``: not in the default
set) ≤ 256 MB, not growing with the log, and so ``cat LOG | trackside follow -`` (``follow-pipe``).
Figures: benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
from pathlib import Path

from benchmarks.bench_memory_commands import TARGET_MB, in_checkout, run, write_layout

INGEST_RATIO = 1.3
COMMANDS = ("analyze-json", "ingest", "report-json", "report-json-layout", "follow-from-start", "follow-pipe")
DEFAULT = COMMANDS[:4]


def command(name: str, exe: str, log: Path, layout: Path, archive: Path) -> list[str]:
    if name == "analyze-json":
        return [exe, "analyze", str(log), "--json"]
    if name == "ingest":
        return [exe, "ingest", str(log), "--archive", str(archive)]
    if name == "follow-from-start":  # the log read as a followed file from its start; ends 3 s after its last line
        return [exe, "follow", str(log), "--from-start", "--jsonl", "--idle-exit", "3"]
    if name == "follow-pipe":  # `cat LOG | trackside follow -`: ends with the stream (peak RSS: the larger, follow's)
        return ["sh", "-c", 'cat "$1" | "$0" follow - --jsonl', exe, str(log)]
    if name == "report-json":
        return [exe, "report", str(log), "--format", "json", "-o", str(archive.parent / "report.json")]
    return [exe, "report", str(log), "--layout", str(layout), "--format", "json", "-o", str(archive.parent / "r.json")]


def _load() -> str:
    """The 1-minute load average now (the machine's other work during the run just ended)."""
    return f"{os.getloadavg()[0]:4.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("logs", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--commands", default=",".join(DEFAULT), help=f"comma-separated, of {', '.join(COMMANDS)}")
    ap.add_argument("--baseline", type=Path, help="also run analyze --json from this checkout, alternately")
    args = ap.parse_args()
    # The trackside of the Python running this (its venv), before any other on PATH.
    beside = Path(sys.executable).with_name("trackside")
    exe = str(beside) if beside.exists() else shutil.which("trackside") or sys.exit("trackside is not installed")
    names = [c.strip() for c in args.commands.split(",") if c.strip()]
    if bad := [c for c in names if c not in COMMANDS]:
        sys.exit(f"--commands: unknown {', '.join(bad)}")
    print("command:", " ".join(sys.argv), flush=True)
    with tempfile.TemporaryDirectory(dir="/work/bench_data" if Path("/work/bench_data").is_dir() else None) as tmp:
        layout = Path(tmp) / "layout.toml"
        write_layout(layout)
        print(f"{'log':<12} {'command':<24} {'wall s':>8} {'CPU s':>8} {'peak MB':>8}  load  target", flush=True)
        for log in args.logs:
            walls: dict[str, list[float]] = {}
            for _ in range(args.repeat):
                archive = Path(tmp) / "arc"
                for name in names:
                    cmd = command(name, exe, log.resolve(), layout, archive)
                    if args.baseline is not None and name in ("analyze-json", "ingest"):
                        wall, cpu, rss, code = run(in_checkout(cmd), cwd=args.baseline)
                        if code != 0:  # a failed run's figures are no figures
                            sys.exit(f"{name} (base) exited {code}: {' '.join(in_checkout(cmd))}")
                        shutil.rmtree(archive, ignore_errors=True)
                        walls.setdefault(f"{name} (base)", []).append(wall)
                        base = f"{name} (base)"
                        print(f"{log.name:<12} {base:<24} {wall:8.2f} {cpu:8.2f} {rss:8.0f}  {_load()}", flush=True)
                    wall, cpu, rss, code = run(cmd)
                    if code != 0:
                        sys.exit(f"{name} exited {code}: {' '.join(cmd)}")
                    walls.setdefault(name, []).append(wall)
                    verdict = "ok" if rss <= TARGET_MB else "OVER"
                    print(
                        f"{log.name:<12} {name:<24} {wall:8.2f} {cpu:8.2f} {rss:8.0f}  {_load()}  {verdict}", flush=True
                    )
                    shutil.rmtree(archive, ignore_errors=True)
            if "ingest" in walls and "analyze-json" in walls:
                ratio = statistics.median(walls["ingest"]) / statistics.median(walls["analyze-json"])
                verdict = "ok" if ratio <= INGEST_RATIO else "OVER"
                print(f"{log.name:<12} ingest / analyze --json, median wall: {ratio:.2f}×  {verdict}", flush=True)
            if "ingest (base)" in walls and "analyze-json (base)" in walls:
                ratio = statistics.median(walls["ingest (base)"]) / statistics.median(walls["analyze-json (base)"])
                print(f"{log.name:<12} base: ingest / analyze --json, median wall: {ratio:.2f}×", flush=True)


if __name__ == "__main__":
    main()
