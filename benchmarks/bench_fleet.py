"""The archive's derivation on the fleet engine: local vs Dask with 1 and 2 workers (issue "Fleet scale").

    # a 3 M-record realistic log, ingested, then its records copied onto 10 consecutive days: 30 M records
    python benchmarks/gen_realistic_diag.py 3000000 /work/bench_data/r3m.log
    trackside ingest /work/bench_data/r3m.log --archive /work/bench_data/fleet/src3m
    python benchmarks/bench_fleet.py /work/bench_data/fleet/arc30m --build-from /work/bench_data/fleet/src3m \\
        --replicas 10 --rounds 2

What is timed: :func:`console.archive.fleet_derive.derive_partitions` over
every (device, day) partition of the archive — each partition reads its
device's records of its day and of the day before (and the days after while
a passage runs on), runs the batch analysis and returns its passages, axles
and wheel records; the rows are gathered and combined in partition order —
the work an ingest's derivation does before it writes.  Each configuration
runs in a child process of its own (``--one``), in turn (local, 1 worker,
2 workers, then again), so a noisy machine disturbs them alike:

* ``start_s``: the LocalCluster's start (not in ``derive_s``);
* ``derive_s``: the map and the combine;
* ``client_cpu_s``, ``worker_cpu_s``: CPU seconds (user + system) spent
  during the derivation here and in each worker: on a machine shared with
  other jobs the wall time says how much CPU we were given, the CPU time
  what the work costs, and how evenly the workers shared it;
* ``peak_rss_mb``: this process's peak (the local engine computes here;
  with Dask it holds the gathered rows), and per worker process its peak
  (``getrusage`` in the worker after the run) — each worker is bounded to
  512 MB by its nanny, so a worker over it would be restarted and show up
  as a retry, not as a bigger number.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _cpu_s() -> float:
    """CPU seconds of this process so far (user + system): the work done, whatever else the machine runs."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _worker_figures(client: Any, cpu_at_start: dict[str, float]) -> dict[str, Any]:
    """Each Dask worker's peak RSS and the CPU seconds it spent since ``cpu_at_start`` (none: local)."""
    if client is None:
        return {}
    rss = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    cpu = client.run(_cpu_s)
    return {
        "worker_peak_rss_mb": sorted(round(v, 1) for v in rss.values()),
        "worker_cpu_s": sorted(round(v - cpu_at_start.get(k, 0.0), 1) for k, v in cpu.items()),
    }


def one(archive: Path, engine: str) -> dict[str, Any]:
    """One configuration, in this process: ``local`` or ``dask:N``."""
    from console.archive.fleet_derive import derive_partitions
    from console.archive.partition import partitions
    from console.archive.store import read_current
    from console.fleet import engine as fleet_engine
    from console.fleet import engine_scope, engine_spec

    m = read_current(archive)
    n_parts = len(partitions(m))
    spec = engine_spec() if engine == "local" else engine_spec("dask", workers=int(engine.split(":")[1]))
    t0 = time.perf_counter()
    out: dict[str, Any] = {"engine": engine, "partitions": n_parts}
    with engine_scope(spec, progress=False):
        current = fleet_engine._current.get()
        client = getattr(current, "client", None)
        cpu_at_start: dict[str, float] = client.run(_cpu_s) if client is not None else {}
        cpu0 = _cpu_s()
        started = time.perf_counter()
        tables = derive_partitions(archive, m)
        done = time.perf_counter()
        out["client_cpu_s"] = round(_cpu_s() - cpu0, 1)
        out |= _worker_figures(client, cpu_at_start)
    out["start_s"] = round(started - t0, 2)
    out["derive_s"] = round(done - started, 2)
    out["rows"] = {k: len(v) for k, v in tables.items()}
    out["peak_rss_mb"] = round(_peak_rss_mb(), 1)
    return out


def one_derive_tables(archive: Path, engine: str) -> dict[str, Any]:
    """``--what derive-tables``: the derivation an ingest runs (console.archive.derive.derive_tables), all of it.

    Every partition derived again (the manifest's derived state dropped), each
    task's rows stored as they come back (parts of an unpublished generation,
    removed after the run), then the cross-head step (section states, ledger,
    health, crossings) in this process.  ``map_s`` is the partition tasks on the
    engine, ``cross_s`` the step after them.
    """
    import copy
    import shutil

    from console.archive.derive import derive_tables
    from console.archive.partition import partitions
    from console.archive.store import read_current
    from console.fleet import engine as fleet_engine
    from console.fleet import engine_scope, engine_spec, fleet_mapper

    m = copy.deepcopy(read_current(archive))
    layout = m.derived.get("layout")
    m.derived = {}
    m.generation += 100_000  # parts of a generation no manifest will name
    spec = engine_spec() if engine == "local" else engine_spec("dask", workers=int(engine.split(":")[1]))
    out: dict[str, Any] = {"engine": engine, "partitions": len(partitions(m))}
    import console.archive.derive as derive_module

    crossed = {"s": 0.0, "cpu_s": 0.0}
    cross_head = derive_module._derive_cross_head

    def timed_cross_head(*args: Any, **kwargs: Any) -> Any:
        # The cross-head step (after every partition task): timed apart, the rest of the run is the map
        # (the tasks on the engine, and their rows stored here as they come back).
        t, cpu = time.perf_counter(), _cpu_s()
        try:
            return cross_head(*args, **kwargs)
        finally:
            crossed["s"] += time.perf_counter() - t
            crossed["cpu_s"] += _cpu_s() - cpu

    derive_module._derive_cross_head = timed_cross_head

    t0 = time.perf_counter()
    written: list[str] = []
    with engine_scope(spec, progress=False):
        client = getattr(fleet_engine._current.get(), "client", None)
        cpu_at_start: dict[str, float] = client.run(_cpu_s) if client is not None else {}
        cpu0 = _cpu_s()
        started = time.perf_counter()
        try:
            written = derive_tables(archive, m, layout, mapper=fleet_mapper)
        finally:
            done = time.perf_counter()
            for rel in written:
                (archive / rel).unlink(missing_ok=True)
            shutil.rmtree(archive / "tmp", ignore_errors=True)
        out["client_cpu_s"] = round(_cpu_s() - cpu0, 1)
        out |= _worker_figures(client, cpu_at_start)
    out["start_s"] = round(started - t0, 2)
    out["derive_s"] = round(done - started, 2)
    out["map_s"] = round(done - started - crossed["s"], 2)
    out["cross_s"] = round(crossed["s"], 2)
    out["client_cpu_cross_s"] = round(crossed["cpu_s"], 1)
    out["parts_written"] = len(written)
    out["peak_rss_mb"] = round(_peak_rss_mb(), 1)
    return out


def records_of(archive: Path) -> int:
    from console.archive.views import run_query

    return int(run_query(archive, "SELECT count(*) FROM records")[1][0][0])  # type: ignore[call-overload]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("archive", type=Path)
    ap.add_argument("--build-from", type=Path, help="an ingested archive to copy onto --replicas consecutive days")
    ap.add_argument("--replicas", type=int, default=10)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--workers", default="1,2", help="worker counts to run, e.g. 1,2")
    ap.add_argument("--no-local", action="store_true", help="skip the local engine")
    ap.add_argument(
        "--what",
        choices=("partitions", "derive-tables"),
        default="partitions",
        help="partitions: the partition tasks, rows gathered here; derive-tables: an ingest's whole derivation",
    )
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--json", type=Path, help="write the runs here")
    args = ap.parse_args()

    if args.one:
        run_one = one_derive_tables if args.what == "derive-tables" else one
        print(json.dumps(run_one(args.archive, args.one)))
        return
    if not (args.archive / "CURRENT").exists():
        if args.build_from is None:
            sys.exit(f"{args.archive}: no archive (give --build-from)")
        from benchmarks.bench_archive import replicate

        t = time.perf_counter()
        n = replicate(args.build_from, args.archive, args.replicas)
        print(f"built {args.archive}: {n:,} records in {time.perf_counter() - t:.0f} s", flush=True)
    n_records = records_of(args.archive)
    size = sum(p.stat().st_size for p in (args.archive / "data").rglob("*.parquet"))
    print(f"archive: {n_records:,} records, {size / 1e6:.1f} MB of Parquet ({size / n_records:.2f} B/record)")

    configs = ([] if args.no_local else ["local"]) + [f"dask:{w}" for w in args.workers.split(",")]
    runs: list[dict[str, Any]] = []
    for r in range(args.rounds):
        for engine in configs:
            cmd = [sys.executable, __file__, str(args.archive), "--what", args.what, "--one", engine]
            res = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if res.returncode != 0:
                sys.exit(f"{engine}: {res.stderr.strip().splitlines()[-1:]}")
            run = json.loads(res.stdout.strip().splitlines()[-1])
            run["round"] = r
            runs.append(run)
            workers = run.get("worker_peak_rss_mb", [])
            rate = n_records / run["derive_s"] / 1e3
            print(
                f"round {r} {engine:7s} derive {run['derive_s']:7.1f} s ({rate:,.0f} k rec/s)"
                f"  start {run['start_s']:5.1f} s  client peak {run['peak_rss_mb']:6.0f} MB"
                + (f"  workers peak {workers} MB" if workers else "")
                + (f"  map {run['map_s']} s cross-head {run['cross_s']} s" if "map_s" in run else "")
                + f"  cpu client {run['client_cpu_s']} s"
                + (f" (cross-head {run['client_cpu_cross_s']} s)" if "client_cpu_cross_s" in run else "")
                + (f" workers {run['worker_cpu_s']} s" if workers else ""),
                flush=True,
            )
    by: dict[str, list[float]] = {}
    for run in runs:
        by.setdefault(run["engine"], []).append(run["derive_s"])
    med = {k: statistics.median(v) for k, v in by.items()}
    for k, v in med.items():
        print(f"median {k:7s} {v:7.1f} s")
    if "dask:1" in med and "dask:2" in med:
        print(f"speed-up 2 workers / 1 worker: {med['dask:1'] / med['dask:2']:.2f}x")
    if args.json:
        args.json.write_text(
            json.dumps({"records": n_records, "parquet_bytes": size, "runs": runs, "median_s": med}, indent=1)
        )


if __name__ == "__main__":
    main()
