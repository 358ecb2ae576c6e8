"""The items the sources' threads hand the engine's thread, bounded in bytes.

A followed file is read as fast as the disk gives it; the engine analyses
it more slowly.  Unbounded, the queue between them held most of a big file
followed from its start (``follow --from-start`` of a 407 MB log peaked at
490 MB).  Here a file's reader (and a pipe's: its writer then waits) waits while more than
:data:`BACKLOG_BYTES` of what was read waits for the engine: the file keeps,
and memory no longer grows with the input.  A source on the network is never
held (its sender sets the rate; holding it would only lose its messages
elsewhere).  A reader that is stopping is held too: ``follow`` drains the
backlog while its sources stop, so a big file read to its end on Ctrl-C
keeps memory as flat as the rest of the run.  A consumer that will take no
more (a second Ctrl-C, a closed station view) calls :meth:`Backlog.close`:
the readers are let go, and what they still hand over is dropped and
recorded (:meth:`Backlog.not_analysed`), never silently.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Sequence

from console.inputs.base import Item, LineBlock, Source

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
        self._closed = False
        self._dropped: dict[str, int] = {}  # a file (as its blocks name it) -> its first line dropped
        self._dropped_items = 0

    def putter(self, source: Source) -> Callable[[Item], None]:
        """How ``source`` hands its items over: a followed file's or a stream's reader waits for room."""
        waits = source.waits_for_room

        def put(item: Item) -> None:
            w = _weight(item)
            with self._room:
                while waits and self._bytes > self.limit_bytes and not self._closed:
                    self._room.wait(0.25)  # woken by the engine's get or by close
                if self._closed:
                    self._drop(item)
                    return
                self._bytes += w
                self._q.put(item)  # under the lock: close never misses an item on its way in

        return put

    def close(self) -> None:
        """No more is taken: the readers waiting for room are let go, and what is handed over from now on,
        and what still waits, is dropped (recorded in :meth:`not_analysed`)."""
        with self._room:
            self._closed = True
            while True:
                try:
                    self._drop(self._q.get_nowait())
                except queue.Empty:
                    break
            self._bytes = 0
            self._room.notify_all()

    def abandon(self, sources: Sequence[Source], wait_s: float) -> None:
        """The consumer gives up (a second Ctrl-C, a closed view): ``sources`` stop without their last read,
        the backlog closes, and each source's thread gets ``wait_s`` to end, so a block in a reader's hands
        as it closed is dropped on record too."""
        for s in sources:
            s.abandon()
        self.close()
        for s in sources:
            s.stop(wait_s)

    def _drop(self, item: Item) -> None:
        self._dropped_items += 1
        if isinstance(item, LineBlock):
            self._dropped.setdefault(item.file, item.first_line)

    def not_analysed(self) -> tuple[dict[str, int], int]:
        """What :meth:`close` dropped: each file's first line not analysed, and the number of items."""
        with self._room:
            return dict(self._dropped), self._dropped_items

    def put(self, item: Item) -> None:
        """An item handed over by no source's thread (never held)."""
        with self._room:
            if self._closed:
                self._drop(item)
                return
            self._bytes += _weight(item)
            self._q.put(item)

    def get(self, timeout_s: float | None = None) -> Item:
        """The next item; ``queue.Empty`` if none came within ``timeout_s`` (None: none is there now)."""
        item = self._q.get_nowait() if timeout_s is None else self._q.get(timeout=timeout_s)
        with self._room:
            if not self._closed:  # close has already let go of every item's weight
                self._bytes -= _weight(item)
            if self._bytes <= self.limit_bytes:
                self._room.notify_all()
        return item

    def empty(self) -> bool:
        return self._q.empty()
