"""What `trackside analyze` reports about a diagnostic log, held as numpy columns."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.counting.wheels import axles_frame
from console.analysis.head_table import Heads, head_names
from console.analysis.inventory import DeviceInventory
from console.analysis.passages.buckets import Columns
from console.analysis.passages.frame_json import passages_json_text
from console.analysis.passages.passage_frame import passages_frame
from console.analysis.passages.speed_settings import SpeedSettings

if TYPE_CHECKING:
    import pandas as pd


@dataclass
class DiagAnalysis:
    """Everything `trackside analyze` reports about a diagnostic log.

    The tables are held as numpy columns; the DataFrames (:attr:`passages`,
    :attr:`axles`, :attr:`wheel_records`, :attr:`activity`) are built on first
    use, so a face that only writes JSON never needs pandas.
    """

    settings: SpeedSettings
    devices: Sequence[DeviceInventory]
    passage_columns: Columns | None  # see passage_columns.passage_columns; None: no passages
    axle_columns: Columns
    overlap_records: int
    unpaired_detections: int
    # Per input file (in read order): its records set aside as another file's overlap.
    overlap_by_file: list[int] = field(default_factory=list)
    # For the section engine: heads as (device id, name), every wheel-sensor
    # record (head key, channel, time, 1/0), and per head the seconds with records.
    heads: Heads = field(default_factory=list)
    wheel_columns: Columns | None = None
    activity_columns: Columns | None = None
    # The times of the records set aside as overlap (the archive counts them per day).
    overlap_times_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def head_names(self) -> list[str]:
        """Every head's name, by head key."""
        return head_names(self.heads)

    @cached_property
    def passages(self) -> pd.DataFrame:
        return passages_frame(self.passage_columns, self.heads)

    @cached_property
    def axles(self) -> pd.DataFrame:
        return axles_frame(self.axle_columns)

    @cached_property
    def wheel_records(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.wheel_columns) if self.wheel_columns is not None else pd.DataFrame()

    @cached_property
    def activity(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.activity_columns) if self.activity_columns is not None else pd.DataFrame()

    def passages_json_text(self) -> str:
        """The passages as a JSON array, without pandas where the values allow."""
        from console.analysis.passages.json_text import encode_passages

        if self.passage_columns is None:
            return "[]"
        text = encode_passages(self.passage_columns, self.heads)
        return text if text is not None else passages_json_text(self.passages)

    def passages_json(self) -> list[dict[str, Any]]:
        import json

        return list(json.loads(self.passages_json_text()))

    def to_dict(self, passages: Any = None, devices: Any = None) -> dict[str, Any]:
        """The JSON document's analysis part; ``passages`` and ``devices`` may be pre-encoded text."""
        s = self.settings
        return {
            "settings": s.to_json(),
            "devices": [d.to_dict() for d in self.devices] if devices is None else devices,
            "passages": self.passages_json() if passages is None else passages,
            "overlap_records": self.overlap_records,
            "unpaired_detections": self.unpaired_detections,
        }
