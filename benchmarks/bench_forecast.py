"""Forecast accuracy on many simulated heads: simulate → ingest → forecast, against the run's truth.

Targets (issue 27), on ≥ 200 drifting and ≥ 200 healthy heads with ≥ 14 days of a drift's history:
the forecast crossing date within ±3 days of the truth for ≥ 90 % of the drifting heads; ≤ 2 % of the
healthy heads called due within the horizon (30 days); a head already past its threshold never called
healthy.  Every step is the real command (subprocess), timed::

    python -m benchmarks.bench_forecast /tmp/forecast-bench --drift 200 --healthy 200 --days 35
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

from benchmarks.forecast_heads import plan, score


def trackside(*args: str) -> list[str]:
    return [str(Path(sys.executable).with_name("trackside")), *args]


def timed(cmd: list[str], **kw: object) -> tuple[subprocess.CompletedProcess[str], float]:
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, check=False, **kw)  # type: ignore[call-overload]
    if res.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(cmd[:3])}…: exit {res.returncode}\n{res.stderr}")
    return res, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("work", type=Path, help="scratch directory (replaced)")
    ap.add_argument("--drift", type=int, default=200)
    ap.add_argument("--healthy", type=int, default=200)
    ap.add_argument("--days", type=float, default=35.0)
    ap.add_argument("--health-every", default="30m")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--learned-bands", action="store_true", help="no analog bands in the layout: learned from the log")
    args = ap.parse_args()
    print("command:", " ".join(sys.argv))
    shutil.rmtree(args.work, ignore_errors=True)
    args.work.mkdir(parents=True)
    p = plan(args.drift, args.healthy, args.days, args.seed, bands=not args.learned_bands)
    layout = args.work / "heads.toml"
    layout.write_text(p.layout_toml, encoding="utf-8")
    run, arc = args.work / "run", args.work / "archive"
    sim_args = ["simulate", "-o", str(run), "--layout", str(layout), "--days", str(args.days), "--health-only"]
    sim_args += ["--health-every", args.health_every, "--seed", str(args.seed), "--json"]
    for f in p.faults:
        sim_args += ["--fault", f]
    _, t_sim = timed(trackside(*sim_args))
    _, t_ingest = timed(trackside("ingest", str(run), "--archive", str(arc), "--layout", str(layout)))
    res, t_fc = timed(trackside("forecast", "--archive", str(arc), "--json"))
    forecast = json.loads(res.stdout)
    truth = json.loads((run / "truth.json").read_text(encoding="utf-8"))
    records = sum(1 for d in run.iterdir() if d.is_dir() for _ in (d / "diagnostic.log").open("rb"))
    result = {
        "heads": {"drifting": len(p.drifting), "healthy": len(p.healthy)},
        "days": args.days,
        "health_every": args.health_every,
        "bands": "learned" if args.learned_bands else "layout",
        "seed": args.seed,
        "records": records,
        "seconds": {"simulate": round(t_sim, 1), "ingest": round(t_ingest, 1), "forecast": round(t_fc, 1)},
        "counts": forecast["counts"],
        **score(truth, forecast, p),
    }
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
