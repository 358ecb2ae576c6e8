"""An axle is stored under its passage's day, however the pipeline's rows fall into the sink's calls.

The local engine feeds one pipeline with every head; the Dask engine one per group of heads, in other
batches.  An axle's day was taken from the passages of the call that wrote it: an axle stamped at its
passage's start (a whole-second head's first axle is) went to the head's previous passage, and an axle whose
passage came in an earlier call to another head's or a later passage.  After a grown file made the groups
again, one engine put an axle on another day than the other.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pytest

from console.analysis.passages.passage_frame import PASSAGE_COLUMNS
from console.archive.derive_sink import ArchiveSink
from parsers.units import NS_PER_DAY

DAY = 20_514  # 2026-03-02, days since 1970
HEADS = [(5001, "WS2"), (5002, "WS1")]


def _at(day: int, hms: str) -> int:
    h, m, s = (float(x) for x in hms.split(":"))
    return int(day * NS_PER_DAY + round((h * 3600 + m * 60 + s) * 1e9))


def _passages(rows: list[tuple[int, int]]) -> dict[str, Any]:
    """Passages (head key, start ns) with every column the sink writes (the rest zero)."""
    n = len(rows)
    cols: dict[str, Any] = {c: np.zeros(n) for c in PASSAGE_COLUMNS[2:]}
    for c in ("direction", "whole_train_basis", "kind"):
        cols[c] = np.zeros(n, np.int64)
    cols["head"] = np.array([h for h, _ in rows], np.int64)
    cols["start_ns"] = np.array([t for _, t in rows], np.int64)
    cols["axle_speeds_start"] = cols["axle_speeds_stop"] = np.zeros(n, np.int64)
    cols["axle_speeds_kmh"] = np.zeros(0)
    return cols


def _axles(rows: list[tuple[int, int]]) -> dict[str, Any]:
    return {"head": np.array([h for h, _ in rows], np.int64), "time_ns": np.array([t for _, t in rows], np.int64)}


class _Rows:
    """A part writer that keeps what it is given: (time ns, day) per row."""

    def __init__(self) -> None:
        self.rows: list[tuple[int, int]] = []

    def add(self, table: pa.Table, day: np.ndarray, *_: Any) -> None:
        times = table.column("time").to_numpy().astype(np.int64) if "time" in table.column_names else None
        if times is not None:
            self.rows += list(zip(times.tolist(), np.asarray(day).tolist(), strict=True))

    def closes_day(self, watermark_ns: int) -> bool:
        return True  # every call's batch written at once: the finest batching the sink can make

    def advance(self, watermark_ns: int) -> None:
        pass  # files are closed by time: nothing kept here is a file

    def close(self) -> list[str]:
        return []


def _axle_days(
    tmp_path: Path, calls: list[tuple[list[tuple[int, int]], list[tuple[int, int]]]]
) -> list[tuple[int, int]]:
    """(axle time, day stored) for the axles and passages given to the sink in ``calls``, in time order."""
    sink = ArchiveSink(tmp_path, 1, "d")
    sink.writers["axles"] = sink.writers["passages"] = written = _Rows()  # type: ignore[assignment]
    for axles, passages in calls:
        sink.axles(_axles(axles), HEADS)
        sink.passages(_passages(passages), HEADS)
    sink.close()  # the tables are made a batch of calls at a time
    return sorted(r for r in written.rows if r[0] in {t for axles, _ in calls for _, t in axles})


# A passage of head 0 over midnight (A), the head's next at 00:00:34 sharp (B, whole seconds: its first axle
# stamped at its start), and head 1's passages.
A, B = _at(DAY - 1, "23:59:40"), _at(DAY, "00:00:34")
A_AXLES = [(0, A), (0, _at(DAY - 1, "23:59:59.5")), (0, _at(DAY, "00:00:05"))]
B_AXLES = [(0, B), (0, B + 1_000_000_000)]
OTHER = [(1, _at(DAY - 1, "22:00:00")), (1, _at(DAY, "00:00:20"))]
WANT = [(t, DAY - 1) for _, t in A_AXLES] + [(t, DAY) for _, t in B_AXLES]


@pytest.mark.parametrize(
    "calls",
    [
        [(A_AXLES + B_AXLES, [(0, A), (0, B), *OTHER])],  # one batch (the local engine's, say)
        [(A_AXLES, [(0, A), OTHER[0]]), (B_AXLES, [(0, B), OTHER[1]])],  # each passage with its axles
        [(A_AXLES[:2], [(0, A)]), (A_AXLES[2:] + B_AXLES, [(0, B)])],  # A's last axle after A was written
        [(A_AXLES[:2], [(0, A)]), (A_AXLES[2:], [OTHER[1]]), (B_AXLES, [(0, B)])],  # ... with another head's
    ],
    ids=["one call", "passage by passage", "axle after its passage", "axle with another head's passage"],
)
def test_an_axle_is_on_its_passages_day_however_the_calls_fall(tmp_path: Path, calls: Any) -> None:
    assert _axle_days(tmp_path, calls) == WANT
