"""Reading ahead: the next chunk of a file read on a thread of its own while the one before is parsed.

The read (a copy from the kernel or the decompressor) releases the GIL, so it overlaps the main thread's
work on the chunk before.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor

from parsers.sources import Chunk, OverlongLine


class ReadAhead:
    """The items of an iterator, each fetched on a thread of its own while the one before is used."""

    def __init__(self, items: Iterator[Chunk | OverlongLine]) -> None:
        self._items = items
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trackside-read")
        self._next: Future[Chunk | OverlongLine | None] | None = self._pool.submit(self._fetch)

    def _fetch(self) -> Chunk | OverlongLine | None:
        return next(self._items, None)

    def __iter__(self) -> Iterator[Chunk | OverlongLine]:
        while self._next is not None:
            item = self._next.result()
            if item is None:
                self._next = None
                return
            self._next = self._pool.submit(self._fetch)
            yield item

    def close(self) -> None:
        """Wait for the read in flight (its result or error dropped), then stop the thread."""
        if self._next is not None:
            self._next.cancel()
            with contextlib.suppress(BaseException):
                self._next.result()
            self._next = None
        self._pool.shutdown()
