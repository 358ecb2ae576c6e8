"""Events held until nothing read later can precede them, then released in the batch path's order.

What a heap of ``(time, head key, group, generation order)`` tuples did for
:class:`~console.analysis.sections.stream.EventStream`, on columns: each
block pushed is sorted once (``np.lexsort``) and kept as a sorted part;
releasing below a time cuts every part at that time (a binary search) and
merges the pieces by the same key.  Parts are merged as they pile up
(each at most half the one before it), so a bound that stays behind for
long (a head that stopped writing, with a power gap set) costs a few sorted
merges, not a scan per release.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from console.analysis.events.block import COLUMNS, EventBlock
from parsers.units import ALL_TIME


@dataclass
class _Part:
    events: EventBlock  # sorted by (time, key, group, seq)
    key: np.ndarray
    group: np.ndarray
    seq: np.ndarray

    def __len__(self) -> int:
        return len(self.events)

    def take(self, index: np.ndarray | slice) -> _Part:
        ix = np.arange(len(self))[index] if isinstance(index, slice) else index
        return _Part(self.events.take(ix), self.key[ix], self.group[ix], self.seq[ix])


def _joined(parts: list[_Part], get: Callable[[_Part], np.ndarray]) -> np.ndarray:
    return get(parts[0]) if len(parts) == 1 else np.concatenate([get(p) for p in parts])


def _sorted(parts: list[_Part], names: Sequence[str], pool: Sequence[str]) -> _Part:
    # Column by column: each is joined and put in order before the next is touched, so a merge of a
    # million events (a log's end with a million heads) never holds the joined block and the ordered
    # one whole at once.
    order = np.lexsort(
        (
            _joined(parts, lambda p: p.seq),
            _joined(parts, lambda p: p.group),
            _joined(parts, lambda p: p.key),
            _joined(parts, lambda p: p.events.time_ns),
        )
    )
    cols = {c: _joined(parts, lambda p, c=c: p.events.column(c))[order] for c in COLUMNS}  # type: ignore[misc]
    key = _joined(parts, lambda p: p.key)[order]
    group = _joined(parts, lambda p: p.group)[order]
    seq = _joined(parts, lambda p: p.seq)[order]
    return _Part(EventBlock.from_columns(cols, names, pool), key, group, seq)


class EventQueue:
    """Event blocks in, released below a bound in (time, key, group, generation order)."""

    def __init__(self, names: Sequence[str], pool: Sequence[str]) -> None:
        self.names, self.pool = names, pool
        self._parts: list[_Part] = []
        self._seq = 0

    def __len__(self) -> int:
        return sum(len(p) for p in self._parts)

    def push(self, block: EventBlock, key: np.ndarray, group: int) -> None:
        """A block in generation order, each event's sort key (head key) and the block's group."""
        n = len(block)
        if not n:
            return
        seq = np.arange(self._seq, self._seq + n, dtype=np.int64)
        self._seq += n
        part = _Part(block, np.asarray(key, np.int64), np.full(n, group, np.int64), seq)
        self._parts.append(_sorted([part], self.names, self.pool))
        parts = self._parts
        while len(parts) >= 2 and len(parts[-2]) <= 2 * len(parts[-1]):
            last = parts.pop()
            parts[-1] = _sorted([parts[-1], last], self.names, self.pool)

    def pop_below(self, bound: int) -> EventBlock:
        """Every event earlier than ``bound`` (all of them at ALL_TIME), in order."""
        out: list[_Part] = []
        kept: list[_Part] = []
        for p in self._parts:
            cut = len(p) if bound == ALL_TIME else int(np.searchsorted(p.events.time_ns, bound, side="left"))
            if cut:
                out.append(p.take(slice(0, cut)) if cut < len(p) else p)
            if cut < len(p):
                kept.append(p.take(slice(cut, None)) if cut else p)
        self._parts = kept
        if not out:
            return EventBlock.empty(self.names, self.pool)
        return (out[0] if len(out) == 1 else _sorted(out, self.names, self.pool)).events
