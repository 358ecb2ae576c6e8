"""Point mode's pairing (no release records) for :class:`~console.analysis.counting.bank.CounterBank`.

:class:`~console.analysis.counting.wheels.HeadCounter` keeps the onsets waiting for a
partner in a queue; they are all of one system (an onset of the other one
would have paired).  An onset first expires the waiting onsets more than a
window old, then takes the oldest waiting one of the other system, else
waits itself.  So the queue is first in, first out, and its length, signed
by its system, is the running sum of +1 per Sys1 and -1 per Sys2 onset
since it was last empty: within a stretch where that sum keeps its sign the
n-th onset that takes is paired with the n-th that waited.

Onsets more than a window after the one before start afresh (everything
waiting has expired), so such runs (clusters) are paired independently.
Pairing as if nothing expired is the rule's answer wherever every pair is
within the window (then nothing paired could have expired first, and what
is left over expires as it would have).  A cluster with a pair further
apart is paired onset by onset instead: that needs a lone onset amid close
ones, which is rare.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from console.analysis.counting.wheels import SYS1


def group_starts(keys: np.ndarray) -> np.ndarray:
    """Start positions of the runs of equal values in ``keys``."""
    return np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]]) if len(keys) else np.zeros(0, np.int64)


def _rank_in_group(mask: np.ndarray, group: np.ndarray) -> np.ndarray:
    """Per position, how many ``mask`` positions of its group come before it (groups contiguous, from 0)."""
    before = np.cumsum(mask) - mask
    return before - before[group_starts(group)][group]


def _one_by_one(
    t: np.ndarray, ch: np.ndarray, tol: np.ndarray, lo: int, hi: int
) -> tuple[list[int], list[int], list[int]]:
    """The queue rule over rows lo … hi - 1, an onset at a time: (pairs' first, second, left over)."""
    queue: deque[int] = deque()
    first: list[int] = []
    second: list[int] = []
    left: list[int] = []
    for r in range(lo, hi):  # per onset of a rare cluster
        while queue and t[queue[0]] + tol[r] < t[r]:
            left.append(queue.popleft())
        if queue and ch[queue[0]] != ch[r]:
            first.append(queue.popleft())
            second.append(r)
        else:
            queue.append(r)
    return first, second, [*left, *queue]


def pair_point_onsets(rows: dict[str, np.ndarray], tol: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Onset rows sorted by head, then queue order (``head``, ``time_ns``, ``channel``), each head's
    window ``tol``: (rows that waited, rows that took them: the pairs; rows never paired, in order)."""
    hd, t, ch = rows["head"], rows["time_ns"], rows["channel"]
    q = len(t)
    if q == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty, empty
    cluster_start = np.r_[True, (hd[1:] != hd[:-1]) | (t[1:] - t[:-1] > tol[1:])]
    cluster = np.cumsum(cluster_start) - 1
    sign = np.where(ch == SYS1, 1, -1)
    total = np.cumsum(sign)
    base = (total - sign)[cluster_start]
    waiting = total - sign - base[cluster]  # signed queue length before each onset
    waits = (waiting == 0) | (np.sign(waiting) == sign)
    stretch = np.cumsum(waiting == 0) - 1
    rank = np.where(waits, _rank_in_group(waits, stretch), _rank_in_group(~waits, stretch))
    w, k = np.flatnonzero(waits), np.flatnonzero(~waits)
    span = q + 1
    a = w[np.searchsorted(stretch[w] * span + rank[w], stretch[k] * span + rank[k])]
    b = k
    far = t[b] - t[a] > tol[b]
    if not far.any():
        paired = np.zeros(q, bool)
        paired[a] = True
        return a, b, np.flatnonzero(~paired & waits)
    bad = np.zeros(int(cluster[-1]) + 1, bool)
    bad[cluster[b[far]]] = True
    keep = ~bad[cluster[b]]
    a, b = a[keep], b[keep]
    paired = np.zeros(q, bool)
    paired[a] = True
    left = [np.flatnonzero(~paired & waits & ~bad[cluster])]
    starts = np.flatnonzero(cluster_start)
    ends = np.r_[starts[1:], q]
    fa, fb = [a], [b]
    for c in np.flatnonzero(bad).tolist():  # per cluster with a lone onset amid close ones: rare
        x, y, z = _one_by_one(t, ch, tol, int(starts[c]), int(ends[c]))
        fa.append(np.array(x, np.int64))
        fb.append(np.array(y, np.int64))
        left.append(np.array(z, np.int64))
    return np.concatenate(fa), np.concatenate(fb), np.sort(np.concatenate(left))
