"""Time `trackside analyze --json` against a bare pyarrow CSV read of the same file.

Runs the two commands alternately (so both see the same page cache and
machine load), each as a fresh process, and reports median wall time,
their ratio, and each one's peak RSS (from wait4's ru_maxrss).

    python benchmarks/gen_diag_log.py 3000000 /tmp/diag_3M.log
    python benchmarks/bench_analyze.py /tmp/diag_3M.log --repeat 5

Targets (issue 2): ratio ≤ 1.0, trackside peak RSS ≤ 400 MB.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

BARE = "import sys, pandas as pd; pd.read_csv(sys.argv[1], sep='\\t', header=None, engine='pyarrow', dtype=str)"


def run(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one child process; stdout discarded."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{cmd[0]} failed: {err}")
    return wall, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    exe = shutil.which("trackside") or sys.exit("trackside is not installed (pip install .)")
    ours_cmd = [exe, "analyze", "--json", str(args.log)]
    bare_cmd = [sys.executable, "-c", BARE, str(args.log)]
    run(bare_cmd)  # warm the page cache
    ours, bare = [], []
    for _ in range(args.repeat):
        ours.append(run(ours_cmd))
        bare.append(run(bare_cmd))
    size_mb = args.log.stat().st_size / 1e6
    o_t = statistics.median(w for w, _ in ours)
    b_t = statistics.median(w for w, _ in bare)
    print(f"input: {args.log} ({size_mb:.0f} MB), {args.repeat} alternating runs each")
    print(f"trackside analyze --json : median {o_t:.2f} s  peak RSS {max(r for _, r in ours):.0f} MB")
    print(f"bare pandas/pyarrow read : median {b_t:.2f} s  peak RSS {max(r for _, r in bare):.0f} MB")
    print(f"ratio (trackside / bare) : {o_t / b_t:.2f}")
    print(
        "runs (s): trackside "
        + " ".join(f"{w:.2f}" for w, _ in ours)
        + " | bare "
        + " ".join(f"{w:.2f}" for w, _ in bare)
    )


if __name__ == "__main__":
    main()
