"""Passages of status records only: counted per head, not listed.

A board writes status dumps (identity, analog values, counters) whether or
not a train passes; each dump with no wheel onset becomes a passage of kind
``status``.  On a busy station they are most passages and most of the JSON,
and say little one by one, so by default they are summarised per counting
head (how many, how many records) and listed only on request.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np

from console.analysis.head_table import Heads, heads_at
from console.analysis.passages.buckets import Columns

_BLOCK = 4096
STATUS_KIND = 2  # passage_frame.PASSAGE_KINDS.index("status")


class StatusSummary:
    """Per head key: status-only passages and their records."""

    def __init__(self) -> None:
        # Counts with room beyond the heads seen (a log adding heads all the way copies them rarely);
        # :attr:`passages` and :attr:`records` are the part up to the last head with a status passage.
        self._counts = np.zeros((2, 0), np.int64)
        self._n = 0

    @property
    def passages(self) -> np.ndarray:
        return self._counts[0, : self._n]

    @property
    def records(self) -> np.ndarray:
        return self._counts[1, : self._n]

    def take(self, cols: Columns) -> Columns:
        """Count the status passages of ``cols``; the others, in order."""
        from console.analysis.passages.stream import take_passages

        status = cols["kind"] == STATUS_KIND
        if not status.any():
            return cols
        head = cols["head"][status]
        n = max(self._n, int(head.max()) + 1)
        if n > self._counts.shape[1]:
            grown = np.zeros((2, max(n, self._counts.shape[1] * 3 // 2)), np.int64)
            grown[:, : self._n] = self._counts[:, : self._n]
            self._counts = grown
        self._n = n
        np.add.at(self._counts[0], head, 1)
        np.add.at(self._counts[1], head, cols["records"][status])
        return take_passages(cols, np.flatnonzero(~status))

    def totals(self) -> dict[str, int]:
        return {"passages": int(self.passages.sum()), "records": int(self.records.sum())}

    def by_head(self, heads: Heads) -> Iterator[dict[str, Any]]:
        """Per head with status passages, in head order: made a block at a time (a log may have a
        status burst at each of a million heads)."""
        rows = np.flatnonzero(self.passages)
        for lo in range(0, len(rows), _BLOCK):
            keys = rows[lo : lo + _BLOCK]
            dev, names = heads_at(heads, keys)
            yield from (
                {"device_id": d, "counting_head": name, "passages": p, "records": r}
                for d, name, p, r in zip(
                    dev.tolist(), names, self.passages[keys].tolist(), self.records[keys].tolist(), strict=True
                )
            )

    def to_dict(self, heads: Heads) -> dict[str, Any]:
        return {**self.totals(), "by_head": list(self.by_head(heads))}
