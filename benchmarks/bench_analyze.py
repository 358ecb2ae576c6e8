"""Time `trackside analyze --json` against a bare pandas/pyarrow read of the same log.

For each log, the two commands run alternately (so both see the same page
cache and machine load), each as a fresh process; reported per log: median
wall time of each, their ratio, each one's peak RSS (wait4's ru_maxrss),
trackside's throughput in records/s and MB/s, and the peak RSS of
`trackside speeds --json`.  Over several logs, the time per record against
the smallest log's shows whether the analysis is linear.

    python benchmarks/gen_realistic_diag.py 3000000 /work/bench_data/real_3M.log \\
        --truth /work/bench_data/real_3M.truth.json
    python benchmarks/bench_analyze.py /work/bench_data/real_3M.log /work/bench_data/real_12M.log --repeat 3

The bare read is what a user would write first::

    pd.read_csv(log, sep="\\t", header=None, engine="pyarrow", dtype=str, on_bad_lines="skip", encoding="latin-1")

Targets (issue 12), checked and printed as PASS/MISS:

* peak RSS of `analyze --json` and `speeds --json` ≤ 256 MB at every size;
* ratio (trackside / bare read) ≤ 0.5;
* linear: the 12 M log takes ≤ 4.3× the 3 M log's time (per record: ≤ 1.075×
  the smallest log's time per record).

Records per log come from the generator's truth file next to it
(``<stem>.truth.json``), else from counting lines.  The machine may be shared:
ratios from alternating runs are what to compare, not absolute times; the load
average is printed with every round.

``--baseline DIR`` also runs ``analyze --json`` from another checkout in each
round (``git archive <commit> | tar -x -C DIR``), for before/after figures in
one run (issue 28)::

    python benchmarks/bench_analyze.py /work/bench_data/r3m.log --repeat 5 --baseline /tmp/base

``--pure`` also runs it with ``TRACKSIDE_PURE=1`` (the numpy tokenizer instead of the compiled one).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

BARE = (
    "import sys, pandas as pd; pd.read_csv(sys.argv[1], sep='\\t', header=None, engine='pyarrow',"
    " dtype=str, on_bad_lines='skip', encoding='latin-1')"
)
RSS_TARGET_MB = 256
RATIO_TARGET = 0.5
LINEAR_TARGET = 4.3 / 4  # 12 M in ≤ 4.3x the time of 3 M: per record, ≤ 1.075x


def run(cmd: list[str], cwd: Path | None = None, env: dict[str, str] | None = None) -> tuple[float, float, float]:
    """Wall seconds, peak RSS (MB) and CPU seconds (user + system, all threads) of one child process;
    stdout discarded.  CPU time is what to compare on a machine shared with other jobs."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=cwd, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd[:3])} failed: {err}")
    return wall, usage.ru_maxrss / 1024, usage.ru_utime + usage.ru_stime


def records_in(log: Path) -> int:
    truth = log.with_name(log.name.removesuffix(".log") + ".truth.json")
    if truth.is_file():
        return int(json.loads(truth.read_text())["records"])
    n = 0
    with log.open("rb") as f:
        while block := f.read(1 << 24):
            n += block.count(b"\n")
    return n


def mark(ok: bool) -> str:
    return "PASS" if ok else "MISS"


def in_checkout(cmd: list[str]) -> list[str]:
    """The command for ``python -c`` run in another checkout (its ``console`` is imported first there)."""
    launch = "import sys; sys.argv = ['trackside'] + sys.argv[1:]; from console.cli.app import app; app()"
    return [sys.executable, "-c", launch, *cmd[1:]]


def load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def bench(exe: str, log: Path, repeat: int, baseline: Path | None = None, pure: bool = False) -> dict[str, float]:
    ours_cmd = [exe, "analyze", "--json", str(log.resolve())]
    bare_cmd = [sys.executable, "-c", BARE, str(log)]
    run(bare_cmd)  # warm the page cache
    ours, bare, base, ours_pure = [], [], [], []
    pure_env = {**os.environ, "TRACKSIDE_PURE": "1"}
    for i in range(repeat):
        if baseline is not None:
            base.append(run(in_checkout(ours_cmd), cwd=baseline))
        ours.append(run(ours_cmd))
        bare.append(run(bare_cmd))
        if pure:
            ours_pure.append(run(ours_cmd, env=pure_env))
        line = f"  round {i + 1}: load {load()}  analyze {ours[-1][0]:.2f} s ({ours[-1][2]:.2f} CPU)"
        line += f"  bare {bare[-1][0]:.2f} s ({bare[-1][2]:.2f} CPU)  ratio {ours[-1][0] / bare[-1][0]:.2f}"
        if base:
            line += f"  baseline {base[-1][0]:.2f} s ({base[-1][2]:.2f} CPU, {base[-1][0] / bare[-1][0]:.2f})"
        if ours_pure:
            p = ours_pure[-1]
            line += f"  pure {p[0]:.2f} s ({p[2]:.2f} CPU, {p[0] / bare[-1][0]:.2f})"
        print(line, flush=True)
    speeds_rss = run([exe, "speeds", "--json", str(log)])[1]
    records = records_in(log)
    size_mb = log.stat().st_size / 1e6
    o_t = statistics.median(w for w, _, _ in ours)
    b_t = statistics.median(w for w, _, _ in bare)
    o_cpu = statistics.median(c for _, _, c in ours)
    b_cpu = statistics.median(c for _, _, c in bare)
    row = {
        "records": records,
        "size_mb": size_mb,
        "ours_s": o_t,
        "bare_s": b_t,
        "ratio": o_t / b_t,
        "ours_cpu_s": o_cpu,
        "bare_cpu_s": b_cpu,
        "ours_rss_mb": max(r for _, r, _ in ours),
        "bare_rss_mb": max(r for _, r, _ in bare),
        "speeds_rss_mb": speeds_rss,
        "records_per_s": records / o_t,
        "mb_per_s": size_mb / o_t,
    }
    print(f"input: {log} ({size_mb:,.0f} MB, {records:,} records), {repeat} alternating runs each")
    print(f"  trackside analyze --json : median {o_t:.2f} s ({o_cpu:.2f} s CPU)  peak RSS {row['ours_rss_mb']:.0f} MB")
    print(f"  bare pandas/pyarrow read : median {b_t:.2f} s ({b_cpu:.2f} s CPU)  peak RSS {row['bare_rss_mb']:.0f} MB")
    others = (("base", "baseline analyze --json ", base), ("pure", "TRACKSIDE_PURE=1 analyze", ours_pure))
    for key, label, runs in others:
        if not runs:
            continue
        run_t = statistics.median(w for w, _, _ in runs)
        run_cpu = statistics.median(c for _, _, c in runs)
        row.update({f"{key}_s": run_t, f"{key}_cpu_s": run_cpu, f"{key}_ratio": run_t / b_t})
        print(
            f"  {label} : median {run_t:.2f} s ({run_cpu:.2f} s CPU)"
            f"  peak RSS {max(r for _, r, _ in runs):.0f} MB  ratio {run_t / b_t:.2f}"
        )
    print(f"  trackside speeds --json  : peak RSS {speeds_rss:.0f} MB")
    print(f"  throughput               : {row['records_per_s']:,.0f} records/s, {row['mb_per_s']:.0f} MB/s")
    print(f"  ratio (trackside / bare) : {row['ratio']:.2f}  [{mark(row['ratio'] <= RATIO_TARGET)} ≤ {RATIO_TARGET}]")
    print(f"  CPU-time ratio           : {o_cpu / b_cpu:.2f}")
    rss_ok = max(row["ours_rss_mb"], speeds_rss) <= RSS_TARGET_MB
    print(f"  peak RSS target          : [{mark(rss_ok)} ≤ {RSS_TARGET_MB} MB]")
    print(
        "  runs (s): trackside "
        + " ".join(f"{w:.2f}" for w, _, _ in ours)
        + " | bare "
        + " ".join(f"{w:.2f}" for w, _, _ in bare),
        flush=True,
    )
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("logs", type=Path, nargs="+", help="logs, smallest first")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json-out", type=Path, help="also write the rows here")
    ap.add_argument("--baseline", type=Path, help="also run analyze --json from this checkout, alternately")
    ap.add_argument(
        "--pure", action="store_true", help="also run analyze --json with TRACKSIDE_PURE=1 (numpy tokenizer)"
    )
    args = ap.parse_args()
    exe = shutil.which("trackside") or sys.exit("trackside is not installed (pip install .)")
    print("command:", " ".join(sys.argv), f"(load {load()}, {os.cpu_count()} CPUs)", flush=True)
    rows = [bench(exe, log, args.repeat, args.baseline, args.pure) for log in args.logs]
    if len(rows) > 1:
        base = rows[0]["ours_s"] / rows[0]["records"]
        for log, row in zip(args.logs[1:], rows[1:], strict=True):
            per_record = row["ours_s"] / row["records"] / base
            scale = row["records"] / rows[0]["records"]
            print(
                f"linearity {log.name}: {row['ours_s'] / rows[0]['ours_s']:.2f}x the time for {scale:.1f}x the records"
                f" ({per_record:.2f}x per record) [{mark(per_record <= LINEAR_TARGET)} ≤ {LINEAR_TARGET:.3f}x]"
            )
    print(
        "| log | records | MB | analyze --json s (CPU s) | bare read s (CPU s) | ratio | CPU ratio"
        " | analyze RSS MB | speeds RSS MB | bare RSS MB | records/s | MB/s |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for log, r in zip(args.logs, rows, strict=True):
        print(
            f"| {log.name} | {r['records']:,} | {r['size_mb']:,.0f} | {r['ours_s']:.2f} ({r['ours_cpu_s']:.2f})"
            f" | {r['bare_s']:.2f} ({r['bare_cpu_s']:.2f}) | {r['ratio']:.2f} | {r['ours_cpu_s'] / r['bare_cpu_s']:.2f}"
            f" | {r['ours_rss_mb']:.0f} | {r['speeds_rss_mb']:.0f} | {r['bare_rss_mb']:.0f}"
            f" | {r['records_per_s']:,.0f} | {r['mb_per_s']:.0f} |"
        )
    if args.json_out:
        args.json_out.write_text(json.dumps(dict(zip(map(str, args.logs), rows, strict=True)), indent=1) + "\n")


if __name__ == "__main__":
    main()
