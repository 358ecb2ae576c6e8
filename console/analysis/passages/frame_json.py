"""The passages table's documented JSON form through pandas' C encoder (null where unknown)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.passages.buckets import AXLES_UNKNOWN_REASONS, axles_unknown_codes
from console.analysis.timefmt import exact_ns, iso_array

if TYPE_CHECKING:
    import pandas as pd


def iso_strings(ns: pd.Series | np.ndarray) -> np.ndarray:
    """ISO 8601 strings in UTC with Z (:func:`timefmt.iso_array`: milliseconds at least), vectorized; None for NaN."""
    ints, ok = exact_ns(ns)
    out = iso_array(ints)
    out[~ok] = None
    return out


def axle_speed_lists(p: pd.DataFrame) -> list[list[float] | None]:
    """Per passage, its per-axle speeds (km/h, 3 decimals), or None without timing."""
    speeds = np.round(np.asarray(p.attrs.get("axle_speeds_kmh", np.zeros(0)), dtype=float), 3).tolist()
    starts = p["axle_speeds_start"].tolist()
    stops = p["axle_speeds_stop"].tolist()
    return [speeds[a:b] if b > a else None for a, b in zip(starts, stops, strict=True)]


def passages_json_text(p: pd.DataFrame) -> str:
    """The passages as a JSON array (C encoder: fast on 10⁵ passages)."""
    import pandas as pd

    if p.empty:
        return "[]"
    n_det = p["records_in_detection_second"].to_numpy(dtype=float)
    unknown = axles_unknown_codes(p["detections_sys1"], p["detections_sys2"])
    frame = pd.DataFrame(
        {
            "device_id": p["device_id"].to_numpy(np.int64),
            "counting_head": p["counting_head"].astype(object).to_numpy(),
            "start": iso_strings(p["start_ns"]),
            "end": iso_strings(p["end_ns"]),
            "duration_s": p["duration_s"].to_numpy(dtype=float).round(6),
            "records": p["records"].to_numpy(np.int64),
            "axles": p["axles"].to_numpy(np.int64),
            "axles_unknown_reason": np.array(AXLES_UNKNOWN_REASONS, dtype=object)[unknown],
            "detections_sys1": p["detections_sys1"].to_numpy(np.int64),
            "detections_sys2": p["detections_sys2"].to_numpy(np.int64),
            "direction": _objects(p["direction"]),
            "detection_second": iso_strings(p["detection_second_ns"]),
            "records_in_detection_second": pd.arrays.IntegerArray(
                np.nan_to_num(n_det).astype(np.int64), np.isnan(n_det)
            ),
            "speed_kmh_per_second_method": p["speed_kmh_per_second_method"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train": p["speed_kmh_whole_train"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train_min": p["speed_kmh_whole_train_min"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train_max": p["speed_kmh_whole_train_max"].to_numpy(dtype=float).round(3),
            "whole_train_basis": _objects(p["whole_train_basis"]),
            "whole_train_duration_s": p["whole_train_duration_s"].to_numpy(dtype=float).round(6),
            "speed_kmh_per_axle": axle_speed_lists(p),
            "speed_kmh_per_axle_mean": p["speed_kmh_per_axle_mean"].to_numpy(dtype=float).round(3),
            "subsecond": p["subsecond"].to_numpy(bool),
            "time_resolution_s": p["time_resolution_s"].to_numpy(dtype=float),
            "kind": _objects(p["kind"]),
        }
    )
    return frame.to_json(orient="records", force_ascii=True, double_precision=10)


def _objects(values: pd.Series) -> np.ndarray:
    # pandas 3 stores these as its string dtype, where missing reads as NaN.
    import pandas as pd

    out = values.astype(object).to_numpy().copy()
    out[pd.isna(values).to_numpy()] = None
    return out


def passages_to_json(p: pd.DataFrame) -> list[dict[str, Any]]:
    """The documented JSON form of the passages table (null where unknown)."""
    import json

    return list(json.loads(passages_json_text(p)))
