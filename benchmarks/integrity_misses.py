"""Why partings reported through the brake pipe were not "parted" within 2 report periods + latency.

Runs the parted runs of ``N`` runs of :mod:`console.sim.integrity_runs` from ``SEED`` (the sweep's
runs: ``benchmarks/integrity_sweep.py N --seed SEED --kind parted`` has the same ones) and sorts
each brake-pipe run outside the target by what its inputs held by the deadline (the parting + 2
report periods + latency), first cause first:

* ``vent late``: the vent reached the EOT unit later than the target allows;
* ``rear lost or late``: no vented rear reading nor emergency status arrived by the deadline;
* ``no front in time``: no head reading measured after the rear's vent (less the pipe's
  travel from the cab) arrived by the deadline;
* ``front vented``: every such front reading was below charged (the cab braking too);
* ``clock allowance``: both arrived, but the rule asks the front reading to be measured after the vent
  by the units' clock allowance and the pressure's fall time as well: how far past the target
  each was parted is listed.

    python benchmarks/integrity_misses.py 1500 --seed 4646
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict

import numpy as np
from rich.progress import track

from console.analysis.integrity.brake_pipe import CHARGED_BAR, FASTEST_WAVE_MPS, VENTED_BAR
from console.sim.integrity_runs import (
    EOT,
    HEAD,
    RunResult,
    judge,
    line_layout,
    make_train,
    random_conditions,
    simulate,
)
from parsers.units import NS


def cause(res: RunResult, vent_late: bool) -> str:
    c, tp = res.cond, res.truth.parting_ns
    assert tp is not None
    deadline = tp + int((2 * c.period_s + c.latency_s) * NS)
    if vent_late:
        return "vent late"
    rear = [(rx, it) for rx, kind, it in res.items if kind == 2 and it[0] == EOT and rx >= tp]
    vented = [(rx, it) for rx, it in rear if it[2] < VENTED_BAR or it[3] > 0]
    if not vented or vented[0][0] > deadline:
        return "rear lost or late"
    t_vent = vented[0][1][1]
    # A cab emergency left the cab by then, at the latest.
    earliest = t_vent - int(make_train(c.consist).length_m / FASTEST_WAVE_MPS * NS)
    front = [it for rx, kind, it in res.items if kind == 2 and it[0] == HEAD and it[1] >= earliest and rx <= deadline]
    if not front:
        return "no front in time"
    if all(it[2] < CHARGED_BAR for it in front):
        return "front vented"
    return "clock allowance"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", type=int)
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args()
    print("$ python " + " ".join(sys.argv), file=sys.stderr)
    lay = line_layout()
    rng = np.random.default_rng(args.seed)
    causes: dict[str, Counter[str]] = defaultdict(Counter)
    past_s: dict[str, list[float]] = defaultdict(list)
    for k in track(range(args.runs), description="runs", transient=True):
        res = simulate(lay, random_conditions(rng, args.seed * 1_000_003 + k, "parted"))
        v = judge(res)
        if not res.cond.brake_pipe or res.truth.parting_ns is None:
            continue
        rate = f"{1 / res.cond.period_s:g} Hz"
        causes[rate]["partings"] += 1
        if v.within_target:
            causes[rate]["within"] += 1
            continue
        why = cause(res, v.vent_late)
        causes[rate][why] += 1
        if why == "clock allowance" and v.detected_s is not None:
            past_s[rate].append(round(v.detected_s - (2 * res.cond.period_s + res.cond.latency_s), 2))
    rates = sorted(causes, key=lambda r: -float(r.split()[0]))  # the fastest first, as the sweep
    out = {r: {**dict(causes[r]), "clock allowance, s past the target": sorted(past_s[r])} for r in rates}
    print(json.dumps({"seed": args.seed, "runs": args.runs, "brake_pipe_partings": out}, indent=1))


if __name__ == "__main__":
    main()
