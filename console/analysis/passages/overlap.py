"""Overlap between files: the same records exported twice, counted once.

Inside one file nothing is ever deduplicated: the order of records is
evidence, and two identical lines are two events (a wheel crossing twice in
one whole second writes two identical lines).  Between files, a run of
identical records at the seam is one export pulled twice (the same export
twice, or two pulls with overlapping time ranges): the later file's copy of
the run is *overlap*, set aside and reported per file.

Per counting head, a later file B overlaps an earlier file A when

* B begins inside A: B's first records equal a run of A's records (B's copy
  of that run is overlap), or
* A begins inside B: A's first records equal a run in B (that run of B is
  overlap).

Records are compared by a 64-bit fingerprint of (time, register, value):
the register holds device, head, channel, address and label.  A run counts
only when it reaches the end of one of the two files (that is what a seam
is): a whole-second log repeats identical lines within a second as distinct
events, so a record of A that happens to equal one inside B is no overlap.
Where several runs qualify, the longest wins.

A run within a single instant is ambiguous on one head: a log cut in the
middle of a whole second (a rotation by size) ends A with a wheel's lines
and begins B with the next wheel's, the same lines at the same second.
Such a run counts only when the files repeat it as a whole: over all their
records (every head and board, in read order), B's beginning must repeat
A's end there too, or B must repeat A's beginning.  A repeated export
repeats every line in the order it wrote them; a cut does not, unless the
lines around it happen to repeat too (a file cut between two identical
wheels of the only head then writing: the same bytes either way).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

_MAX_CANDIDATES = 64  # identical records at one instant: a handful, not thousands
_M1 = np.uint64(0x9E3779B97F4A7C15)
_M2 = np.uint64(0xBF58476D1CE4E5B9)
_M3 = np.uint64(0x94D049BB133111EB)


def fingerprints(time_ns: np.ndarray, register_id: np.ndarray, value: np.ndarray) -> np.ndarray:
    """A 64-bit fingerprint per record (splitmix64 of its time, register and value)."""
    x = time_ns.astype(np.uint64) * _M1
    x ^= register_id.astype(np.uint64) * _M2 + value.astype(np.uint64) * _M3
    x ^= x >> np.uint64(30)
    x *= _M2
    x ^= x >> np.uint64(27)
    x *= _M3
    return x ^ (x >> np.uint64(31))


def _run(a: np.ndarray, b: np.ndarray) -> int:
    """Length of the common prefix of a and b."""
    n = min(len(a), len(b))
    diff = np.flatnonzero(a[:n] != b[:n])
    return int(diff[0]) if len(diff) else n


def _best_run(ref: np.ndarray, probe: np.ndarray) -> tuple[int, int]:
    """(start in ref, length) of the longest run of ref equal to all of probe's
    beginning that reaches the end of ref or of probe (a seam); (0, 0) if none."""
    if not len(ref) or not len(probe):
        return 0, 0
    cands = np.flatnonzero(ref == probe[0])
    best = (0, 0)
    for j in cands[-_MAX_CANDIDATES:].tolist():  # identical records: a few per instant
        n = _run(ref[j:], probe)
        seam = j + n == len(ref) or n == len(probe)
        if seam and n > best[1]:
            best = (j, n)
    return best


WholeFiles = Callable[[int, int], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


class _Corroboration:
    """Two files' seam runs over all their records (every head and board, in read order), once a pair."""

    def __init__(self, whole_files: WholeFiles) -> None:
        self.whole_files = whole_files
        self._pairs: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def holds(self, fa: int, fb: int, keys: np.ndarray, b_begins: bool) -> bool:
        """Whether the records ``keys`` (of file ``fb``) lie in the files' own seam run: B's beginning
        repeating A's end (``b_begins``), else the run of B repeating A's beginning."""
        if (fa, fb) not in self._pairs:
            _, fp_a, keys_b, fp_b = self.whole_files(fa, fb)
            _, n = _best_run(fp_a, fp_b)
            j, m = _best_run(fp_b, fp_a)
            self._pairs[fa, fb] = (keys_b[:n], keys_b[j : j + m])
        run = self._pairs[fa, fb][0 if b_begins else 1]
        return bool(np.isin(keys, run).all())


def overlap_mask(
    file: np.ndarray,
    head: np.ndarray,
    fp: np.ndarray,
    time_ns: np.ndarray,
    key: np.ndarray | None = None,
    whole_files: WholeFiles | None = None,
) -> np.ndarray:
    """Records (in read order) that repeat an earlier file's run at a seam.

    ``key`` names each record (default: its place in these arrays);
    ``whole_files(fa, fb)`` gives (keys, fingerprints) of every record of
    files ``fa`` and ``fb`` in read order (default: these arrays, which must
    then hold every record of the files).
    """
    n = len(fp)
    out = np.zeros(n, bool)
    if n == 0 or (file == file[0]).all():
        return out
    if whole_files is None:

        def whole_files(fa: int, fb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            in_a, in_b = np.flatnonzero(file == fa), np.flatnonzero(file == fb)
            named = (in_a, in_b) if key is None else (key[in_a], key[in_b])
            return named[0], fp[in_a], named[1], fp[in_b]

    order = np.lexsort((file, head))  # per head, files in read order, each in its own order
    h, f = head[order], file[order]
    cut = np.flatnonzero(np.r_[True, (h[1:] != h[:-1]) | (f[1:] != f[:-1]), True])
    groups: dict[int, list[tuple[int, np.ndarray]]] = {}
    for lo, hi in zip(cut[:-1].tolist(), cut[1:].tolist(), strict=True):  # per (head, file)
        groups.setdefault(int(h[lo]), []).append((int(f[lo]), order[lo:hi]))
    whole = _Corroboration(whole_files)

    def counts(fa: int, fb: int, records: np.ndarray, b_begins: bool) -> bool:
        if not len(records):
            return False
        t = time_ns[records]
        if t.min() != t.max():
            return True  # identical events share one instant: a run over several is a repeat
        return whole.holds(fa, fb, records if key is None else key[records], b_begins)

    for parts in groups.values():
        for k, (fb, later) in enumerate(parts):
            for fa, earlier in parts[:k]:
                pa, pb = fp[earlier], fp[later]
                # B begins inside A: B's first records are overlap.
                _, n_b = _best_run(pa, pb)
                if counts(fa, fb, later[:n_b], True):
                    out[later[:n_b]] = True
                # A begins inside B: the run of B equal to A's beginning is overlap.
                j, n_a = _best_run(pb, pa)
                if counts(fa, fb, later[j : j + n_a], False):
                    out[later[j : j + n_a]] = True
    return out
