"""Train integrity against the truth over randomized runs: the figures of the issue's targets.

Runs ``N`` runs of :mod:`console.sim.integrity_runs` from ``SEED`` (the same
seed gives the same runs as ``TRACKSIDE_INTEGRITY_RUNS=N`` in
tests/test_integrity_runs.py, whose seed is 2026) and prints the summary as
JSON: partings missed and detected within 2 report periods + latency,
detection and doubt times by fix rate, false partings per 1,000 whole
train-hours, EOT losses reported as doubt.  The partings' figures are also
split: ``brake_pipe`` (units that report the brake pipe and the EOT's
emergency status, 70 % of the runs) and ``gnss_only`` (units that do not).

    python benchmarks/integrity_sweep.py 3000 --seed 2028
    python benchmarks/integrity_sweep.py 1000 --seed 2029 --kind whole   # more whole train-hours
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from rich.progress import Progress

from console.sim.integrity_runs import many_runs, summary


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", type=int)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--kind", choices=("parted", "whole", "eot_loss"), help="only runs of this kind")
    args = ap.parse_args()
    print("$ python " + " ".join(sys.argv), file=sys.stderr)
    t0 = time.perf_counter()
    with Progress(transient=True) as bar:
        task = bar.add_task("runs", total=args.runs)
        verdicts = many_runs(args.runs, args.seed, progress=lambda k: bar.update(task, completed=k), kind=args.kind)
    s = summary(verdicts)
    s["seed"] = args.seed
    s["elapsed_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(_no_nan(s), indent=1))


def _no_nan(x: object) -> object:
    """JSON has no NaN: a figure with no runs behind it is null."""
    if isinstance(x, dict):
        return {k: _no_nan(v) for k, v in x.items()}
    return None if isinstance(x, float) and x != x else x


if __name__ == "__main__":
    main()
