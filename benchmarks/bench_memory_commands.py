"""Peak RSS, wall and CPU time of `trackside sections`, `health`, `analyze`, `speeds` and `report` on big logs.

Each command runs as a fresh process (stdout to /dev/null); wall time, CPU
time (user + system) and peak RSS come from ``os.wait4`` (``ru_maxrss``).
The logs are the realistic multi-board exports of ``gen_realistic_diag.py``
(40 boards, 80 heads WS1 … WS80, device ids 5001 …).  No shipped layout
names those heads, so the benchmark writes one (:func:`write_layout`): each
board's two heads bound one section (WS1 in, WS2 out, …).  The generator's trains are independent per
head, so most sections end disturbed (count underflow): that is fine for a
memory benchmark, every axle still goes through the section engine and into
the ledger.

    python benchmarks/gen_realistic_diag.py 3000000 /work/bench_data/r3m.log --truth /work/bench_data/r3m.json
    python benchmarks/bench_memory_commands.py /work/bench_data/r3m.log --repeat 1
    python benchmarks/bench_memory_commands.py /work/bench_data/r3m.log --baseline /tmp/old --commands health

Target (issue 12): peak RSS ≤ 256 MB for every command at 3 M, 12 M and 30 M records.

Measured 2026-11-23 on the shared 2-core machine while ~5 other jobs ran
(wall times are inflated and noisy; compare them only within one row pair).
Logs: gen_realistic_diag.py 3 M (400 MB), 12 M (1.6 GB), 30 M (4.0 GB)
records; layout from :func:`write_layout` (80 heads, 40 sections).
A process that imports the CLI and reads an empty log peaks at ~135 MB.

| log | command | before (whole-file read) | after (streamed) |
| --- | --- | --- | --- |
| 3 M | `sections` | 664 MB, 54.9 s | 192 MB, 52.8 s |
| 3 M | `sections --json` | 862 MB, 63.0 s | 195 MB, 62.1 s |
| 3 M | `health` | 885 MB, 30.3 s | 195 MB, 31.3 s |
| 3 M | `report --format md` | 898 MB, 75.0 s | 543 MB, 78.4 s (over: see below) |
| 12 M | `sections` | — | 206 MB, 383.6 s |
| 12 M | `sections --json` | — | 207 MB, 514.4 s |
| 12 M | `health` | — | 208 MB, 243.2 s |
| 12 M | `report --format md` | — | 1619 MB, 266.1 s (over) |
| 30 M | `sections --json` | — | 231 MB, 1478 s |

Side by side at 3 M (``--baseline DIR``: a checkout of the commit before the
streaming read, 43c5cc4, made with ``git archive 43c5cc4 | tar -x -C DIR``;
alternating, one run each, heavier load):
`sections --json` 186.6 s / 863 MB → 135.8 s / 204 MB (0.73× the time);
`health` 105.3 s / 873 MB → 88.3 s / 194 MB (0.84×); `report --format md`
205.9 s / 891 MB → 124.6 s / 539 MB (0.60×).

`report` stayed over the target: the analysis streamed, but the report
document (console/sinks/report/document.py ``document``) was built whole before it
was rendered: every passage, every state change and every ledger row as a
dict (332 k ledger rows and 41 k passages at 3 M), then the Markdown, HTML
or JSON text in one string.

Report in bounded memory, measured 2026-11-26 on the same shared 2-core
machine (3–5 other jobs running; wall times inflated and noisy, CPU = user +
system seconds is the figure to compare).  Before: main at cb3d35c
(``git archive cb3d35c | tar -x -C DIR``); after: the branch that spools
passages and the section history to disk and writes the report as it is
rendered (console/sinks/report/spooled.py, jsonwrite.py).  One run each, before
and after alternately, with ``/usr/bin/time``; the outputs compared with
``cmp``: the same bytes in every row.  A process that imports the CLI and
the report now peaks at ~115 MB (the frame, CAN and GNSS parsers load only
when such inputs are given).

| log | command | before: peak, wall, CPU | after: peak, wall, CPU |
| --- | --- | --- | --- |
| 3 M | `report --format md` | 542 MB, 33.0 s, 18.9 s | 183 MB, 22.2 s, 13.8 s |
| 3 M | `report --format json` | 1046 MB, 33.7 s, 22.6 s | 192 MB, 25.5 s, 17.3 s |
| 3 M | `report --format html` | 600 MB, 34.0 s, 22.0 s | 183 MB, 22.7 s, 17.4 s |
| 12 M | `report --format md` | 1617 MB, 119.5 s, 80.0 s | 194 MB, 81.5 s, 54.1 s |
| 12 M | `report --format json` | 3574 MB, 130.4 s, 82.1 s | 204 MB, 75.8 s, 57.0 s |
| 12 M | `report --format html` | 1852 MB, 119.1 s, 83.0 s | 198 MB, 98.1 s, 63.5 s |
| 30 M | `report --format md` | not run (the old path needs GBs) | 220 MB, 206.4 s, 145.1 s |
| 30 M | `report --format json` | not run | 230 MB, 193.1 s, 152.3 s |
| 30 M | `report --format html` | not run | 226 MB, 196.4 s, 136.1 s |

The other commands after the change, 12 M, one run each (this script):
`sections` 191 MB (45.3 s CPU), `sections --json` 202 MB (51.6 s),
`health` 194 MB (33.7 s), `health --json` 193 MB (33.0 s), `analyze --json`
186 MB (13.9 s), `speeds --json` 187 MB (12.5 s).  `sections --json` at
30 M: 231 MB (137.0 s), one run earlier that day, before the heap trim after
the read.  The read itself now runs with Arrow on the system allocator
(console/stream_jobs.py ``read_memory``): the report's read peak at 12 M was
17 MB lower with it, at the same CPU.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_MB = 256.0
BOARDS = 40
COMMANDS = (
    "sections",
    "sections-json",
    "health",
    "health-json",
    "analyze-json",
    "speeds-json",
    "report-md",
    "report-json",
    "report-html",
)


def write_layout(path: Path, boards: int = BOARDS) -> None:
    """A layout for gen_realistic_diag's heads: board b's WS(2b+1), WS(2b+2) bound section S(b+1)."""
    lines = ['[line]\nname = "benchmark: realistic multi-board export"\nspeed_mps = 20.0\n']
    for b in range(boards):
        for k in (1, 2):
            n = 2 * b + k
            lines.append(
                f'[[heads]]\nid = "WS{n}"\ndevice_id = {5001 + b}\nchainage_m = {1000.0 * n}\n'
                'spacing_m = 0.13\nup = "sys1_to_sys2"\n'
            )
    for b in range(boards):
        lines.append(
            f'[[sections]]\nid = "S{b + 1}"\n'
            f'bounds = [{{ head = "WS{2 * b + 1}", sign = 1 }}, {{ head = "WS{2 * b + 2}", sign = -1 }}]\n'
        )
    path.write_text("\n".join(lines), encoding="utf-8")


def command(name: str, exe: str, log: Path, layout: Path) -> list[str]:
    if name.startswith("sections"):
        return [exe, "sections", str(log), "--layout", str(layout), *(["--json"] if name.endswith("json") else [])]
    if name.startswith(("health", "analyze", "speeds")):
        verb = name.split("-")[0]
        return [exe, verb, str(log), *(["--json"] if name.endswith("json") else [])]
    fmt = name.split("-")[1]
    return [exe, "report", str(log), "--layout", str(layout), "--format", fmt]


def in_checkout(cmd: list[str]) -> list[str]:
    """The command for ``python -c`` run in another checkout (its ``console`` is imported first there)."""
    launch = "import sys; sys.argv = ['trackside'] + sys.argv[1:]; from console.cli.app import app; app()"
    return [sys.executable, "-c", launch, *cmd[1:]]


def run(cmd: list[str], cwd: Path | None = None) -> tuple[float, float, float, int]:
    """Wall seconds, CPU seconds (user + system), peak RSS (MB) and exit code of one child process;
    stdout discarded."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=cwd)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 1):
        raise SystemExit(f"{' '.join(cmd)} failed ({code}): {err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("logs", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--commands", default=",".join(COMMANDS), help=f"comma-separated, of {', '.join(COMMANDS)}")
    ap.add_argument("--baseline", type=Path, help="also run each command from this checkout, alternately")
    args = ap.parse_args()
    exe = shutil.which("trackside") or sys.exit("trackside is not installed (pip install .)")
    names = [c.strip() for c in args.commands.split(",") if c.strip()]
    bad = [c for c in names if c not in COMMANDS]
    if bad:
        sys.exit(f"--commands: unknown {', '.join(bad)}")
    with tempfile.TemporaryDirectory() as tmp:
        layout = Path(tmp) / "layout.toml"
        write_layout(layout)
        print(f"{'log':<28} {'command':<19} {'wall s':>8} {'CPU s':>8} {'peak MB':>8}  target")
        for log in args.logs:
            for name in names:
                cmd = command(name, exe, log.resolve(), layout.resolve())
                for _ in range(args.repeat):
                    if args.baseline is not None:
                        wall, cpu, rss, _code = run(in_checkout(cmd), cwd=args.baseline)
                        print(f"{log.name:<28} {name + ' (base)':<19} {wall:8.2f} {cpu:8.2f} {rss:8.0f}", flush=True)
                    wall, cpu, rss, _code = run(cmd)
                    verdict = "ok" if rss <= TARGET_MB else "OVER"
                    print(f"{log.name:<28} {name:<19} {wall:8.2f} {cpu:8.2f} {rss:8.0f}  {verdict}", flush=True)


if __name__ == "__main__":
    main()
