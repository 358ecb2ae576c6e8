"""The items the sources' threads hand the engine's thread, bounded in bytes.

A followed file is read as fast as the disk gives it; the engine analyses
it more slowly.  Unbounded, the queue between them held most of a big file
followed from its start (``follow --from-start`` of a 407 MB log peaked at
490 MB).  Here a file's reader waits while more than
:data:`BACKLOG_BYTES` of what was read waits for the engine: the file keeps,
and memory no longer grows with the input.  A source on the network is never
held (its sender sets the rate; holding it would only lose its messages
elsewhere), and a source that is stopping is not held either: what it
still reads is analysed before the end, as before.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable

from console.inputs.base import Item, LineBlock, Source
from console.inputs.follow import FileSource

BACKLOG_BYTES = 16 << 20  # a few of the file reader's blocks: the engine never waits for the disk
ITEM_BYTES = 512  # an item other than a block of lines (a fix, a frame, a note), as counted here


def _weight(item: Item) -> int:
    return len(item.data) if isinstance(item, LineBlock) else ITEM_BYTES


class Backlog:
    """A queue of items: :meth:`putter` for each source's thread, :meth:`get` for the engine's."""

    def __init__(self, limit_bytes: int | None = None) -> None:
        self.limit_bytes = BACKLOG_BYTES if limit_bytes is None else limit_bytes
        self._q: queue.SimpleQueue[Item] = queue.SimpleQueue()
        self._bytes = 0
        self._room = threading.Condition()

    def putter(self, source: Source) -> Callable[[Item], None]:
        """How ``source`` hands its items over: a followed file's reader waits for room."""
        waits = isinstance(source, FileSource)

        def put(item: Item) -> None:
            w = _weight(item)
            with self._room:
                while waits and self._bytes > self.limit_bytes and not source.stopping:
                    self._room.wait(0.25)  # woken by the engine's get; the timeout sees a stop
                self._bytes += w
            self._q.put(item)

        return put

    def put(self, item: Item) -> None:
        """An item handed over by no source's thread (never held)."""
        with self._room:
            self._bytes += _weight(item)
        self._q.put(item)

    def get(self, timeout_s: float | None = None) -> Item:
        """The next item; ``queue.Empty`` if none came within ``timeout_s`` (None: none is there now)."""
        item = self._q.get_nowait() if timeout_s is None else self._q.get(timeout=timeout_s)
        with self._room:
            self._bytes -= _weight(item)
            if self._bytes <= self.limit_bytes:
                self._room.notify_all()
        return item

    def empty(self) -> bool:
        return self._q.empty()
