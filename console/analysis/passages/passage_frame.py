"""The passages table as a DataFrame: :func:`passages_frame` turns the numpy columns (codes) into it,
:func:`frame_columns` turns it back for the byte encoders."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from console.analysis.counting.wheels import DIRECTION_12, DIRECTION_21
from console.analysis.head_table import Heads, heads_at
from console.analysis.passages.buckets import Columns

if TYPE_CHECKING:
    import pandas as pd

PASSAGE_BASES = (None, "detections", "records")
PASSAGE_DIRECTIONS = (None, DIRECTION_12, DIRECTION_21, "mixed")  # the direction codes 0, 1, 2, 3
PASSAGE_KINDS = ("train", "damping", "status")


def passages_frame(cols: Columns | None, heads: Heads) -> pd.DataFrame:
    """The passages table (:data:`PASSAGE_COLUMNS`) from :func:`.passage_columns.passage_columns`' columns."""
    import pandas as pd

    if cols is None:
        return pd.DataFrame(columns=list(PASSAGE_COLUMNS))
    # Only the heads of these passages are looked up: a log may have a million heads.
    used, inverse = np.unique(cols["head"], return_inverse=True)
    used_dev, used_names = heads_at(heads, used)
    head_name = np.empty(len(used), dtype=object)
    head_name[:] = used_names
    text = {
        "counting_head": head_name[inverse.reshape(-1)],
        "direction": np.array(PASSAGE_DIRECTIONS, dtype=object)[cols["direction"]],
        "whole_train_basis": np.array(PASSAGE_BASES, dtype=object)[cols["whole_train_basis"]],
        "kind": np.array(PASSAGE_KINDS, dtype=object)[cols["kind"]],
    }
    data = {"device_id": used_dev[inverse.reshape(-1)], **{c: text.get(c, cols.get(c)) for c in PASSAGE_COLUMNS[1:]}}
    out = pd.DataFrame(data)
    out.attrs["axle_speeds_kmh"] = cols["axle_speeds_kmh"]
    return out


PASSAGE_COLUMNS = (
    "device_id",
    "counting_head",
    "start_ns",
    "end_ns",
    "duration_s",
    "records",
    "detections_sys1",
    "detections_sys2",
    "axles",
    "direction",
    "detection_second_ns",
    "records_in_detection_second",
    "speed_kmh_per_second_method",
    "speed_kmh_whole_train",
    "speed_kmh_whole_train_min",
    "speed_kmh_whole_train_max",
    "whole_train_basis",
    "whole_train_duration_s",
    "axle_speeds_start",
    "axle_speeds_stop",
    "speed_kmh_per_axle_mean",
    "subsecond",
    "time_resolution_s",
    "kind",
)


def frame_columns(p: pd.DataFrame) -> tuple[Columns, list[tuple[int, str]]] | None:
    """The columns and heads :func:`passages_frame` makes ``p`` of (its rows in its order), for the
    byte encoders; None where a value has no such form (a null head, count or flag, a text with no code)."""
    import pandas as pd

    ints = ("start_ns", "end_ns", "records", "detections_sys1", "detections_sys2", "axles")
    if any(p[c].dtype.kind not in "iu" for c in (*ints, "device_id", "axle_speeds_start", "axle_speeds_stop")):
        return None
    if p["subsecond"].dtype.kind != "b" or p["counting_head"].isna().any():
        return None
    dev_code, devs = pd.factorize(p["device_id"].to_numpy(np.int64))
    name_code, names = pd.factorize(p["counting_head"])
    if not all(isinstance(n, str) for n in names):
        return None
    head, pairs = pd.factorize(dev_code.astype(np.int64) * max(len(names), 1) + name_code)
    heads = [(int(devs[k // len(names)]), str(names[k % len(names)])) for k in pairs.tolist()]
    cols: Columns = {"head": head.astype(np.int64)}
    for c in PASSAGE_COLUMNS[2:]:
        if c in ("direction", "whole_train_basis", "kind"):
            values = {"direction": PASSAGE_DIRECTIONS, "whole_train_basis": PASSAGE_BASES, "kind": PASSAGE_KINDS}[c]
            known = [v for v in values if v is not None]
            code = pd.Index(known).get_indexer(pd.Index(p[c].to_numpy(object))).astype(np.int8)  # -1: null, unknown
            if values[0] is None:
                if ((code < 0) != p[c].isna().to_numpy()).any():
                    return None
                code = code + 1
            elif (code < 0).any():
                return None
            cols[c] = code
        else:
            cols[c] = p[c].to_numpy()
    cols["axle_speeds_kmh"] = np.asarray(p.attrs.get("axle_speeds_kmh", np.zeros(0)), np.float64)
    return cols, heads
