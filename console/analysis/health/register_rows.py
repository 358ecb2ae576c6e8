"""The records of one health register, as the rules read them: plain-string heads, times in ns."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from parsers.units import NS as NS_PER_S

if TYPE_CHECKING:
    import pandas as pd

NS_PER_H = 3600 * NS_PER_S


def times_ns(times: pd.Series) -> np.ndarray:
    return times.to_numpy(dtype="datetime64[ns]").view(np.int64)


def register_records(records: pd.DataFrame, canonical: str, extra: tuple[str, ...] = ()) -> pd.DataFrame:
    """Records of one register, with a plain-string head, in the table's (read) order."""
    import pandas as pd  # deferred: the report path reads its inputs before pandas is needed (memory)

    picked = records.loc[records["label_canonical"] == canonical, ["time", "counting_head", "channel", "value", *extra]]
    return pd.DataFrame(
        {
            "time_ns": times_ns(picked["time"]),
            "head": picked["counting_head"].astype(str).to_numpy(),
            "channel": picked["channel"].to_numpy(dtype=np.int64),
            "value": picked["value"].to_numpy(dtype=np.float64),
            **{c: picked[c].to_numpy() for c in extra},
        }
    )


def register_rows(records: pd.DataFrame, canonical: str, extra: tuple[str, ...] = ()) -> pd.DataFrame:
    """Records of one register, with a plain-string head, sorted by head, channel, time."""
    out = register_records(records, canonical, extra)
    return out.sort_values(["head", "channel", *extra, "time_ns"], kind="stable").reset_index(drop=True)
