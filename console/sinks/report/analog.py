"""The analog receiver values (``analog_value`` registers) of a report's diagnostic logs: the series the plots
draw, and the document's table of them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from console.analysis.timefmt import iso
from console.sinks.report.model import ReportData

if TYPE_CHECKING:  # pandas is imported where it is used (see console.sinks.report.model)
    import pandas as pd


def _f(x: Any, digits: int = 3) -> float | None:
    """A finite float rounded for the document, else None."""
    if x is None:
        return None
    v = float(x)
    return None if not math.isfinite(v) else round(v, digits)


def analog_series(data: ReportData) -> pd.DataFrame:
    """The analog receiver values (``analog_value`` registers) as time_ns, head, channel, address, value."""
    import pandas as pd

    cols = ["time_ns", "head", "channel", "address", "value"]
    rec = data.job.records if data.job is not None else pd.DataFrame()
    if rec.empty or "label_canonical" not in rec.columns:
        return pd.DataFrame(columns=cols)
    pick = rec[rec["label_canonical"] == "analog_value"]
    return (
        pd.DataFrame(
            {
                "time_ns": pick["time"].to_numpy(dtype="datetime64[ns]").view(np.int64),
                "head": pick["counting_head"].astype(str).to_numpy(),
                "channel": pick["channel"].to_numpy(dtype=np.int64),
                "address": pick["address"].to_numpy(dtype=np.int64),
                "value": pick["value"].to_numpy(dtype=np.float64),
            },
            columns=cols,
        )
        .sort_values(["head", "channel", "address", "time_ns"], kind="stable")
        .reset_index(drop=True)
    )


def analog_table(data: ReportData) -> list[dict[str, Any]]:
    """Per head, channel and address: how many values, their min, mean and max, the first and the last."""
    if data.job is None or data.job.kept_nothing:
        return []  # no record kept: no table made
    series = analog_series(data)
    out = []
    for key, g in series.groupby(["head", "channel", "address"], sort=True):
        head, channel, address = cast(tuple[str, int, int], key)
        v = g["value"].to_numpy()
        out.append(
            {
                "counting_head": str(head),
                "channel": int(channel),
                "address": int(address),
                "values": len(v),
                "min": _f(v.min()),
                "mean": _f(v.mean()),
                "max": _f(v.max()),
                "first": iso(int(g["time_ns"].min())),
                "last": iso(int(g["time_ns"].max())),
            }
        )
    return out
