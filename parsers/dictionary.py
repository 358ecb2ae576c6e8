"""Distinct strings → dense ids, held flat: no Python object per entry.

A log of a million counting heads has a million distinct register spans and
head names.  A ``dict`` keyed by them costs some 250 bytes an entry (the
key object, its hash slot, the id's int), more than the log line the entry
came from.  Here each entry is a 128-bit BLAKE2b digest of its bytes in
numpy runs sorted by the digest's high half (16 bytes, plus 4 for its id),
and a :class:`StringDictionary` keeps its strings as one UTF-8 buffer with
offsets, as Arrow does.

The digest stands for the bytes: two different strings share one with
probability 2^-128 per pair, and a cryptographic hash cannot be steered to a
collision by a crafted log.  Lookups are vectorized (``np.searchsorted``
per run); a new run is merged into the one before it once that is no more
than twice its size, so there are O(log n) runs and each entry is merged
O(log n) times.  A small, bounded ``dict`` in front answers the few thousand
strings a realistic log repeats in every chunk without hashing them again.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pyarrow as pa

# The front cache's size: a realistic log's distinct spans fit (a few thousand); an
# adversarial one's do not, and the cache is cleared when full (bounded: a cache, not a store).
FRONT_CACHE_MAX = 32_768
_DIGEST_BYTES = 16


def digests(keys: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """(high, low) 64-bit halves of each key's 128-bit BLAKE2b digest."""
    if not keys:
        return np.zeros(0, np.uint64), np.zeros(0, np.uint64)
    blake = hashlib.blake2b
    raw = b"".join([blake(k, digest_size=_DIGEST_BYTES).digest() for k in keys])
    both = np.frombuffer(raw, "<u8").reshape(-1, 2)
    return both[:, 0].copy(), both[:, 1].copy()


class _Run:
    """Digests sorted by their high half (entries sharing one are told apart by the low half) with their ids."""

    __slots__ = ("hi", "ids", "lo", "shared_hi")

    def __init__(self, hi: np.ndarray, lo: np.ndarray, ids: np.ndarray) -> None:
        self.hi, self.lo, self.ids = hi, lo, ids
        # Entries sharing a high half: about one pair in 10^7 at a million entries (none for exact keys).
        self.shared_hi = bool(len(hi) > 1 and (hi[1:] == hi[:-1]).any())

    @classmethod
    def sorted(cls, hi: np.ndarray, lo: np.ndarray, ids: np.ndarray) -> _Run:
        order = np.argsort(hi, kind="stable")
        return cls(hi[order], lo[order], ids[order])

    @classmethod
    def merged(cls, a: _Run, b: _Run) -> _Run:
        """Two runs as one, merged in place of a sort: each entry of ``b`` goes after the entries of ``a``
        not above it; the new arrays are the only copies made."""
        at_b = np.searchsorted(a.hi, b.hi, "right") + np.arange(len(b.hi))
        from_b = np.zeros(len(a.hi) + len(b.hi), bool)
        from_b[at_b] = True
        out = []
        for x, y in ((a.hi, b.hi), (a.lo, b.lo), (a.ids, b.ids)):
            col = np.empty(len(from_b), x.dtype)
            col[at_b] = y
            col[~from_b] = x
            out.append(col)
        return cls(*out)

    def find(self, hi: np.ndarray, lo: np.ndarray, out: np.ndarray) -> None:
        """Write the id of each digest found here into ``out``."""
        if not len(self.hi) or not len(hi):
            return
        left = np.searchsorted(self.hi, hi, "left")
        at = np.minimum(left, len(self.hi) - 1)
        hit = (self.hi[at] == hi) & (self.lo[at] == lo)
        out[hit] = self.ids[at[hit]]
        if self.shared_hi:
            # The first entry of a shared high half may not be the one: look at the others by hand.
            right = np.searchsorted(self.hi, hi, "right")
            for q in np.flatnonzero(((right - left) > 1) & ~hit).tolist():
                for k in range(int(left[q]) + 1, int(right[q])):
                    if self.lo[k] == lo[q]:
                        out[q] = self.ids[k]


class DigestIndex:
    """128-bit digests (or any distinct 128-bit keys, as two uint64 halves) → int32 ids, in sorted runs
    (see the module docstring)."""

    def __init__(self) -> None:
        self._runs: list[_Run] = []
        self._n = 0

    def __len__(self) -> int:
        return self._n

    def get(self, hi: np.ndarray, lo: np.ndarray) -> np.ndarray:
        """The id of each digest, -1 where absent."""
        out = np.full(len(hi), -1, np.int32)
        for run in self._runs:
            run.find(hi, lo, out)
        return out

    def add(self, hi: np.ndarray, lo: np.ndarray, ids: np.ndarray) -> None:
        """Add digests (absent so far, distinct) with their ids."""
        if not len(hi):
            return
        self._runs.append(_Run.sorted(hi, lo, ids.astype(np.int32, copy=False)))
        self._n += len(hi)
        while len(self._runs) > 1 and len(self._runs[-2].hi) <= 2 * len(self._runs[-1].hi):
            b, a = self._runs.pop(), self._runs.pop()
            self._runs.append(_Run.merged(a, b))


class Growable:
    """A numpy column appended to in place (capacity grows by half); ``view()`` is its filled part."""

    __slots__ = ("data", "n")

    def __init__(self, dtype: type | str) -> None:
        self.data = np.zeros(16, dtype)
        self.n = 0

    def extend(self, values: np.ndarray) -> None:
        need = self.n + len(values)
        if need > len(self.data):
            # Views handed out keep the old buffer, whose filled part never changes.
            grown = np.zeros(max(need, len(self.data) * 3 // 2), self.data.dtype)
            grown[: self.n] = self.data[: self.n]
            self.data = grown
        self.data[self.n : need] = values
        self.n = need

    def view(self) -> np.ndarray:
        return self.data[: self.n]


class StringDictionary:
    """Strings → dense codes in order of first sight, with the strings kept as one UTF-8 buffer.

    ``code``/``codes`` intern; :attr:`values` (a list, built on demand) and
    :meth:`arrow` give them back.  Strings that are not valid Unicode (lone
    surrogates from undecodable file names) are stored with ``surrogatepass``
    and come back unchanged.
    """

    def __init__(self) -> None:
        self._index: DigestIndex | None = DigestIndex()
        self._front: dict[str, int] = {}
        self._text = bytearray()
        self._offsets = Growable(np.int64)
        self._offsets.extend(np.zeros(1, np.int64))
        self._values: list[str] = []  # decoded on demand, for the few callers that want a list
        self._surrogates = False  # some string is not valid Unicode: not one for Arrow

    def __len__(self) -> int:
        return self._offsets.n - 1

    def code(self, value: str) -> int:
        """The code of one string (a new code for a new string)."""
        found = self._front.get(value)
        if found is not None:
            return found
        return int(self.codes([value])[0])

    def freeze(self) -> None:
        """No more strings will be interned: drop the lookup (its digests weigh about as much as the
        strings); :meth:`value`, :meth:`take` and :meth:`arrow` still read them, ``code(s)`` then raise."""
        self._index = None
        self._front = {}

    def codes(self, values: Sequence[str]) -> np.ndarray:
        """Codes of many strings at once (int32), new strings numbered in order of first sight."""
        index = self._index
        if index is None:
            raise RuntimeError("StringDictionary frozen: no more strings can be interned")
        front = self._front
        got = [front.get(v) for v in values]
        if None not in got:
            return np.array(got, np.int32)
        # Distinct missed strings, in order of first sight.
        distinct = list(dict.fromkeys([v for v, g in zip(values, got, strict=True) if g is None]))
        try:
            encoded = [v.encode("utf-8") for v in distinct]
        except UnicodeEncodeError:  # a lone surrogate (an undecodable byte of a file name)
            encoded = [v.encode("utf-8", "surrogatepass") for v in distinct]
            self._surrogates = True
        hi, lo = digests(encoded)
        ids = index.get(hi, lo)
        new = np.flatnonzero(ids < 0)
        if len(new):
            ids[new] = len(self) + np.arange(len(new), dtype=np.int32)
            index.add(hi[new], lo[new], ids[new])
            new_bytes = [encoded[k] for k in new.tolist()]
            lengths = np.fromiter(map(len, new_bytes), np.int64, len(new_bytes))
            self._offsets.extend(len(self._text) + np.cumsum(lengths))
            self._text += b"".join(new_bytes)
        found = dict(zip(distinct, ids.tolist(), strict=True))
        if len(front) + len(found) > FRONT_CACHE_MAX:
            front.clear()
        if len(found) <= FRONT_CACHE_MAX:  # more at once: new strings, not the ones a log repeats
            front.update(found)
        return np.array([found[v] if g is None else g for v, g in zip(values, got, strict=True)], np.int32)

    def value(self, code: int) -> str:
        """The string of one code."""
        at = self._offsets.data
        return self._text[at[code] : at[code + 1]].decode("utf-8", "surrogatepass")

    @property
    def values(self) -> list[str]:
        """All strings, by code: a list kept and extended, for the small dictionaries read often
        (a large one is better read with :meth:`take`)."""
        if len(self._values) < len(self):
            self._values += self.take(np.arange(len(self._values), len(self)))
        return self._values

    def take(self, codes: np.ndarray) -> list[str]:
        """The strings of ``codes``, as a new list."""
        codes = np.asarray(codes, np.int64)
        if len(codes) >= 4096 and 8 * len(codes) >= len(self._text) and not self._surrogates:
            # Many: Arrow makes the strings (no Python int per offset).  Its numpy conversion is the
            # faster but imports pandas, which a JSON-only command never loads: only if it is loaded
            # (and the indices are handed over as a buffer: pa.array would look for pandas too).
            import pyarrow as pa

            indices = pa.Array.from_buffers(pa.int64(), len(codes), [None, pa.py_buffer(codes)])
            taken = self.arrow().take(indices)
            if "pandas" in sys.modules:
                return list(taken.to_numpy(zero_copy_only=False).tolist())
            return list(taken.to_pylist())
        at = self._offsets.data
        buf = self._text
        return [
            buf[a:b].decode("utf-8", "surrogatepass")
            for a, b in zip(at[codes].tolist(), at[codes + 1].tolist(), strict=True)
        ]

    def binary(self) -> pa.Array:
        """All strings, by code, as their UTF-8 bytes (``surrogatepass``) in an Arrow large_binary array.

        Byte order there is the strings' code-point order (Python's ``<``), lone surrogates included:
        sorting it sorts the strings without making them."""
        import pyarrow as pa

        n = len(self)
        offsets = self._offsets.data[: n + 1]
        return pa.Array.from_buffers(
            pa.large_binary(), n, [None, pa.py_buffer(offsets.copy()), pa.py_buffer(bytes(self._text))]
        )

    def arrow(self) -> pa.Array:
        """All strings, by code, as an Arrow large_string array over one copy of the buffer.

        A string that is not valid Unicode (a lone surrogate) is not valid UTF-8 there: callers
        needing those use :meth:`take`."""
        import pyarrow as pa  # loaded by the callers that want Arrow (a small GNSS read needs none)

        n = len(self)
        offsets = self._offsets.data[: n + 1]
        return pa.Array.from_buffers(
            pa.large_utf8(), n, [None, pa.py_buffer(offsets.copy()), pa.py_buffer(bytes(self._text))]
        )
