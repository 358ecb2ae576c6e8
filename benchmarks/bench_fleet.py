"""Ingest on the fleet engine: local vs Dask with 1 and 2 workers (issue "One engine").

    # a 12 M-record realistic log, cut into one file per device and day (40 devices × 2 days = 80 files)
    python benchmarks/gen_realistic_diag.py 12000000 /work/bench_data/r12m.log
    python benchmarks/bench_fleet.py /work/bench_data/fleet12m --split-from /work/bench_data/r12m.log --rounds 2

What is timed: ``trackside ingest DIR`` of every file, into a fresh archive,
the whole command's work in this process (each configuration runs in a
child process of its own, ``--one``, in turn: local, 1 worker, 2 workers,
then again, so a noisy machine disturbs them alike).  On Dask the files are
planned by independent group of heads (the heads of sections sharing heads
go together; a head no section uses is a device's group): the files sharing
a group are one task, which parses them, writes their records and feeds
each group's pipeline in the same pass, as the local ingest does, and saves
each group's state; the client plans, gathers the ledger and publishes.

* ``start_s``: the LocalCluster's start (not in ``ingest_s``);
* ``ingest_s``, with ``phases`` (read, records, derive, publish) as the ingest reports them;
* ``client_cpu_s``, ``worker_cpu_s``: CPU seconds (user + system) here and in each worker;
* ``peak_rss_mb``: this process's peak; per worker process its peak;
* ``serial``: the ingest's wall cut where its task maps start and end and its phases end; each piece
  outside the maps is the client's serial work, by name, [wall s, client CPU s] (:func:`serial_parts`),
  printed with its share of the wall and the load average.
"""

from __future__ import annotations

import argparse
import itertools
import json
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

_KEY = re.compile(rb"\tID:(\d+)\t.*\tDate:(\d{4}-\d\d-\d\d)\t")


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def split(log: Path, out: Path) -> int:
    """One file per device and day of ``log`` (lines in their order); the number of files."""
    out.mkdir(parents=True, exist_ok=True)
    files: dict[tuple[bytes, bytes], Any] = {}
    try:
        with log.open("rb") as f:
            for line in f:  # a benchmark's preparation, once
                m = _KEY.search(line)
                key = (m[1], m[2]) if m else (b"junk", b"x")
                h = files.get(key)
                if h is None:
                    h = files[key] = (out / f"{key[0].decode()}-{key[1].decode()}.log").open("wb")
                h.write(line)
    finally:
        for h in files.values():
            h.close()
    return len(files)


def serial_parts(
    wall0: float, cpu0: float, phase_ends: dict[str, tuple[float, float]], spans: list[Any]
) -> dict[str, list[float]]:
    """The ingest's wall cut at its phases' ends and its task maps' starts and ends: each piece outside the
    task maps is the client's serial work, named by its phase and the maps around it; ``[wall s, client CPU s]``
    each.  ``tasks: LABEL`` sums the pieces inside the maps of that label (the workers run; the client waits,
    schedules and collects: a LocalCluster's scheduler runs in this process)."""
    points: list[tuple[float, float, str]] = [(wall0, cpu0, "start")]
    points += [(w, c, f"end {name}") for name, (w, c) in phase_ends.items()]
    for sp in spans:
        points += [(sp.wall0, sp.cpu0, f"[{sp.label}"), (sp.wall1, sp.cpu1, f"{sp.label}]")]
    points.sort()
    inside = [(sp.wall0, sp.wall1, sp.label) for sp in spans]
    phase_names = list(phase_ends)
    out: dict[str, list[float]] = {}
    for (w0, c0, what0), (w1, c1, what1) in itertools.pairwise(points):
        mid = (w0 + w1) / 2
        label = next((lb for a, b, lb in inside if a <= mid <= b), None)
        if label is not None:
            name = f"tasks: {label}"
        else:
            # The phase this piece lies in (the first whose end is at or after it), and the task maps around it.
            phase = next((n for n in phase_names if phase_ends[n][0] >= w1), phase_names[-1])
            after = f"after {what0[:-1]}" if what0.endswith("]") else "from its start" if what0 == "start" else ""
            before = f"before {what1[1:]}" if what1.startswith("[") else ""
            name = ": ".join([phase, " ".join(w for w in (after, before) if w)]).rstrip(": ")
        acc = out.setdefault(name, [0.0, 0.0])
        acc[0] += w1 - w0
        acc[1] += c1 - c0
    return {k: [round(v[0], 2), round(v[1], 2)] for k, v in out.items()}


def one(inputs: Path, engine: str) -> dict[str, Any]:
    """One configuration, in this process: ``local`` or ``dask:N``."""
    from console.archive.ingest import run_ingest
    from console.fleet import engine as fleet_engine
    from console.fleet import engine_scope
    from console.fleet.options import engine_spec

    spec = engine_spec("local") if engine == "local" else engine_spec("dask", workers=int(engine.split(":")[1]))
    arc = Path(tempfile.mkdtemp(prefix="bench-fleet-"))
    out: dict[str, Any] = {"engine": engine}
    t0 = time.perf_counter()
    try:
        with engine_scope(spec, progress=False):
            client = getattr(fleet_engine._current.get(), "client", None)
            cpu_at_start = client.run(_cpu_s) if client is not None else {}
            started = time.perf_counter()
            cpu0 = _cpu_s()
            pcpu0 = time.process_time()
            summary = run_ingest([inputs], arc)
            done = time.perf_counter()
            out["client_cpu_s"] = round(_cpu_s() - cpu0, 1)
            out["serial"] = serial_parts(started, pcpu0, summary.phase_ends, fleet_engine.task_spans())
            if client is not None:
                rss = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
                cpu = client.run(_cpu_s)
                out["worker_peak_rss_mb"] = sorted(round(v, 1) for v in rss.values())
                out["worker_cpu_s"] = sorted(round(v - cpu_at_start.get(k, 0.0), 1) for k, v in cpu.items())
    finally:
        shutil.rmtree(arc, ignore_errors=True)
    out["start_s"] = round(started - t0, 2)
    out["ingest_s"] = round(done - started, 2)
    out["phases"] = {k: round(v, 2) for k, v in summary.phases.items()}
    out["records"] = summary.records
    out["files"] = len(summary.added)
    out["peak_rss_mb"] = round(_peak_rss_mb(), 1)
    out["load"] = Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("inputs", type=Path, help="a directory of diagnostic logs")
    ap.add_argument("--split-from", type=Path, help="a log to cut into one file per device and day first")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--workers", default="1,2", help="worker counts to run, e.g. 1,2")
    ap.add_argument("--no-local", action="store_true", help="skip the local engine")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--json", type=Path, help="write the runs here")
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.inputs, args.one)))
        return
    if args.split_from is not None and not args.inputs.exists():
        t = time.perf_counter()
        n = split(args.split_from, args.inputs)
        print(f"split {args.split_from} into {n} files in {time.perf_counter() - t:.0f} s", flush=True)
    configs = ([] if args.no_local else ["local"]) + [f"dask:{w}" for w in args.workers.split(",")]
    runs: list[dict[str, Any]] = []
    for r in range(args.rounds):
        for engine in configs:
            cmd = [sys.executable, __file__, str(args.inputs), "--one", engine]
            res = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if res.returncode != 0:
                sys.exit(f"{engine}: {res.stderr.strip().splitlines()[-3:]}")
            run = json.loads(res.stdout.strip().splitlines()[-1])
            run["round"] = r
            runs.append(run)
            workers = run.get("worker_peak_rss_mb", [])
            serial = {k: v for k, v in run.get("serial", {}).items() if not k.startswith("tasks")}
            tasks = {k: v for k, v in run.get("serial", {}).items() if k.startswith("tasks")}
            serial_s = sum(v[0] for v in serial.values())
            print(
                f"round {r} {engine:7s} ingest {run['ingest_s']:7.1f} s ({run['records'] / run['ingest_s'] / 1e3:,.0f}"
                f" k rec/s, {run['files']} files)  phases {run['phases']}  start {run['start_s']:5.1f} s"
                f"  client peak {run['peak_rss_mb']:6.0f} MB cpu {run['client_cpu_s']} s"
                + (f"  workers peak {workers} MB cpu {run['worker_cpu_s']} s" if workers else ""),
                flush=True,
            )
            if workers:
                print(
                    f"    serial (client alone) {serial_s:.2f} s"
                    f" = {100 * serial_s / run['ingest_s']:.1f} % of the wall;"
                    f" {tasks} [wall s, client CPU s];  load {run['load']}",
                    flush=True,
                )
                for k, v in serial.items():
                    print(f"      {k:40s} {v[0]:6.2f} s wall {v[1]:6.2f} s CPU", flush=True)
    by: dict[str, list[float]] = {}
    for run in runs:
        by.setdefault(run["engine"], []).append(run["ingest_s"])
    med = {k: statistics.median(v) for k, v in by.items()}
    for k, v in med.items():
        print(f"median {k:7s} {v:7.1f} s")
    if "dask:1" in med and "dask:2" in med:
        print(f"speed-up 2 workers / 1 worker: {med['dask:1'] / med['dask:2']:.2f}x")
    if args.json:
        args.json.write_text(json.dumps({"runs": runs, "median_s": med}, indent=1))


if __name__ == "__main__":
    main()
