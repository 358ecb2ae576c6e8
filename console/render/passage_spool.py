"""``--json`` passages in bounded memory: encoded as they close, spooled to a temporary file.

A stream closes passages in time order; the JSON document lists them as a
whole-file read does, by counting head, then start.  Each passage is encoded
once, as it closes, and appended to an unnamed temporary file; only its
place (head key, start, offset, length: 24 bytes) stays in memory.  At the
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

from console.analysis.passages import Columns
from console.jsonout import JSONParts

_LINE_TYPE = "p"
_PREFIX = '{"type":"' + _LINE_TYPE + '",'
# Texts copied out per read of the spool (bounded memory, few calls).
_COPY_ROWS = 4096


def passage_texts(cols: Columns, heads: list[tuple[int, str]]) -> list[str]:
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
        self._ordered: tuple[np.ndarray, np.ndarray] | None = None
        self.count = 0

    def add(self, cols: Columns, heads: list[tuple[int, str]]) -> None:
        """Take one batch (any order); only its texts' places stay in memory."""
        if not len(cols["head"]):
            return
        assert self._ordered is None, "passages added after they were read"
        texts = [t.encode("ascii") for t in passage_texts(cols, heads)]
        lengths = np.fromiter((len(t) for t in texts), np.int64, len(texts))
        self._file.write(b"".join(texts))
        self._offset.append(self._size + np.cumsum(lengths) - lengths)
        self._length.append(lengths.astype(np.int32))
        self._head.append(np.asarray(cols["head"], np.int32))
        self._start.append(np.asarray(cols["start_ns"], np.int64))
        self._size += int(lengths.sum())
        self.count += len(texts)

    def clear(self) -> None:
        """Forget every passage taken so far (the log is read again)."""
        self._file.seek(0)
        self._file.truncate()
        self._size = self.count = 0
        self._head, self._start, self._offset, self._length = [], [], [], []
        self._ordered = None

    def json_parts(self) -> JSONParts:
        """The passages as a JSON array in a whole read's order (by head, then start), written piece by piece."""
        return JSONParts(self._parts())

    def _order(self) -> tuple[np.ndarray, np.ndarray]:
        """Offsets and lengths of the texts in a whole read's order (by head, then start); made once."""
        if self._ordered is None:
            self._file.flush()
            # Each column joined and its parts let go in turn: few copies at once.
            head = _joined(self._head)
            start = _joined(self._start)
            order = np.lexsort((start, head))
            del head, start
            self._ordered = _joined(self._offset)[order], _joined(self._length)[order]
        return self._ordered

    def _blocks(self) -> Iterator[list[bytes]]:
        """The texts in order, a list of up to ``_COPY_ROWS`` at a time."""
        offset, length = self._order()
        fd = self._file.fileno()
        for lo in range(0, len(offset), _COPY_ROWS):
            rows = slice(lo, lo + _COPY_ROWS)
            # One pread per passage (no seek, no buffer refill): flushed in _order, so the file holds them all.
            yield [os.pread(fd, n, off) for off, n in zip(offset[rows].tolist(), length[rows].tolist(), strict=True)]

    def _parts(self) -> Iterator[str]:
        if not self.count:
            yield "[]"
            return
        yield "["
        for i, pieces in enumerate(self._blocks()):
            yield ("," if i else "") + b",".join(pieces).decode("ascii")
        yield "]"

    def texts(self) -> Iterator[str]:
        """Each passage's JSON object, in a whole read's order (by head, then start); may be read again."""
        if not self.count:
            return
        for pieces in self._blocks():
            for piece in pieces:
                yield piece.decode("ascii")

    def close(self) -> None:
        self._file.close()


def _joined(parts: list[np.ndarray]) -> np.ndarray:
    """The parts as one array; the list is emptied (its arrays freed as soon as nothing else holds them)."""
    out = np.concatenate(parts)
    parts.clear()
    return out
