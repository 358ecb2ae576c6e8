"""``--json`` passages in bounded memory: encoded as they close, spooled to a temporary file.

A stream closes passages in time order; the JSON document lists them as a
whole-file read does, by counting head, then start.  Each passage is encoded
once, as it closes, and appended to an unnamed temporary file; its place
(head key, start, offset, length) and any numeric ``columns`` the caller
asks for go to a second one, a fixed-size record each, so nothing stays in
memory per passage.  At the end the places are read back to find the
document's order and the texts are copied out in it, piece by piece, so
neither the passages table nor its JSON is ever held whole.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections import deque
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import IO

import numpy as np

from console.analysis.head_table import Heads
from console.analysis.passages.buckets import Columns
from console.analysis.passages.status import STATUS_KIND
from console.analysis.passages.stream import by_head_and_start, concat_passages, take_passages
from console.engine.sinks import Sink
from console.jsonout import JSONParts

_LINE_TYPE = "p"
_PREFIX = '{"type":"' + _LINE_TYPE + '",'
# Texts copied out per read of the spool (bounded memory, few calls).
_COPY_ROWS = 4096
# A passage's place in the texts' file: 24 bytes on disk.
_PLACE = [("head", "<i4"), ("length", "<i4"), ("start_ns", "<i8"), ("offset", "<i8")]
_INDEX_ROWS = 1 << 16  # places read back at a time
_ENCODE_ROWS = 8192  # passages encoded at a time
_ENCODING_MAX = 2  # batches handed to the encoder and not yet written (bounds the memory they hold)


def passage_texts(cols: Columns, heads: Heads) -> list[str]:
    """Each passage of ``cols`` as one JSON object (the ``--json`` fields, ASCII)."""
    from console.analysis.passages.json_text import encode_passages

    text = encode_passages(cols, heads, workers=1, lines_of_type=_LINE_TYPE)
    if text is not None:
        return ["{" + line[len(_PREFIX) :] for line in text.splitlines()]
    # Text the byte encoder does not cover: pandas' encoder, as for a whole read.
    from console.analysis.passages.frame_json import passages_json_text
    from console.analysis.passages.passage_frame import passages_frame
    from console.jsonout import encode

    return [encode(p) for p in json.loads(passages_json_text(passages_frame(cols, heads)))]


def _encode(cols: Columns, heads: Heads) -> tuple[bytes, np.ndarray]:
    """The passages' JSON objects, each followed by a comma, back to back; and each one's length, its comma
    included.  (A run of passages read back is then a piece of the array as it is: no cutting, no joining.)"""
    from console.analysis.passages.json_text import encode_objects

    encoded = encode_objects(cols, heads, after=",")
    if encoded is not None:
        return encoded
    texts = [t.encode("ascii") + b"," for t in passage_texts(cols, heads)]
    return b"".join(texts), np.fromiter((len(t) for t in texts), np.int64, len(texts))


def _encode_by_head(cols: Columns, heads: Heads) -> tuple[bytes, np.ndarray, np.ndarray]:
    """:func:`_encode` of the passages by head, then start (each head's then lie back to back on disk, to be
    read back at once); and that order."""
    order = by_head_and_start(cols)
    text, lengths = _encode(take_passages(cols, order), heads)
    return text, lengths, order


class PassageSpool(Sink):
    """Collects batches of closed passages; :meth:`json_parts` gives them back as one JSON array.

    ``columns``: passage columns (name, NumPy type) kept too, read back with :meth:`columns`.
    """

    def __init__(self, columns: Sequence[tuple[str, str]] = ()) -> None:
        # Deleted when closed (or when the process ends): no name to clean up.
        self._file: IO[bytes] = tempfile.TemporaryFile(prefix="trackside-passages-")  # noqa: SIM115
        self._index: IO[bytes] = tempfile.TemporaryFile(prefix="trackside-passages-")  # noqa: SIM115
        self._record = np.dtype([*_PLACE, *columns])
        self._extra = [name for name, _ in columns]
        self._size = 0
        self._ordered: tuple[np.ndarray, np.ndarray] | None = None
        self._pending: list[Columns] = []
        self._pending_rows = 0
        self._heads: Heads | None = None
        # Encoded on a thread of its own, while the pipeline goes on (numpy releases the GIL); written in order.
        self._encoder: ThreadPoolExecutor | None = None
        self._encoding: deque[tuple[Future[tuple[bytes, np.ndarray, np.ndarray]], np.ndarray]] = deque()
        self.count = 0

    def passages(self, cols: Columns, heads: Heads) -> None:
        """Take one batch (any order); its texts and places go to disk, a few thousand passages at a time."""
        n = len(cols["head"])
        if not n:
            return
        assert self._ordered is None, "passages added after they were read"
        # Held until there are enough to encode at once: the encoder's cost is mostly per call, and a
        # stream closes a few hundred passages per chunk.  Head keys only ever grow: the latest table
        # names every key of the batches held.
        self._pending.append(cols)
        self._pending_rows += n
        self._heads = heads
        self.count += n
        if self._pending_rows >= _ENCODE_ROWS:
            self._flush()

    def _flush(self, wait: bool = False) -> None:
        """The held batches, handed to the encoder; what it has encoded, written in order (``wait``: all)."""
        if self._pending:
            cols = concat_passages(self._pending) if len(self._pending) > 1 else self._pending[0]
            assert cols is not None and self._heads is not None
            self._pending, self._pending_rows = [], 0
            rec = np.empty(len(cols["head"]), self._record)
            rec["head"] = cols["head"]
            rec["start_ns"] = cols["start_ns"]
            for name in self._extra:
                rec[name] = cols[name]
            if self._encoder is None:
                self._encoder = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trackside-passages")
            self._encoding.append((self._encoder.submit(_encode_by_head, cols, self._heads), rec))
        while self._encoding and (wait or len(self._encoding) > _ENCODING_MAX or self._encoding[0][0].done()):
            future, rec = self._encoding.popleft()
            text, lengths, order = future.result()
            # The places stay in the order taken (columns() reads them so); the texts are by head.
            rec["length"][order] = lengths
            rec["offset"][order] = self._size + np.cumsum(lengths, dtype=np.int64) - lengths
            self._file.write(text)
            self._index.write(rec.tobytes())
            self._size += len(text)

    def restart(self, passages: bool) -> None:
        """The log is read again: forget every passage taken so far, when they will be handed again."""
        if not passages:
            return
        for f in (self._file, self._index):
            f.seek(0)
            f.truncate()
        self._size = self.count = 0
        self._ordered = None
        self._pending, self._pending_rows = [], 0
        for future, _ in self._encoding:
            future.cancel()
        self._encoding.clear()

    def columns(self, names: Sequence[str], rows: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """These columns of every passage taken (``rows``: of these, ascending), in the order they were taken.

        Read back from disk a block at a time: only the result is held whole.
        """
        self._flush(wait=True)
        picked = None if rows is None else np.asarray(rows, np.int64)
        out = {name: np.empty(self.count if picked is None else len(picked), self._record[name]) for name in names}
        self._index.flush()
        fd, size = self._index.fileno(), self._record.itemsize
        for lo in range(0, self.count, _INDEX_ROWS):
            n = min(_INDEX_ROWS, self.count - lo)
            a, b = (lo, lo + n) if picked is None else np.searchsorted(picked, [lo, lo + n]).tolist()
            if a == b:
                continue
            part = np.frombuffer(os.pread(fd, n * size, lo * size), self._record)
            if picked is not None:
                part = part[picked[a:b] - lo]
            for name in names:
                out[name][a:b] = part[name]
        return out

    def json_parts(self) -> JSONParts:
        """The passages as a JSON array in a whole read's order (by head, then start), written piece by piece."""
        return JSONParts(self._parts())

    def _order(self) -> tuple[np.ndarray, np.ndarray]:
        """Offsets and lengths of the texts in a whole read's order (by head, then start); made once."""
        if self._ordered is None:
            self._flush(wait=True)
            self._file.flush()
            keys = self.columns(("head", "start_ns"))
            order = np.lexsort((keys.pop("start_ns"), keys.pop("head")))
            places = self.columns(("offset", "length"))
            self._ordered = places["offset"][order], places["length"][order]
        return self._ordered

    def _runs(self) -> Iterator[tuple[bytes, list[int]]]:
        """The texts in order (each with its comma), as runs read at once, each with its texts' lengths."""
        offset, length = self._order()
        fd = self._file.fileno()
        for lo in range(0, len(offset), _COPY_ROWS):
            off, n = offset[lo : lo + _COPY_ROWS], length[lo : lo + _COPY_ROWS]
            # Passages back to back in the file (a head's of one batch) are read at once (pread: no seek, no
            # buffer refill; flushed in _order, so the file holds them all).
            cut = np.flatnonzero(off[1:] != off[:-1] + n[:-1]) + 1
            for a, b in zip(np.r_[0, cut].tolist(), np.r_[cut, len(off)].tolist(), strict=True):
                yield os.pread(fd, int(off[b - 1] + n[b - 1] - off[a]), int(off[a])), n[a:b].tolist()

    def _parts(self) -> Iterator[str | bytes]:
        if not self.count:
            yield "[]"
            return
        # Runs of texts each with its comma are the array's body as it is, handed on as read (tens of kB each):
        # only the last comma goes.
        yield "["
        last = b""
        for run, _ in self._runs():
            if last:
                yield last
            last = run
        yield last[:-1]
        yield "]"

    def texts(self) -> Iterator[str]:
        """Each passage's JSON object, in a whole read's order (by head, then start); may be read again."""
        if not self.count:
            return
        for run, lengths in self._runs():
            at = 0
            for k in lengths:
                yield run[at : at + k - 1].decode("ascii")  # its comma left out
                at += k

    def close(self) -> None:
        if self._encoder is not None:
            self._encoder.shutdown(cancel_futures=True)
        self._file.close()
        self._index.close()


@dataclass
class FirstPassages(Sink):
    """The first ``limit`` listed passages of a whole read's order (by head key, then start) and how many
    passages there are, from batches of closed passages: what a table of the first rows needs, in memory
    bounded by ``limit`` (a log may close a passage at each of a million heads).

    Status-only passages are counted, not listed.  Ties keep the order the batches came in, as the
    whole table's stable sort does.
    """

    limit: int
    cols: Columns | None = None
    listed: int = 0
    status: int = 0

    def passages(self, cols: Columns, heads: object = None) -> None:
        """One batch of closed passages (``heads``: unused)."""
        status = cols["kind"] == STATUS_KIND
        self.status += int(status.sum())
        keep = np.flatnonzero(~status)
        self.listed += len(keep)
        part = take_passages(cols, keep)
        merged = concat_passages([self.cols, part]) if self.cols is not None else part
        assert merged is not None
        self.cols = take_passages(merged, by_head_and_start(merged)[: self.limit])

    def restart(self, passages: bool) -> None:
        """The log is read again: forget every passage taken so far, when they will be handed again."""
        if passages:
            self.cols, self.listed, self.status = None, 0, 0
