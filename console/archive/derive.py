"""Derived tables: what the batch analyses compute on the archive's inputs read together.

The tables are written from :func:`console.archive.history.report_data`,
which calls the same analysis functions ``trackside report`` calls on the
files, so a derived table cannot drift from the batch result: passages,
axles, section states, the count ledger, health findings and crossing
timelines.  Every ingest that adds something recomputes them over the whole
archive (state that straddles an ingest boundary — a passage, an occupied
section — is then carried by construction); recomputing only the affected
heads and days is the planned optimisation, see docs/archive.md.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from console.archive.parts import write_small
from console.archive.store import Manifest

DERIVED = ("passages", "axles", "section_states", "count_ledger", "crossing_timelines", "health_findings")


def _arrow(df: pd.DataFrame) -> pa.Table:
    df = df.copy()
    df.attrs = {}  # per-axle speed lists of passages: not a column, not archived
    for c in df.columns:
        if df[c].dtype == object and df[c].isna().all():
            # No value at all: the column still gets its type (numbers for units, text otherwise).
            df[c] = df[c].astype("float64" if c.endswith(("_s", "_ns", "_m", "_kmh")) else "string")
        elif df[c].dtype == object:
            df[c] = df[c].map(
                lambda v: None if v is None else v if isinstance(v, str | int | float | bool | dt.date) else str(v)
            )
    return pa.Table.from_pandas(df, preserve_index=False)


def tables_from(data: Any) -> dict[str, pd.DataFrame]:
    """The derived tables of one ReportData, as DataFrames (times as ns integers and timestamps)."""
    out: dict[str, pd.DataFrame] = {}
    job = data.job
    if job is not None:
        p = job.analysis.passages.copy()
        p["start"] = pd.to_datetime(p["start_ns"], unit="ns")
        out["passages"] = p
        ax = job.analysis.axles.copy()
        heads = job.analysis.heads
        if len(ax):
            ax["device_id"] = np.array([h[0] for h in heads], np.int64)[ax["head"].to_numpy()]
            ax["counting_head"] = np.array([h[1] for h in heads], object)[ax["head"].to_numpy()]
        else:
            ax["device_id"] = pd.Series(dtype="int64")
            ax["counting_head"] = pd.Series(dtype=object)
        ax["time"] = pd.to_datetime(ax["time_ns"], unit="ns")
        out["axles"] = ax.drop(columns=["head"])
    if data.sections is not None:
        tl = data.sections.timeline.copy()
        tl["time"] = pd.to_datetime(tl["time_ns"], unit="ns")
        out["section_states"] = tl
        led = data.sections.ledger.copy()
        led["time"] = pd.to_datetime(led["time_ns"], unit="ns")
        out["count_ledger"] = led
    if data.findings:
        out["health_findings"] = pd.DataFrame([f.to_dict() for f in data.findings])
    if data.crossing is not None and data.crossing.timelines:
        rows = []
        for r in data.crossing.timelines:
            d = dict(r.__dict__)
            d["alarms"] = "; ".join(r.alarms)
            d["violations"] = "; ".join(r.violations)
            late_by = d.get("late_by_s")
            d["late"] = bool(r.violations) or (late_by is not None and late_by > 0)
            rows.append(d)
        ct = pd.DataFrame(rows)
        for c in ("t_on_ns", "t_head_arrival_ns", "t_tail_clear_ns", "t_off_ns", "baseline_off_ns"):
            ct[c] = ct[c].astype("Int64")
            ct[c.replace("_ns", "")] = pd.to_datetime(ct[c], unit="ns")
        out["crossing_timelines"] = ct
    return out


def derive_tables(root: Path, manifest: Manifest, layout: str | None) -> list[str]:
    """Recompute every derived table into new parts of ``manifest`` (not yet published); the parts written."""
    from console.archive.history import report_data

    spec = layout if layout is not None else manifest.derived.get("layout")
    manifest.derived = {"layout": spec, "tables": list(DERIVED)}
    data = report_data(root, spec, manifest=manifest)
    frames = tables_from(data)
    gen = manifest.generation
    written: list[str] = []
    for name in DERIVED:
        manifest.tables[name] = []
        df = frames.get(name)
        if df is None or df.empty:
            continue
        time_col = {"passages": "start_ns", "axles": "time_ns", "section_states": "time_ns", "count_ledger": "time_ns"}
        if name in time_col:
            # One part per table, in time order with a day column: derived tables are rewritten whole
            # at each ingest, and a part per day and device would be thousands of tiny files.
            df = df.sort_values(time_col[name], kind="stable")
            df["day"] = pd.to_datetime(df[time_col[name]], unit="ns").dt.date
        rel = write_small(root, name, gen, "d", _arrow(df))
        parts = [rel] if rel else []
        manifest.tables[name] = parts
        written += parts
    return written
