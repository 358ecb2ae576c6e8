"""Memory given back between the phases of a long job, so that one phase's peak does not stack on another's."""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path


@contextmanager
def read_memory(arrow: bool = True) -> Iterator[None]:
    """Memory kept bounded around a log's read: Arrow on the system allocator, freed pages returned after.

    Arrow's default pool (mimalloc) keeps the pages the decoder's threads
    freed in those threads' heaps, where ``release_unused`` does not reach
    them; and the C heap keeps what the read freed.  The faces write their
    output after the read, so that output would stack on top of both.  On a
    12 M-record report the peak RSS was 17 MB (the pool) and 5 MB (the heap)
    lower, at the same CPU.

    ``arrow``: whether the read uses Arrow.  A read that does not (the compiled tokenizer's) and finds it not
    loaded yet does not load it: about 30 ms of start-up.
    """
    if not arrow and "pyarrow" not in sys.modules:
        try:
            yield
        finally:
            trim_heap()
        return
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


def fixed_mmap_threshold(threshold_bytes: int = 128 << 10) -> None:
    """glibc's malloc serves every block from ``threshold_bytes`` up by its own mapping, for the rest of the
    process (``M_MMAP_THRESHOLD``; elsewhere nothing).

    glibc raises the threshold each time such a block is freed (up to 32 MB), after which a read's
    growing columns and its batches' temporary arrays share the heap: the columns' moves leave holes the
    heap keeps.  Fixed, a freed batch goes back to the system at once and a column grows by remapping.
    `trackside gnss` on a million-device CSV peaked about 30 MB lower, at the same CPU.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(-3, threshold_bytes)  # M_MMAP_THRESHOLD (malloc.h)


def heap_kept_for_reuse(pad_bytes: int = 64 << 20, mapped_from_bytes: int = 32 << 20) -> None:
    """glibc's malloc keeps freed memory for the next chunk's arrays instead of giving it back and faulting it
    in again, for the rest of the process (``M_TOP_PAD``, ``M_TRIM_THRESHOLD`` twice the pad, and blocks
    mapped on their own only from ``mapped_from_bytes``; elsewhere nothing).

    A read makes each chunk's columns anew and frees the last's: with the defaults, much of a batch
    command's system time is page faults on that memory.  `analyze --json` of 3 M records took about 5 %
    less wall time, at 11 MB more peak; of a log of a million heads, 6 % less, at 483 MB against 451.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt(-2, pad_bytes)  # M_TOP_PAD (malloc.h)
    mallopt(-1, 2 * pad_bytes)  # M_TRIM_THRESHOLD
    mallopt(-3, mapped_from_bytes)  # M_MMAP_THRESHOLD


# Inputs from this size up are read with the memory kept bounded (big_read_memory); smaller ones are not worth
# loading pyarrow for (a small NMEA file never needs it).
BIG_READ_BYTES = 16 << 20


@contextmanager
def big_read_memory(paths: Iterable[Path | str], mmap_threshold_bytes: int = 128 << 10) -> Iterator[None]:
    """Around a read of files of :data:`BIG_READ_BYTES` or more in all: :func:`read_memory`, and blocks from
    ``mmap_threshold_bytes`` up mapped on their own (:func:`fixed_mmap_threshold`); smaller reads as they are.

    `trackside gnss --json` on a million-device CSV (59 MB) peaked at 279 MB, not 352 MB."""
    total = 0
    for path in paths:
        with suppress(OSError):
            total += os.stat(path).st_size
    if total < BIG_READ_BYTES:
        yield
        return
    fixed_mmap_threshold(mmap_threshold_bytes)
    with read_memory():
        yield
