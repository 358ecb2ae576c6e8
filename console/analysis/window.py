"""The last few items of a stream, in a list: what ``deque(maxlen=n)`` keeps, at a tenth of its memory for a few.

A deque holds its items in blocks of 64 slots, about 600 bytes however few
it keeps.  The live crossing units and the integrity monitor keep a dozen
windows of 3 to 25 items for every train (every unit heard is a train): as
deques, about 15 KB a unit for the run.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import TypeVar, overload

T = TypeVar("T")


class Window(Sequence[T]):
    """The last ``maxlen`` items appended, oldest first."""

    __slots__ = ("_items", "maxlen")

    def __init__(self, maxlen: int) -> None:
        if maxlen < 1:
            raise ValueError("a window keeps at least one item")
        self.maxlen = maxlen
        self._items: list[T] = []

    def append(self, item: T) -> None:
        items = self._items
        items.append(item)
        if len(items) > self.maxlen:
            del items[0]  # a few items: cheaper than a deque's block

    def clear(self) -> None:
        self._items.clear()

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[T]:
        return iter(self._items)

    @overload
    def __getitem__(self, i: int) -> T: ...
    @overload
    def __getitem__(self, i: slice) -> list[T]: ...
    def __getitem__(self, i: int | slice) -> T | list[T]:
        return self._items[i]

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Window) and self.maxlen == other.maxlen and self._items == other._items

    __hash__ = None  # type: ignore[assignment]  # mutable

    def __repr__(self) -> str:
        return f"Window({self._items!r}, maxlen={self.maxlen})"
