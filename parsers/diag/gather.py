"""A tokenized chunk's records gathered into columns: the good fast lines, after the registry's lookups.

The main thread has merged the chunk's span dictionaries into the registry (a register id per register
span, the decoded columns per value span); the gather picks each fast line's register id, value, data code
and kind and adds the day to the time, and lists the fast lines that were no good (a bad span or time).
Two gathers give the same columns (tests/test_diag_compiled.py): :func:`gather_compiled`, one compiled pass
without the GIL (``compiled_tokens.c``), and :func:`gather_numpy`; the reader (:mod:`parsers.diag.read`)
chooses.
"""

from __future__ import annotations

import numpy as np

from parsers.diag.tokens import Tokens

try:
    from parsers.diag import compiled_tokens
except ImportError:  # built without a C compiler: the numpy gather
    compiled_tokens = None  # type: ignore[assignment]

# The columns: register id, time ns, value, data code, data kind, subsecond, line (per good fast line); bad fast lines.
Gathered = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
_GATHERED_TYPES = (np.int32, np.int64, np.int64, np.int32, np.int8, np.bool_, np.intp)


def gather_compiled(tok: Tokens, reg_lut: np.ndarray, val_cols: np.ndarray, val_ok: np.ndarray) -> Gathered:
    """:func:`gather_numpy`'s columns in one compiled pass without the GIL (``compiled_tokens.c``)."""
    assert compiled_tokens is not None
    n_good, *cols, bad = compiled_tokens.gather_records(
        reg_lut,
        tok.reg_idx,
        tok.val_idx,
        np.ascontiguousarray(val_cols),
        val_ok,
        tok.time_ok,
        tok.tod_ns,
        tok.subsecond,
        tok.fast,
    )
    got: list[np.ndarray] = [np.frombuffer(c, t)[:n_good] for c, t in zip(cols, _GATHERED_TYPES, strict=True)]
    return (*got, np.frombuffer(bad, np.intp)[: len(tok.fast) - n_good])  # type: ignore[return-value]


def gather_numpy(tok: Tokens, reg_lut: np.ndarray, val_cols: np.ndarray, val_ok: np.ndarray) -> Gathered:
    """The record columns of a chunk's good fast lines (register and value spans valid, time read), and the
    positions of the other fast lines."""
    rid = reg_lut[tok.reg_idx]
    good = (rid >= 0) & val_ok[tok.val_idx] & tok.time_ok
    if good.all():  # the usual chunk: no selection to copy (the token arrays are this chunk's alone)
        vi, rid_g, tod_ns, subsecond, lines = tok.val_idx, rid, tok.tod_ns, tok.subsecond, tok.fast
    else:
        vi, rid_g, tod_ns = tok.val_idx[good], rid[good], tok.tod_ns[good]
        subsecond, lines = tok.subsecond[good], tok.fast[good]
    time_ns = val_cols[3][vi] + tod_ns
    value = val_cols[1][vi]
    # Narrowed per distinct value span, before the gather: no conversion per record.
    data_code = val_cols[0].astype(np.int32)[vi]
    data_kind = val_cols[2].astype(np.int8)[vi]
    return rid_g, time_ns, value, data_code, data_kind, subsecond, lines, np.flatnonzero(~good)
