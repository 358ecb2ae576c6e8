"""`trackside query --format csv|jsonl` of a long result: Arrow batches written column by column (now) against
Python rows written value by value (before), alternately, each a fresh process.

    python benchmarks/bench_query_text.py ARCHIVE --sql "SELECT * FROM records" --rounds 2

"value by value" is the same command with console.cli.commands.query.ARROW_AFTER_ROWS raised above the result's
size: every row then goes through the Python path, as before the column writer.  Both outputs are compared
byte for byte.  Printed per format and path: wall and CPU seconds (median) and the peak RSS (wait4's
``ru_maxrss``), and µs per row.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

LAUNCH = (
    "import sys; sys.argv[0] = 'trackside'\n"
    "from console.cli.commands import query\n"
    "query.ARROW_AFTER_ROWS = int(sys.argv.pop(1))\n"
    "from console.cli.app import run\n"
    "run()\n"
)


def _run(first_rows: int, archive: Path, sql: str, fmt: str) -> tuple[float, float, int, str, int]:
    """(wall s, CPU s, peak RSS MB, output's SHA-256, output's lines) of one run."""
    args = [sys.executable, "-c", LAUNCH, str(first_rows), "query", sql, "--archive", str(archive), "--format", fmt]
    digest = hashlib.sha256()
    lines = 0
    start = time.perf_counter()
    p = subprocess.Popen(args, stdout=subprocess.PIPE)
    assert p.stdout is not None
    for block in iter(lambda: p.stdout.read(1 << 20), b""):  # type: ignore[union-attr]
        digest.update(block)
        lines += block.count(b"\n")
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - start
    if status:
        raise SystemExit(f"query exited with {status}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss // 1024, digest.hexdigest(), lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("archive", type=Path)
    ap.add_argument("--sql", default="SELECT * FROM records")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--formats", default="csv,jsonl")
    a = ap.parse_args()
    paths = {"by column (now)": 5_000, "by value (before)": 1 << 62}
    print(f"# {' '.join(sys.argv)}")
    print(f"# load average {os.getloadavg()[0]:.1f}")
    for fmt in a.formats.split(","):
        got: dict[str, list[tuple[float, float, int, str, int]]] = {name: [] for name in paths}
        for _ in range(a.rounds):
            for name, first in paths.items():
                got[name].append(_run(first, a.archive, a.sql, fmt))
        digests = {r[3] for runs in got.values() for r in runs}
        rows = got["by column (now)"][0][4] - (1 if fmt == "csv" else 0)
        print(f"\n{fmt}: {rows:,} rows, outputs {'identical' if len(digests) == 1 else 'DIFFER'}")
        print("| path | wall s | CPU s | peak MB | CPU µs/row |")
        print("|---|---:|---:|---:|---:|")
        for name, runs in got.items():
            wall = statistics.median(r[0] for r in runs)
            cpu = statistics.median(r[1] for r in runs)
            peak = max(r[2] for r in runs)
            print(f"| {name} | {wall:.2f} | {cpu:.2f} | {peak} | {cpu / max(rows, 1) * 1e6:.2f} |")


if __name__ == "__main__":
    main()
