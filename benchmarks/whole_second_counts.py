"""Axle counts per time resolution against the generator's truth.

python benchmarks/gen_realistic_diag.py 200000 /tmp/real.log --truth /tmp/real.truth.json
python benchmarks/whole_second_counts.py /tmp/real.log /tmp/real.truth.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from console.drivers.batch import ReadOptions, read_diag  # noqa: E402
from console.engine.pipeline import PipelineSettings  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", type=Path, nargs="+")
    ap.add_argument("--truth", type=Path, required=True)
    a = ap.parse_args(argv)
    truth = json.loads(a.truth.read_text(encoding="utf-8"))
    res_of = {h: b["resolution"] for b in truth["boards"] for h in b["heads"]}
    t0 = time.perf_counter()
    job = read_diag(a.logs, PipelineSettings(), opts=ReadOptions(hold_passages=True))
    elapsed = time.perf_counter() - t0
    counted: Counter[str] = Counter()
    trains: Counter[str] = Counter()
    for p in job.analysis.passages_json():
        counted[p["counting_head"]] += p["axles"]
        trains[p["counting_head"]] += p["kind"] == "train"
    true_trains = Counter(truth["passages_per_head"])
    rows: dict[str, list[int]] = {}
    for head, n_true in truth["axles_per_head"].items():
        r = rows.setdefault(res_of[head], [0, 0, 0, 0, 0, 0])
        r[0] += 1
        r[1] += n_true
        r[2] += counted[head]
        r[3] += counted[head] == n_true
        r[4] += true_trains[head]
        r[5] += trains[head]
    rep = job.report
    print(f"records {rep.records:,}  rejected {rep.rejected}  lines {rep.lines_read:,}  analysed in {elapsed:.1f} s")
    print(
        "| resolution | heads | axles (truth) | axles counted | share | heads exact"
        " | passages (truth) | train passages |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for res in ("us", "ms", "s"):
        if res in rows:
            h, t, c, ex, pt, pc = rows[res]
            print(f"| {res} | {h} | {t:,} | {c:,} | {c / t:.1%} | {ex}/{h} | {pt:,} | {pc:,} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
