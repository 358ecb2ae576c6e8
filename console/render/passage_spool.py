"""``--json`` passages in bounded memory: encoded as they close, spooled to a temporary file.

A stream closes passages in time order; the JSON document lists them as a
whole-file read does, by counting head, then start.  Each passage is encoded
once, as it closes, and appended to an unnamed temporary file; only its
place (head key, start, offset, length: 32 bytes) stays in memory.  At the
end the document copies the texts out in the document's order, piece by
piece, so neither the passages table nor its JSON is ever held whole.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Iterator
from typing import IO

import numpy as np

from console.analysis.head_table import Heads
from console.analysis.passages import Columns
from console.jsonout import JSONParts

_LINE_TYPE = "p"
_PREFIX = '{"type":"' + _LINE_TYPE + '",'
# Texts copied out per read of the spool (bounded memory, few calls).
_COPY_ROWS = 4096


def passage_texts(cols: Columns, heads: Heads) -> list[str]:
    """Each passage of ``cols`` as one JSON object (the ``--json`` fields, ASCII)."""
    from console.analysis.passages_json import encode_passages

    text = encode_passages(cols, heads, workers=1, lines_of_type=_LINE_TYPE)
    if text is not None:
        return ["{" + line[len(_PREFIX) :] for line in text.splitlines()]
    # Text the byte encoder does not cover: pandas' encoder, as for a whole read.
    from console.analysis.diagnostics import _passages_frame, passages_json_text
    from console.jsonout import encode

    return [encode(p) for p in json.loads(passages_json_text(_passages_frame(cols, heads)))]


class PassageSpool:
    """Collects batches of closed passages; :meth:`json_parts` gives them back as one JSON array."""

    def __init__(self) -> None:
        # Deleted when closed (or when the process ends): no name to clean up.
        self._file: IO[bytes] = tempfile.TemporaryFile(prefix="trackside-passages-")  # noqa: SIM115
        self._size = 0
        self._head: list[np.ndarray] = []
        self._start: list[np.ndarray] = []
        self._offset: list[np.ndarray] = []
        self._length: list[np.ndarray] = []
        self.count = 0

    def add(self, cols: Columns, heads: Heads) -> None:
        """Take one batch (any order); only its texts' places stay in memory."""
        if not len(cols["head"]):
            return
        texts = [t.encode("ascii") for t in passage_texts(cols, heads)]
        lengths = np.fromiter((len(t) for t in texts), np.int64, len(texts))
        self._file.write(b"".join(texts))
        self._offset.append(self._size + np.cumsum(lengths) - lengths)
        self._length.append(lengths)
        self._head.append(np.asarray(cols["head"], np.int64))
        self._start.append(np.asarray(cols["start_ns"], np.int64))
        self._size += int(lengths.sum())
        self.count += len(texts)

    def clear(self) -> None:
        """Forget every passage taken so far (the log is read again)."""
        self._file.seek(0)
        self._file.truncate()
        self._size = self.count = 0
        self._head, self._start, self._offset, self._length = [], [], [], []

    def json_parts(self) -> JSONParts:
        """The passages as a JSON array in a whole read's order (by head, then start), written piece by piece."""
        return JSONParts(self._parts())

    def _parts(self) -> Iterator[str]:
        if not self.count:
            yield "[]"
            return
        self._file.flush()
        head, start = np.concatenate(self._head), np.concatenate(self._start)
        offset, length = np.concatenate(self._offset), np.concatenate(self._length)
        self._head = self._start = self._offset = self._length = []
        order = np.lexsort((start, head))
        del head, start
        offset, length = offset[order], length[order]
        del order
        fd = self._file.fileno()
        yield "["
        for lo in range(0, len(offset), _COPY_ROWS):
            rows = slice(lo, lo + _COPY_ROWS)
            # One pread per passage (no seek, no buffer refill): flushed above, so the file holds them all.
            pieces = [os.pread(fd, n, off) for off, n in zip(offset[rows].tolist(), length[rows].tolist(), strict=True)]
            yield ("," if lo else "") + b",".join(pieces).decode("ascii")
        yield "]"

    def close(self) -> None:
        self._file.close()
