"""A chunk of diagnostic records cut into spans: the tokens, and the compiled tokenizer that cuts them.

Each line of a chunk is cut into three spans: fields 1–9 (the *register span*: device, counting head,
channel, address, label), fields 10–11 (the *value span*: data and date) and the time.  The two text spans
are dictionary-encoded per chunk (a log has a few thousand distinct spans however many million records it
holds) and the time is read to nanoseconds since midnight.

Two tokenizers cut alike (tests/test_diag_compiled.py): :func:`tokenize_compiled` here, one pass in C
without the GIL (``compiled_tokens.c``), and :func:`parsers.diag.tokens_numpy.tokenize_numpy`, numpy and
Arrow only, the reference; the reader (:mod:`parsers.diag.read`) chooses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from parsers.sources import Chunk

try:
    from parsers.diag import compiled_tokens
except ImportError:  # built without a C compiler: the numpy tokenizer
    compiled_tokens = None  # type: ignore[assignment]

#: Whether the compiled tokenizer was built (``pip install`` with a C compiler).
COMPILED_BUILT = compiled_tokens is not None


@dataclass
class Tokens:
    """A chunk cut into spans (thread-pool output, before dictionary merging).

    ``fast`` lists the lines whose shape the vectorized pass recognised; all
    other non-blank lines go through :meth:`parsers.diag.read.DiagReader._slow_line`.
    """

    chunk: Chunk
    buf: memoryview | bytes
    starts: np.ndarray
    ends: np.ndarray
    blank: np.ndarray
    fast: np.ndarray
    reg_idx: np.ndarray
    reg_dict: list[bytes]
    val_idx: np.ndarray
    val_dict: list[bytes]
    tod_ns: np.ndarray
    subsecond: np.ndarray
    time_ok: np.ndarray


def chunk_bytes(chunk: Chunk) -> memoryview | bytes:
    """The chunk's data, ending with a newline (a last line without one gets it)."""
    return chunk.data if chunk.ends_with_newline() else bytes(chunk.data) + b"\n"


def tokenize_compiled(chunk: Chunk) -> Tokens:
    """:func:`parsers.diag.tokens_numpy.tokenize_numpy`'s cut, in one compiled pass without the GIL
    (``compiled_tokens.c``)."""
    assert compiled_tokens is not None
    data = chunk_bytes(chunk)
    n_fast, starts, ends, blank, fast, reg_idx, reg_dict, val_idx, val_dict, tod, subsecond, time_ok = (
        compiled_tokens.tokenize(data)
    )
    return Tokens(
        chunk=chunk,
        buf=data,
        starts=np.frombuffer(starts, np.intp),
        ends=np.frombuffer(ends, np.intp),
        blank=np.frombuffer(blank, np.bool_),
        fast=np.frombuffer(fast, np.intp)[:n_fast],
        reg_idx=np.frombuffer(reg_idx, np.intp)[:n_fast],
        reg_dict=reg_dict,
        val_idx=np.frombuffer(val_idx, np.intp)[:n_fast],
        val_dict=val_dict,
        tod_ns=np.frombuffer(tod, np.int64)[:n_fast],
        subsecond=np.frombuffer(subsecond, np.bool_)[:n_fast],
        time_ok=np.frombuffer(time_ok, np.bool_)[:n_fast],
    )
