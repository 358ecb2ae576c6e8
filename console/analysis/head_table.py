"""The counting heads of a diagnostic read, by head key, held as columns.

A head key numbers the (device id, counting head name) pairs of a log in
the order their first register appeared.  A log where every record names
its own head has as many heads as lines, so the heads are two numpy columns
(device id, code of the name in the registry's head dictionary), not a
list of tuples; a head is a ``(device_id, name)`` tuple only when asked
for, and faces that need many names take them in one go (:meth:`names`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import overload

import numpy as np

from parsers.dictionary import StringDictionary

Heads = Sequence[tuple[int, str]]


class HeadTable(Sequence[tuple[int, str]]):
    """(device id, counting head name) per head key: a read-only view over the registry's columns."""

    def __init__(self, device_id: np.ndarray, name_code: np.ndarray, names: StringDictionary) -> None:
        self.device_id = device_id
        self.name_code = name_code
        self._names = names

    def __len__(self) -> int:
        return len(self.device_id)

    @overload
    def __getitem__(self, key: int) -> tuple[int, str]: ...
    @overload
    def __getitem__(self, key: slice) -> list[tuple[int, str]]: ...
    def __getitem__(self, key: int | slice) -> tuple[int, str] | list[tuple[int, str]]:
        if isinstance(key, slice):
            keys = np.arange(len(self))[key]
            return list(zip(self.device_id[keys].tolist(), self.names(keys), strict=True))
        return int(self.device_id[key]), self._names.value(int(self.name_code[key]))

    def __iter__(self) -> Iterator[tuple[int, str]]:
        return iter(zip(self.device_id.tolist(), self.names(), strict=True))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, HeadTable):
            return (
                len(self) == len(other)
                and bool((self.device_id == other.device_id).all())
                and (self.names() == other.names())
            )
        if isinstance(other, Sequence):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other, strict=True))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]  # mutable-sized view: not hashable, as a list

    def __repr__(self) -> str:
        shown = ", ".join(map(repr, self[:3]))
        return f"HeadTable([{shown}{', …' if len(self) > 3 else ''}], {len(self)} heads)"

    def names(self, keys: np.ndarray | None = None) -> list[str]:
        """The names of the heads at ``keys`` (all heads by default), as a list."""
        codes = self.name_code if keys is None else self.name_code[np.asarray(keys, np.int64)]
        return self._names.take(codes)

    def devices(self, keys: np.ndarray) -> np.ndarray:
        """The device ids (int64) of the heads at ``keys``."""
        return self.device_id[np.asarray(keys, np.int64)].astype(np.int64)


def head_names(heads: Heads) -> list[str]:
    """Every head's name, by head key."""
    return heads.names() if isinstance(heads, HeadTable) else [name for _, name in heads]


def heads_at(heads: Heads, keys: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """(device ids as int64, names) of the heads at ``keys``: only those heads are looked at."""
    keys = np.asarray(keys, np.int64)
    if isinstance(heads, HeadTable):
        return heads.devices(keys), heads.names(keys)
    picked = [heads[k] for k in keys.tolist()]
    return np.array([h[0] for h in picked], dtype=np.int64), [h[1] for h in picked]


class HeadNames(Sequence[str]):
    """Head key → name, read from the heads last given (:meth:`follow`): an event stream's names
    without a Python string per head held (a log may name a million heads)."""

    def __init__(self) -> None:
        self._heads: Heads = ()

    def follow(self, heads: Heads) -> None:
        """The read's heads so far (keys only ever added): the longer of these and the ones held."""
        if len(heads) > len(self._heads):
            self._heads = heads

    def __len__(self) -> int:
        return len(self._heads)

    @overload
    def __getitem__(self, key: int) -> str: ...
    @overload
    def __getitem__(self, key: slice) -> list[str]: ...
    def __getitem__(self, key: int | slice) -> str | list[str]:
        if isinstance(key, slice):
            return [name for _, name in self._heads[key]]
        return self._heads[key][1]

    def take(self, keys: np.ndarray) -> list[str]:
        """The names of the heads at ``keys``, in one go."""
        return heads_at(self._heads, keys)[1]


def by_head_then_time(heads: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The order of ``np.lexsort((t, heads))``, and heads and times in it.

    Within one head, records (and onsets) mostly come in time order: a stable sort by head alone (a radix
    sort while head keys fit 16 bits) then already has each head's times sorted, at a fraction of lexsort's
    cost.
    Checked, and lexsort where it does not hold.
    """
    if len(heads) and int(heads.max()) < 1 << 16 and int(heads.min()) >= 0:
        order = np.argsort(heads.astype(np.uint16), kind="stable")
        hs, ts = heads[order], t[order]
        if bool(((ts[1:] >= ts[:-1]) | (hs[1:] != hs[:-1])).all()):
            return order, hs, ts
    order = np.lexsort((t, heads))
    return order, heads[order], t[order]
