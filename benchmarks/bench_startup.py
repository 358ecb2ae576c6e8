"""Start-up time of `trackside` on tiny inputs, beside `python -c pass`.

A first run is most often a small file: what it costs is start-up (imports,
the Typer app), not the analysis.  Each command runs as a fresh process,
alternating with the others round after round (so all see the same machine
load), and the median and minimum wall time and the peak RSS (wait4's
``ru_maxrss``) are printed, with the interpreter's own start-up
(`python -c pass`) as the floor.

    python benchmarks/bench_startup.py --rounds 15
    python benchmarks/bench_startup.py --rounds 15 --against /path/to/older/venv/bin/trackside

CPU time (user + system, median) is printed too: under load it moves less
than wall time.

Target (issue 23): ≤ 0.4 s wall for `analyze`, `gnss` and `query` on a tiny
input, checked against the medians and printed as PASS/MISS.  On a machine
shared with other jobs, compare the rows of one run, not runs of different
days.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_S = 0.4
TARGETED = ("analyze", "gnss", "query")
ROOT = Path(__file__).resolve().parent.parent
TWO_RECORDS = (ROOT / "sample_logs" / "osong_ws4_0932_passage.log").read_bytes()


def _sentence(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$%s*%02X\n" % (body, checksum)


NMEA = _sentence(b"GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W") + _sentence(
    b"GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
)


# As installed: byte-compiled modules (pip compiles them at install; a run writes them for an editable
# install), whatever this shell says (PYTHONDONTWRITEBYTECODE would recompile every module at every start).
_ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def run(cmd: list[str]) -> tuple[float, float, float]:
    """Wall seconds, CPU seconds (user + system) and peak RSS (MB) of one child process (output discarded;
    a failure stops the run).  CPU time is what to compare on a machine shared with other jobs."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=_ENV)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {err}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def commands(work: Path, trackside: str, label: str = "") -> dict[str, list[str]]:
    log, nmea, archive = work / "tiny.log", work / "tiny.nmea", work / f"archive{len(label)}"
    log.write_bytes(TWO_RECORDS)
    nmea.write_bytes(NMEA)
    if not archive.exists():  # each install its own archive: the archive format may differ between versions
        subprocess.run(
            [trackside, "ingest", str(log), "--archive", str(archive)], check=True, capture_output=True, env=_ENV
        )
    return {
        f"--help{label}": [trackside, "--help"],
        f"analyze{label}": [trackside, "analyze", str(log)],
        f"analyze --json{label}": [trackside, "analyze", str(log), "--json"],
        f"gnss{label}": [trackside, "gnss", str(nmea)],
        f"query{label}": [trackside, "query", "--archive", str(archive), "SELECT count(*) FROM records"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=15, help="runs of each command, alternating")
    parser.add_argument(
        "--against",
        metavar="TRACKSIDE",
        help="another install's trackside executable (an older version, say), run alternately with this one",
    )
    args = parser.parse_args()
    here = str(Path(sys.executable).with_name("trackside"))
    with tempfile.TemporaryDirectory() as tmp:
        cmds = {"python -c pass": [sys.executable, "-c", "pass"], **commands(Path(tmp), here)}
        if args.against:
            cmds.update(commands(Path(tmp), args.against, " (against)"))
        for cmd in cmds.values():  # warm the page cache and write the byte code once, untimed
            run(cmd)
        walls: dict[str, list[float]] = {k: [] for k in cmds}
        cpus: dict[str, list[float]] = {k: [] for k in cmds}
        rss: dict[str, float] = dict.fromkeys(cmds, 0.0)
        for _ in range(args.rounds):
            for name, cmd in cmds.items():
                wall, cpu, peak = run(cmd)
                walls[name].append(wall)
                cpus[name].append(cpu)
                rss[name] = max(rss[name], peak)
    print(f"{here}, {args.rounds} rounds, load average {os.getloadavg()[0]:.1f}")
    if args.against:
        print(f"against: {args.against}")
    print(f"{'command':<26} {'median s':>9} {'min s':>7} {'CPU s':>7} {'peak RSS MB':>12}")
    for name in cmds:
        median = statistics.median(walls[name])
        verdict = ""
        if name in TARGETED:
            verdict = "  PASS" if median <= TARGET_S else f"  MISS (target ≤ {TARGET_S} s)"
        cpu = statistics.median(cpus[name])
        print(f"{name:<26} {median:9.3f} {min(walls[name]):7.3f} {cpu:7.3f} {rss[name]:12.0f}{verdict}")


if __name__ == "__main__":
    main()
