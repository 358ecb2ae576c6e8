"""Memory given back between the phases of a long job, so that one phase's peak does not stack on another's."""

from __future__ import annotations

import ctypes
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def read_memory() -> Iterator[None]:
    """Memory kept bounded around a log's read: Arrow on the system allocator, freed pages returned after.

    Arrow's default pool (mimalloc) keeps the pages the decoder's threads
    freed in those threads' heaps, where ``release_unused`` does not reach
    them; and the C heap keeps what the read freed.  The faces write their
    output after the read, so that output would stack on top of both.  On a
    12 M-record report the peak RSS was 17 MB (the pool) and 5 MB (the heap)
    lower, at the same CPU.
    """
    import pyarrow as pa

    before = pa.default_memory_pool()
    pa.set_memory_pool(pa.system_memory_pool())
    try:
        yield
    finally:
        pa.set_memory_pool(before)
        trim_heap()


def trim_heap() -> None:
    """Give the C heap's free pages back to the system (glibc's malloc_trim; elsewhere nothing)."""
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):
        return
    trim(0)


def one_malloc_arena() -> None:
    """glibc's malloc serves every thread started from now on from one heap (``M_ARENA_MAX`` 1; elsewhere nothing).

    A job whose threads pass buffers to each other (an ingest's tokenizers, its parser and its Parquet
    writer) otherwise leaves each thread's heap holding pages another thread freed: a 3 M-record ingest
    peaked about 30 MB lower with one heap, for the same CPU.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(-8, 1)  # M_ARENA_MAX (malloc.h)
