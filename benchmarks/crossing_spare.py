"""How early the crossing unit warns beyond what the evidence requires (issue 25).

Runs the randomized crossing harness (:mod:`console.sim.crossing_runs`) and
prints, per group of runs, the **avoidable spare**: the oracle's onset (the
unit's own bounds applied to the true motion) minus the controller's.  The
physics spare (the oracle's lead beyond the warning time) and the paper's
rule d/v ≤ T (Co Nhu Van, TCSJ 2026) against the same oracle stand beside it;
then the safety summary (violations, late warnings) and the road closure
after the tail cleared against the fixed-time baseline.

Targets over ≥ 3000 runs on a seed not tuned on, with 0 violations and 0 late
warnings: avoidable spare median ≤ 10 s and p95 ≤ 40 s overall; median
≤ 15 s without speed; median ≤ 10 s with fixes every 10 s.

    python benchmarks/crossing_spare.py --runs 3000 --seed SEED
"""

from __future__ import annotations

import argparse
import io
import sys
import time
from pathlib import Path

import numpy as np
from rich import box
from rich.console import Console
from rich.progress import track
from rich.table import Table

from console.layout import load_layout
from console.output_path import write_atomic
from console.sim.crossing_runs import (
    FIX_RATES,
    TUNE,
    RunConditions,
    Verdict,
    fix_rate,
    one_run,
    random_conditions,
    spare_table,
    summary,
)


def _f(x: float | None) -> str:
    return "–" if x is None else f"{x:.1f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=600)
    ap.add_argument("--seed", type=int, default=11, help="the harness seed (runs k use seed·100000 + k)")
    ap.add_argument("--set", action="append", default=[], help="NAME=VALUE: a controller setting under trial")
    ap.add_argument("--plot", type=Path, help="also draw the avoidable spare's distributions by fix rate (PNG)")
    args = ap.parse_args()
    for kv in args.set:
        name, _, value = kv.partition("=")
        TUNE[name] = int(value) if value.isdigit() else float(value)
    out = Console(highlight=False, width=320)
    out.print(f"$ python {' '.join(sys.argv)}", markup=False)
    layout = load_layout("example")
    t0 = time.perf_counter()
    # The same runs as many_runs(layout, runs, seed), one at a time for the progress bar.
    rng = np.random.default_rng(args.seed)
    results = []
    for k in track(range(args.runs), description="harness", console=out, transient=True):
        crossing = layout.crossings[k % len(layout.crossings)]
        cond = random_conditions(rng, args.seed * 100_000 + k)
        results.append((cond, one_run(layout, crossing, cond)))
    wall = time.perf_counter() - t0
    rows = spare_table(results)
    t = Table(box=box.MARKDOWN, title=None)
    cols: tuple[str, ...] = (
        "case",
        "runs",
        "avoidable median",
        "avoidable p95",
        "fix-time oracle median",
        "fix-time oracle p95",
    )
    cols += ("exact positions median", "exact positions p95", "noise allowance median", "noise allowance p95")
    cols += ("estimate median", "estimate p95", "physics median", "paper rule median", "paper rule late")
    for c in cols:
        t.add_column(c, justify="left" if c == "case" else "right", no_wrap=True)
    for r in rows:
        t.add_row(
            r.case,
            str(r.runs),
            _f(r.median_s),
            _f(r.p95_s),
            _f(r.sparse_median_s),
            _f(r.sparse_p95_s),
            _f(r.exact_median_s),
            _f(r.exact_p95_s),
            _f(r.allowance_median_s),
            _f(r.allowance_p95_s),
            _f(r.estimation_median_s),
            _f(r.estimation_p95_s),
            _f(r.physics_median_s),
            _f(r.paper_median_s),
            str(r.paper_late),
        )
    out.print(t)
    s = summary(results)
    keys = (
        "runs",
        "violations",
        "late_warnings",
        "held_on",
        "min_lead_minus_warning_time_s",
        "min_oracle_lead_minus_warning_time_s",
        "median_avoidable_spare_s",
        "p95_avoidable_spare_s",
        "median_physics_spare_s",
        "median_abs_error_hindsight_physics_s",
        "runs_released",
        "median_released_on_s",
        "runs_reopened_under_10s",
        "median_excess_s",
        "p95_excess_s",
        "baseline_early_runs",
        "baseline_max_early_s",
    )
    for key in keys:
        out.print(f"{key}: {s[key]}", markup=False)
    neg = [r.avoidable_s for _, r in results if r.avoidable_s is not None and r.avoidable_s < 0]
    out.print(f"runs warned later than the oracle: {len(neg)} (least {min(neg, default=0):.1f} s)", markup=False)
    # The fix-time oracle knows the true state at every received fix and releases as the unit does:
    # where its own avoidable spare exceeds 40 s in more than 5 % of runs, no unit warning on these
    # fixes without flicker can meet p95 ≤ 40 s (the unit's bounds are at or before the truth).
    fix_spare = [x for _, r in results if (x := r.sparse_s) is not None]
    over = sum(x > 40 for x in fix_spare)
    share = over / max(1, len(fix_spare))
    out.print(f"fix-time oracle avoidable spare > 40 s: {over} of {len(fix_spare)} runs ({share:.1%})", markup=False)
    est = [x for _, r in results if (x := r.estimation_s) is not None]
    out.print(
        f"runs warned later than the fix-time oracle: {sum(x < 0 for x in est)} (least {min(est, default=0):.1f} s)",
        markup=False,
    )
    for name, attr in (
        ("exact-positions yardstick", "exact_lead_s"),
        ("noise-allowance yardstick", "allowance_lead_s"),
    ):
        diff = [r.lead_s - lead for _, r in results if r.lead_s is not None and (lead := getattr(r, attr)) is not None]
        out.print(
            f"runs warned later than the {name}: {sum(x < 0 for x in diff)} of {len(diff)}"
            f" (least {min(diff, default=0):.1f} s)",
            markup=False,
        )
    base = [r.baseline_early_s for _, r in results if r.baseline_early_s is not None]
    out.print(f"fixed-time baseline: opened early in {sum(b > 0 for b in base)} runs", markup=False)
    out.print(f"wall {wall:.0f} s ({wall / max(1, len(results)) * 1000:.0f} ms a run)", markup=False)
    if args.plot is not None:
        write_atomic(args.plot, spare_plot_png(results, f"{args.runs} runs, seed {args.seed}"))
        out.print(f"plot: {args.plot}", markup=False)


def spare_plot_png(results: list[tuple[RunConditions, Verdict]], title: str) -> bytes:
    """The avoidable spare of the unit and of each yardstick as distributions, one panel per fix rate."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 3.6))
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(FIX_RATES), sharey=True)
    series = (
        ("the unit", "#1f4e79", lambda r: r.avoidable_s),
        ("fix-time oracle", "#2e7d32", lambda r: r.sparse_s),
        ("exact positions", "#ef6c00", lambda r: r.yardstick_avoidable_s(r.exact_lead_s)),
        ("noise allowance", "#8e24aa", lambda r: r.yardstick_avoidable_s(r.allowance_lead_s)),
    )
    for ax, rate in zip(axes, FIX_RATES, strict=True):
        runs = [r for c, r in results if fix_rate(c) == rate]
        for name, colour, value in series:
            xs = np.sort([x for r in runs if (x := value(r)) is not None])
            if len(xs):
                ax.step(
                    np.maximum(xs, 0.0),
                    np.arange(1, len(xs) + 1) / len(xs),
                    where="post",
                    color=colour,
                    lw=1.2,
                    label=f"{name} (median {np.median(xs):.1f} s)",
                )
        for target in (10.0, 40.0):
            ax.axvline(target, color="#9e9e9e", ls="--", lw=0.8)
        ax.set_xscale("symlog", linthresh=10.0)
        ax.set_xlim(0, 400)
        ax.set_title(f"fixes {rate} ({len(runs)} runs)", loc="left", fontsize=9)
        ax.set_xlabel("avoidable spare (s)")
        ax.grid(True, lw=0.3, color="#d0d7de")
        ax.legend(loc="lower right", fontsize=7, frameon=False)
    axes[0].set_ylabel("share of runs")
    fig.suptitle(
        f"How much earlier than the oracle each warned ({title}); dashed: the issue's 10 s and 40 s",
        fontsize=9,
        x=0.01,
        ha="left",
    )
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    return buf.getvalue()


if __name__ == "__main__":
    main()
