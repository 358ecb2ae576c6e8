"""Many simulated heads, some wearing, for the forecast's benchmark and its tests.

:func:`plan` lays out ``n_drift`` drifting heads and ``n_healthy`` healthy ones on a long line (every
head with the layout's analog band, ±48 counts around its level, eight heads to a device), and gives
each drifting head one slow fault at a rate drawn around the kind's default (× 0.5 … 1.5) that has
run for ``history`` days (drawn in [14, 21]) when the run ends.  Half drift their analog value, half
grow their disturbance rate, on a channel drawn at random.  :func:`score` compares a forecast's
JSON with the run's ``truth.json``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

import numpy as np

from console.sim.slow_faults import DEFAULT_RATES

BAND_HALF = 48.0  # the band the health rule would learn around 2400 (± 2 %)
HEADS_PER_DEVICE = 8
SPACING_M = 500.0


@dataclass(frozen=True)
class Plan:
    layout_toml: str
    faults: list[str]  # --fault arguments
    drifting: list[str]
    healthy: list[str]
    days: float


def head_name(i: int) -> str:
    return f"H{i + 1:03d}"


def layout_toml(n_heads: int, seed: int, bands: bool = True, heads_per_device: int = HEADS_PER_DEVICE) -> str:
    """``bands``: each head's analog band in the layout (else the forecast learns it, as the health rule does)."""
    rng = np.random.default_rng([seed, 1])
    levels = np.round(2400 + rng.normal(0, 15, n_heads))
    length = (n_heads + 1) * SPACING_M
    lines = [
        "[line]",
        f'name = "Forecast benchmark line, {n_heads} heads"',
        "speed_mps = 20.0",
        "",
        "[[consists]]",
        'id = "tram3"',
        "axles_m = [0.0, 1.8, 8.5, 10.3, 18.3, 20.1, 26.8, 28.6]",
        "",
    ]
    for k, x in enumerate((0.0, length)):
        lines += ["[[track]]", f"chainage_m = {x:.0f}", "lat = 20.75", f"lon = {105.9 + k * length / 104_000:.6f}", ""]
    for i in range(n_heads):
        lo, hi = levels[i] - BAND_HALF, levels[i] + BAND_HALF
        lines += [
            "[[heads]]",
            f'id = "{head_name(i)}"',
            f"device_id = {5001 + i // heads_per_device}",
            f"chainage_m = {(i + 1) * SPACING_M:.0f}",
            "spacing_m = 0.13",
            *([f"analog_band = [{lo:.0f}, {hi:.0f}]"] if bands else []),
            "",
        ]
    return "\n".join(lines)


def plan(
    n_drift: int,
    n_healthy: int,
    days: float,
    seed: int = 1,
    bands: bool = True,
    heads_per_device: int = HEADS_PER_DEVICE,
) -> Plan:
    """The layout and the faults (see the module's doc)."""
    rng = np.random.default_rng([seed, 2])
    n = n_drift + n_healthy
    order = rng.permutation(n)  # drifting and healthy heads mixed along the line and on the devices
    drifting = sorted(head_name(int(i)) for i in order[:n_drift])
    healthy = sorted(head_name(int(i)) for i in order[n_drift:])
    faults = []
    for k, head in enumerate(drifting):
        kind = "analog_drift" if k % 2 == 0 else "disturbance_growth"
        rate = DEFAULT_RATES[kind] * float(rng.uniform(0.5, 1.5))
        history = float(rng.uniform(14.0, min(21.0, days)))
        start_s = round((days - history) * 86_400.0)
        channel = int(rng.integers(1, 3))
        faults.append(f"{kind}:{head}:{start_s}s::{channel}:{rate:.4f}")
    return Plan(layout_toml(n, seed, bands, heads_per_device), faults, drifting, healthy, days)


def _t(text: str | None) -> float | None:
    if text is None:
        return None
    return dt.datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp()


def score(truth: dict[str, Any], forecast: dict[str, Any], p: Plan) -> dict[str, Any]:
    """Accuracy on the drifting series, due calls on the healthy heads, and past heads never called healthy."""
    end = _t(truth["end"])
    assert end is not None
    got = {(f["target"], f["channel"], f["figure"]): f for f in forecast["forecasts"]}
    errors: list[float] = []
    past_errors: list[float] = []
    missing = 0
    past_not_due: list[str] = []
    for c in truth["threshold_crossings"]:
        f = got.get((c["target"], c["channel"], c["figure"]))
        t_true = _t(c["time"])
        if f is None or t_true is None:
            missing += 1
            continue
        t_fc = _t(f["crossing"])
        err = (t_fc - t_true) / 86_400.0 if t_fc is not None else float("inf")
        (past_errors if t_true <= end else errors).append(err)
        if t_true <= end and f["status"] not in ("past", "due"):
            past_not_due.append(f"{c['target']} {c['figure']} Sys{c['channel']}: {f['status']}")
    all_err = np.abs(np.array(errors + past_errors))
    healthy = set(p.healthy)
    due_healthy = sorted(
        {f["target"] for f in forecast["forecasts"] if f["target"] in healthy and f["status"] in ("past", "due")}
    )
    return {
        "drifting_series": len(truth["threshold_crossings"]),
        "missing": missing,
        "within_3_days": float(np.mean(all_err <= 3.0)) if len(all_err) else None,
        "future_crossings": len(errors),
        "future_within_3_days": float(np.mean(np.abs(errors) <= 3.0)) if errors else None,
        "past_crossings": len(past_errors),
        "past_within_3_days": float(np.mean(np.abs(past_errors) <= 3.0)) if past_errors else None,
        "median_abs_error_days": float(np.median(all_err)) if len(all_err) else None,
        "p90_abs_error_days": float(np.quantile(all_err, 0.9)) if len(all_err) else None,
        "healthy_heads": len(healthy),
        "healthy_called_due": due_healthy,
        "healthy_due_share": len(due_healthy) / len(healthy) if healthy else None,
        "past_not_called_due": past_not_due,
    }
