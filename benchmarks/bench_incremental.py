"""Ingest of one more day into an archive holding several days: how long, with the code on the path.

The log is split by the records' date into one file per day; an archive is
built from all days but the last (one ingest), then copied ``--runs`` times
and the last day ingested into each copy, timed.  Run it once per code
version and compare (the derivation before issue 13's incremental derive
recomputed every derived table over the whole archive)::

    python benchmarks/gen_diag_log.py 400000 /tmp/diag_400k.log
    python benchmarks/bench_incremental.py /tmp/diag_400k.log /tmp/inc-new --runs 3
    git worktree add /tmp/old 43c5cc4 && PYTHONPATH=/tmp/old python benchmarks/bench_incremental.py \\
        /tmp/diag_400k.log /tmp/inc-old --runs 3
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path


def split_by_day(log: Path, out: Path) -> list[Path]:
    """One file per date (``Date:YYYY-MM-DD`` of each line), in date order."""
    out.mkdir(parents=True, exist_ok=True)
    files: dict[str, list[bytes]] = {}
    with log.open("rb") as f:
        for line in f:
            i = line.find(b"Date:")
            day = line[i + 5 : i + 15].decode() if i >= 0 else "0000-00-00"
            files.setdefault(day, []).append(line)
    paths = []
    for day in sorted(files):
        p = out / f"day-{day}.log"
        p.write_bytes(b"".join(files[day]))
        paths.append(p)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("work", type=Path, help="scratch directory (replaced)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--layout", default=None)
    args = ap.parse_args()

    import console.archive.derive as derive_module
    from console.archive.ingest import run_ingest
    from console.archive.store import read_current

    shutil.rmtree(args.work, ignore_errors=True)
    days = split_by_day(args.log, args.work / "days")
    base = args.work / "base"
    t0 = time.perf_counter()
    run_ingest(days[:-1], base, layout=args.layout)
    first = time.perf_counter() - t0
    m = read_current(base)
    records = sum(int(e.get("records", 0)) for e in m.files)
    times = []
    cpu = []
    for i in range(args.runs):
        arc = args.work / f"run{i}"
        shutil.copytree(base, arc)
        t0, c0 = time.perf_counter(), time.process_time()
        run_ingest([days[-1]], arc)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)  # all threads of this process: less sensitive to other jobs
        rederived = None
        parts = read_current(arc).derived.get("partitions")
        if parts is not None:
            g = read_current(arc).generation
            rederived = sum(1 for v in parts.values() if v["generation"] == g)
        shutil.rmtree(arc)
    print(
        json.dumps(
            {
                "code": str(Path(derive_module.__file__).resolve().parent.parent.parent),
                "days_in_archive": len(days) - 1,
                "records_in_archive": records,
                "first_ingest_s": round(first, 2),
                "one_more_day_s": [round(t, 2) for t in times],
                "one_more_day_cpu_s": [round(t, 2) for t in cpu],
                "partitions": len(parts) if parts is not None else None,
                "partitions_rederived": rederived,
            }
        )
    )


if __name__ == "__main__":
    main()
