"""The parsed records: :class:`DiagChunk` batches keyed into a registry, and the record table built from them.

:class:`DiagChunk` is what :class:`parsers.diag.read.DiagReader` yields, a fact table of ids into its
:class:`~parsers.diag.registry.DiagRegistry`; :func:`chunks_to_frame` joins chunks with their registry into
one DataFrame of the documented columns (:data:`RECORD_COLUMNS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from parsers.diag.fields import DATA_KINDS
from parsers.diag.registry import DiagRegistry
from parsers.report import escape_name

if TYPE_CHECKING:
    import pandas as pd


@dataclass
class DiagChunk:
    """Parsed records of one chunk: a fact table keyed into a DiagRegistry."""

    file_id: int
    register_id: np.ndarray  # int32
    time_ns: np.ndarray  # int64, ns since epoch (log local time, naive)
    subsecond: np.ndarray  # bool: the time carried a fraction
    value: np.ndarray  # int64
    data_code: np.ndarray  # int32
    data_kind: np.ndarray  # int8
    line: np.ndarray  # int64, 1-based

    def __len__(self) -> int:
        return len(self.register_id)

    def take(self, mask: np.ndarray) -> DiagChunk:
        """The records where mask is true."""
        return DiagChunk(
            self.file_id,
            self.register_id[mask],
            self.time_ns[mask],
            self.subsecond[mask],
            self.value[mask],
            self.data_code[mask],
            self.data_kind[mask],
            self.line[mask],
        )


RECORD_COLUMNS = (
    "time",
    "diag_id",
    "device_id",
    "device",
    "type",
    "gs",
    "counting_head",
    "channel",
    "address",
    "label",
    "label_canonical",
    "data",
    "value",
    "data_kind",
    "subsecond",
    "file",
    "line",
)


def _utf8_name(value: str) -> str:
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        return escape_name(value)
    return value


def _categorical(codes: np.ndarray, values: list[str]) -> pd.Categorical:
    import pandas as pd

    # Arrow strings are UTF-8: a file name that is not (surrogateescape) is stored as shown, ``\xff``.
    cats = pd.Index([_utf8_name(v) for v in values], dtype=pd.StringDtype("pyarrow"))
    return pd.Categorical.from_codes(codes, categories=cats, validate=False)


def _present_heads(codes: np.ndarray, registry: DiagRegistry) -> pd.Categorical:
    """The head column with only the heads its records name as categories (in the registry's order)."""
    import pandas as pd

    codes = np.asarray(codes).ravel()
    present = np.unique(codes[codes >= 0])
    at = np.where(codes >= 0, np.searchsorted(present, codes), -1).astype(np.int32)  # -1: no head, as given
    cats = pd.Index([_utf8_name(v) for v in registry.heads.take(present)], dtype=pd.StringDtype("pyarrow"))
    return pd.Categorical.from_codes(at, categories=cats, validate=False)


def chunks_to_frame(chunks: list[DiagChunk], registry: DiagRegistry, all_heads: bool = True) -> pd.DataFrame:
    """One DataFrame (the documented record table) from parsed chunks.

    ``all_heads``: the head column's categories are every head of the registry; without, only the heads
    the chunks' records name (a few registers kept from a log that names a million heads)."""
    import pandas as pd

    rid = np.concatenate([c.register_id for c in chunks]) if chunks else np.zeros(0, np.int32)

    def cat(name: str) -> np.ndarray:
        return np.concatenate([getattr(c, name) for c in chunks]) if chunks else np.zeros(0)

    arrays = registry.arrays() if registry.n_registers else None

    def reg(name: str, dtype: str) -> np.ndarray:
        if arrays is None:
            return np.zeros(0, dtype=dtype)
        return arrays[name][rid]

    file_codes = (
        np.concatenate([np.full(len(c), c.file_id, np.int32) for c in chunks]) if chunks else np.zeros(0, np.int32)
    )
    canon = registry.canonicals.values
    frame = pd.DataFrame(
        {
            "time": pd.to_datetime(cat("time_ns").astype(np.int64), unit="ns"),
            "diag_id": reg("diag_id", "int32"),
            "device_id": reg("device_id", "int32"),
            "device": _categorical(reg("device", "int32"), registry.devices.values),
            "type": _categorical(reg("type", "int32"), registry.types.values),
            "gs": _categorical(reg("gs", "int32"), registry.gs.values),
            # All head names, not kept as a list by the registry (a log may name a million heads).
            "counting_head": _categorical(
                reg("counting_head", "int32"), registry.heads.take(np.arange(len(registry.heads)))
            )
            if all_heads
            else _present_heads(reg("counting_head", "int32"), registry),
            "channel": reg("channel", "int8"),
            "address": reg("address", "int32").astype(np.int16),
            "label": _categorical(reg("label", "int32"), registry.labels.values),
            "label_canonical": _categorical(reg("label_canonical", "int32"), canon),
            "data": _categorical(cat("data_code").astype(np.int32), registry.data.values),
            "value": cat("value").astype(np.int64),
            "data_kind": _categorical(cat("data_kind").astype(np.int32), list(DATA_KINDS)),
            "subsecond": cat("subsecond").astype(bool),
            "file": _categorical(file_codes, registry.files),
            "line": cat("line").astype(np.int64),
        },
        columns=list(RECORD_COLUMNS),
    )
    # Empty labels carry no register name: missing, not the empty string.
    frame["label_canonical"] = (
        frame["label_canonical"].cat.remove_categories([""]) if "" in canon else frame["label_canonical"]
    )
    return frame
