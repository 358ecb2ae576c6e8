"""Views of seed 001's ATO scenario: our figures beside the paper's, and speed against distance.

Every number comes from :func:`console.sim.ato.metrics`; the table, the JSON
and the plot only lay them out.  The plot is characters, readable without
colour (one letter per controller), and needs no terminal.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from rich import box
from rich.table import Table
from rich.text import Text

from console.sim.ato import PAPER_FIGURES, PAPER_WORDING, ScenarioResult, metrics
from console.sim.control import CONTROLLER_NAMES, FUZZY_D_READINGS

LABELS = {"pid": "PID", "fuzzy": "Fuzzy (SpeedT)", "fuzzy-d": "Fuzzy-D"}
MARKERS = {"pid": "P", "fuzzy": "F", "fuzzy-d": "D"}
STYLES = {"pid": "red", "fuzzy": "yellow", "fuzzy-d": "green"}
METRIC_KEYS = ("overshoot_pct", "distance_to_target_m", "steady_state_error_mps", "stop_error_m")
_FORMATS = {"steady_state_error_mps": "{:.3f}"}


def _fmt(key: str, value: float | None) -> Text:
    if value is None:
        return Text("never", style="dim")
    return Text(_FORMATS.get(key, "{:.1f}").format(value))


# How each reading of the seed's eq. 6 is labelled where Fuzzy-D is shown twice.
READING_LABELS = {"output-gain": "", "normalised": "  K normalised"}


def _reading_rank(r: ScenarioResult) -> int:
    return FUZZY_D_READINGS.index(r.reading) if r.reading in FUZZY_D_READINGS else 0


def _ordered(results: Sequence[ScenarioResult]) -> list[ScenarioResult]:
    rank = {n: i for i, n in enumerate(CONTROLLER_NAMES)}
    return sorted(results, key=lambda r: (rank.get(r.controller, len(rank)), _reading_rank(r), r.plant))


def ato_table(results: Sequence[ScenarioResult]) -> Table:
    """Per controller the paper's figures, then ours on each plant that was run (fits 80 columns)."""
    t = Table(
        title="ATO run: ours beside the paper's (Nguyen Van Tiem, TCSJ 2020, §4)",
        title_justify="left",
        title_style="bold",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        caption=(
            "force: our train model; linear: the paper's G(s). never: not within 2 % of 15 m/s before 900 m."
            " Fuzzy-D: u = K·U_Fuzzy + K_D·ė with U_Fuzzy on SpeedT's scale (the equations as printed);"
            " K normalised: U_Fuzzy in [−1, 1], K = 10 only rescales it, so K cancels (docs/ato.md)"
        ),
        caption_justify="left",
    )
    t.add_column("Controller", no_wrap=True)
    t.add_column("Source", no_wrap=True)
    for head in ("Overshoot %", "To 15 m/s m", "Steady m/s", "Stop err m"):
        t.add_column(head, justify="right", no_wrap=True)
    by_name: dict[str, list[ScenarioResult]] = {}
    for r in _ordered(results):
        by_name.setdefault(r.controller, []).append(r)
    for i, (name, runs) in enumerate(by_name.items()):
        paper = PAPER_FIGURES.get(name)
        label = LABELS.get(name, name)
        if paper is not None:
            t.add_row(label, Text("paper", style="dim"), *(_fmt(k, paper[k]) for k in METRIC_KEYS))
            label = ""
        reading = runs[0].reading
        for r in runs:
            if r.reading != reading:
                reading = r.reading
                label = READING_LABELS.get(r.reading, r.reading)
            m = metrics(r)
            t.add_row(label, r.plant, *(_fmt(k, m[k]) for k in METRIC_KEYS))
            label = ""
        if i < len(by_name) - 1:
            t.add_section()
    return t


def _metrics_json(r: ScenarioResult) -> dict[str, Any]:
    m = metrics(r)
    out: dict[str, Any] = {}
    for k in METRIC_KEYS:
        value = m[k]
        out[k] = None if value is None else round(value, 4)
    return out


def ato_json(results: Sequence[ScenarioResult]) -> list[dict[str, Any]]:
    """One object per controller and plant: our metrics (None where undefined), the paper's figures and words.

    Fuzzy-D's object is its first reading's run (the equations as printed when
    it was run); runs under the other readings of eq. 6 are listed in it under
    ``other_readings``, so there is one object per controller and plant.
    """
    out: list[dict[str, Any]] = []
    placed: dict[tuple[str, str], dict[str, Any]] = {}
    for r in _ordered(results):
        row = placed.get((r.controller, r.plant))
        if row is not None:
            row.setdefault("other_readings", []).append({"reading": r.reading, **_metrics_json(r)})
            continue
        paper: dict[str, Any] = dict(PAPER_FIGURES.get(r.controller, {}))
        if r.controller in PAPER_WORDING:
            paper["wording"] = PAPER_WORDING[r.controller]
        row = {"controller": r.controller, "plant": r.plant, "reading": r.reading or None, **_metrics_json(r)}
        row["paper"] = paper
        placed[(r.controller, r.plant)] = row
        out.append(row)
    return out


def ato_plot(results: Sequence[ScenarioResult], width: int = 80, height: int = 20, plant: str | None = None) -> Text:
    """Speed against distance, one letter per controller and dots for the target, on one plant.

    ``plant`` defaults to the first result's.  Where two controllers fall in
    the same cell the cell shows ``*``.
    """
    # One curve per controller: for Fuzzy-D the equations as printed when they were run, else its first reading.
    on_plant = plant or (results[0].plant if results else "")
    shown: dict[str, str] = {}
    for r in _ordered(results):
        if r.plant == on_plant:
            shown.setdefault(r.controller, r.reading)
    runs = [r for r in _ordered(results) if r.plant == on_plant and shown[r.controller] == r.reading]
    out = Text(no_wrap=True)
    if not runs:
        out.append("no runs to plot\n")
        return out
    margin = 6  # "15.0 |"
    cols = max(10, width - margin)
    rows = max(5, height)
    x_max = max(max(float(r.x_m[-1]) for r in runs), runs[0].stop_m)
    v_max = max(max(float(r.v_mps.max()), float(r.target_mps.max())) for r in runs) * 1.05 or 1.0
    centres = (np.arange(cols) + 0.5) * x_max / cols
    grid: list[list[str]] = [[" "] * cols for _ in range(rows)]
    style_at: dict[tuple[int, int], str] = {}

    def row_of(v: float) -> int:
        return min(rows - 1, max(0, round((rows - 1) * (1.0 - v / v_max))))

    def series(r: ScenarioResult, values: np.ndarray) -> np.ndarray:
        x = np.maximum.accumulate(r.x_m)  # a stopped train repeats x; interp needs it non-decreasing
        vals: np.ndarray = np.interp(centres, x, values, right=np.nan)
        return vals

    target = series(runs[0], runs[0].target_mps)
    for j, v in enumerate(target):
        if not np.isnan(v):
            grid[row_of(float(v))][j] = "·"
    for r in runs:
        mark = MARKERS.get(r.controller, r.controller[:1].upper())
        for j, v in enumerate(series(r, r.v_mps)):
            if np.isnan(v):
                continue
            i = row_of(float(v))
            cell = grid[i][j]
            grid[i][j] = mark if cell in (" ", "·", mark) else "*"
            style_at[(i, j)] = STYLES.get(r.controller, "") if grid[i][j] == mark else "bold"
    out.append(f"Speed (m/s) against distance (m), {runs[0].plant} plant\n", style="bold")
    for i in range(rows):
        v_label = v_max * (1.0 - i / (rows - 1))
        out.append(f"{v_label:4.1f} |" if i % 4 == 0 or i == rows - 1 else "     |")
        for j in range(cols):
            ch = grid[i][j]
            out.append(ch, style=style_at.get((i, j), "dim" if ch == "·" else ""))
        out.append("\n")
    axis = [" "] * cols
    ticks = [k * 500.0 for k in range(int(x_max // 500) + 1)]
    labels = [" "] * cols
    for x in ticks:
        j = min(cols - 1, int(x / x_max * cols))
        axis[j] = "+"
        s = f"{x:.0f}"
        start = min(max(0, j - len(s) // 2), cols - len(s))
        labels[start : start + len(s)] = list(s)
    out.append("     +" + "".join("-" if a == " " else a for a in axis) + "\n")
    out.append("      " + "".join(labels).rstrip() + "\n")
    legend = "  ".join(f"{MARKERS.get(r.controller, '?')} {LABELS.get(r.controller, r.controller)}" for r in runs)
    out.append(f"      {legend}  · target  * overlap\n")
    return out
