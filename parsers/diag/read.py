"""Frauscher-style diagnostic records → a columnar table.

A record is one line of twelve tab-separated ``Key:Value`` fields (spaces for the tabs are read too, off the
fast path: a record copied from an e-mail or a PDF)::

    Diag_id:00002  ID:4083  Device:IM  Type:013  GS:GS03  Trackinfo:WS4  ch:1
    Adr:080  Label:Summenzä  Data:18  Date:2015-10-31  Time:09:32:24[.125]

How it stays fast and bounded (no Python loop per record):

* the file is read in line-aligned chunks (``parsers.sources``); numpy finds
  the newlines and tabs of a chunk in one pass;
* each line is cut into three spans: fields 1–9 (the *register span*: device,
  counting head, channel, address, label), fields 10–11 (*value span*: data
  and date) and the time.  The two text spans are wrapped, without copying,
  as Arrow binary-view arrays and dictionary-encoded in C++: a log has a few
  thousand distinct spans however many million records it holds, and each
  distinct span is validated and decoded once, in Python;
* the time, which is nearly unique per record, is parsed with vectorized
  byte arithmetic;
* chunks are tokenized on a thread pool (numpy and Arrow release the GIL)
  while the main thread merges the small per-chunk dictionaries.

Every line ends up as a record, a blank line or a rejection with its file,
line number and reason (``parsers.report``).

The parts: :mod:`parsers.diag.tokens` and :mod:`parsers.diag.tokens_numpy` cut
chunks into spans, :mod:`parsers.diag.gather` gathers the good lines' columns,
:mod:`parsers.diag.read_ahead` reads the next chunk meanwhile, and
:mod:`parsers.diag.records` holds the record batches and builds the table;
this module is the reader that drives them and reads the other lines one by one.
"""

from __future__ import annotations

import os
import re
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from parsers.diag.fields import FIELD_KEYS, FieldError, parse_time
from parsers.diag.gather import gather_compiled, gather_numpy
from parsers.diag.read_ahead import ReadAhead
from parsers.diag.records import DiagChunk, chunks_to_frame
from parsers.diag.registry import DiagRegistry
from parsers.diag.tokens import COMPILED_BUILT, Tokens, tokenize_compiled
from parsers.diag.tokens_numpy import tokenize_numpy
from parsers.report import FileReport, ParseReport
from parsers.sources import (
    DEFAULT_CHUNK_BYTES,
    DEFAULT_MAX_LINE_BYTES,
    Chunk,
    OverlongLine,
    ReadFailure,
    iter_chunks,
    open_input,
)

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["DiagReader", "compiled_tokenizer", "read_diag"]

# The compiled tokenizer where it was built (``pip install`` with a C compiler), unless TRACKSIDE_PURE=1 asks
# for the numpy one: both give the same tokens (tests/test_diag_compiled.py).
_COMPILED = COMPILED_BUILT and not os.environ.get("TRACKSIDE_PURE")
_tokenize: Callable[[Chunk], Tokens] = tokenize_compiled if _COMPILED else tokenize_numpy
_gather = gather_compiled if _COMPILED else gather_numpy


def compiled_tokenizer() -> bool:
    """Whether the compiled tokenizer is in use."""
    return _tokenize is tokenize_compiled


# Below this chunk size the thread pool's hand-over costs more than tokenizing in the reading thread.
_POOL_MIN_CHUNK_BYTES = 256 << 10


@dataclass
class _Ready:
    """A chunk tokenized in the reading thread, queued like a worker's future."""

    tokens: Tokens

    def result(self) -> Tokens:
        return self.tokens


class DiagReader:
    """Streams diagnostic records from files as :class:`DiagChunk` batches.

    Use :meth:`chunks` for bounded-memory streaming, or :func:`read_diag` for
    one DataFrame.  After iteration, :attr:`report` accounts for every line.
    """

    def __init__(
        self,
        paths: Iterable[Path],
        *,
        chunk_bytes: int = DEFAULT_CHUNK_BYTES,
        max_line_bytes: int = DEFAULT_MAX_LINE_BYTES,
        workers: int = 2,
        on_progress: Callable[[int], None] | None = None,
    ) -> None:
        self.paths = [Path(p) for p in paths]
        self.chunk_bytes = chunk_bytes
        self.max_line_bytes = max_line_bytes
        self.workers = workers
        self.on_progress = on_progress
        self.registry = DiagRegistry()
        self.report = ParseReport()

    def chunks(self) -> Iterator[DiagChunk]:
        """Parse all files in order; yields chunks of records as they are ready."""
        with ThreadPoolExecutor(max_workers=max(1, self.workers)) as pool:
            for path in self.paths:
                yield from self._file_chunks(path, pool)
        self.report.unknown_labels.update(self.registry.unknown_labels())
        self.report.check()

    def _file_chunks(self, path: Path, pool: ThreadPoolExecutor) -> Iterator[DiagChunk]:
        stream, raw, info = open_input(path)
        name = str(path)
        file_id = len(self.registry.files)
        self.registry.files.append(name)
        fr = FileReport(file=name, encoding=info.encoding, compressed=info.compressed)
        self.report.files.append(fr)
        last_pos = 0

        def progress() -> None:
            nonlocal last_pos
            pos = raw.tell()
            if self.on_progress is not None and pos > last_pos:
                self.on_progress(pos - last_pos)
            last_pos = pos

        pending: deque[Future[Tokens] | _Ready | OverlongLine] = deque()
        # Small chunks are tokenized in this thread: handing each to a worker costs more than it saves.
        inline = self.workers <= 1 or self.chunk_bytes < _POOL_MIN_CHUNK_BYTES
        next_line = 1  # line numbers are handed out here, in file order
        done_buffers: list[bytearray] = []  # read buffers of resolved chunks, to read into again

        def drain() -> DiagChunk | None:
            nonlocal next_line
            item = pending.popleft()
            if isinstance(item, OverlongLine):
                self._overlong(item, fr, next_line)
                next_line += 1
                return None
            tok = item.result()
            out = self._resolve(tok, fr, file_id, next_line)
            next_line += len(tok.starts)
            # Nothing of the chunk's buffer is referenced beyond this point.
            if isinstance(tok.chunk.data, memoryview) and isinstance(tok.chunk.data.obj, bytearray):
                done_buffers.append(tok.chunk.data.obj)
            return out

        source = iter_chunks(
            stream,
            info,
            chunk_bytes=self.chunk_bytes,
            max_line_bytes=self.max_line_bytes,
            on_bytes=progress,
            name=name,
            recycle=done_buffers,
        )
        # The next chunk is read on a thread of its own while this thread resolves the last one: the read
        # (a copy from the kernel or the decompressor) releases the GIL.
        ahead = ReadAhead(source) if not inline else None
        try:
            for item in ahead if ahead is not None else source:
                if isinstance(item, OverlongLine):
                    pending.append(item)
                elif inline:
                    pending.append(_Ready(_tokenize(item)))
                else:
                    pending.append(pool.submit(_tokenize, item))
                while len(pending) > self.workers:
                    if (out := drain()) is not None:
                        yield out
            while pending:
                if (out := drain()) is not None:
                    yield out
        finally:
            if ahead is not None:
                ahead.close()  # no read in flight when the stream closes
            for fut in pending:
                if isinstance(fut, Future):
                    fut.cancel()
            stream.close()
            raw.close()
        fr.ends_without_newline = info.ends_without_newline
        fr.bytes_read = last_pos

    def _overlong(self, o: OverlongLine, fr: FileReport, line: int) -> None:
        fr.lines_read += 1
        if isinstance(o, ReadFailure):  # the lines before a corrupt spot are kept; it stands for the rest
            self.report.reject(fr, line, "corrupt", o.message(line - 1), o.head)
            return
        reason = f"line longer than {self.max_line_bytes} bytes ({o.length} bytes)"
        self.report.reject(fr, line, "too long", reason, o.head)

    def parse_lines(self, data: bytes, fr: FileReport, file_id: int, first_line: int) -> DiagChunk:
        """Whole lines of a growing file (newline-terminated), numbered from ``first_line``:
        parsed into this reader's registry, rejections into ``fr`` (the live follower's entry)."""
        return self._resolve(_tokenize(Chunk(data, final=False)), fr, file_id, first_line)

    def _resolve(self, tok: Tokens, fr: FileReport, file_id: int, first_line: int) -> DiagChunk:
        """Merge a chunk's span dictionaries into the registry; parse or reject the rest."""
        reg = self.registry
        n_lines = len(tok.starts)
        fr.lines_read += n_lines

        reg_lut, reg_err = reg.register_ids(tok.reg_dict)
        val_cols, val_err = reg.values(tok.val_dict)
        val_ok = np.ones(len(tok.val_dict), bool)
        val_ok[list(val_err)] = False

        rid_g, time_ns, value, data_code, data_kind, subsecond, lines, bad_j = _gather(tok, reg_lut, val_cols, val_ok)

        # The rest is blank, off the fast path, or rejected: few lines, Python is fine.
        n_blank = int(tok.blank.sum())
        fr.blank += n_blank
        rest_lines: list[int] = []
        if len(lines) + n_blank < n_lines:  # else every line is a record or blank (fast lines are never blank)
            rest = np.ones(n_lines, bool)
            rest[lines] = False
            rest &= ~tok.blank
            rest_lines = np.flatnonzero(rest).tolist()
        bad_fast = dict(zip(tok.fast[bad_j].tolist(), bad_j.tolist(), strict=True))
        last_open = tok.chunk.final and not tok.chunk.ends_with_newline()
        slow: list[tuple[int, int, int, bool, int, int, int]] = []
        for li in rest_lines:
            raw = bytes(tok.buf[tok.starts[li] : tok.ends[li]])
            j = bad_fast.get(li)
            if j is not None and b" " in raw and _spaced_fields(raw) is not None:
                j = None  # spaces for some of its tabs: the fast path cut it wrong, the slow one reads it
            err: FieldError | None = None
            if j is not None and int(tok.reg_idx[j]) in reg_err:
                err = reg_err[int(tok.reg_idx[j])]
            elif j is not None and int(tok.val_idx[j]) in val_err:
                err = val_err[int(tok.val_idx[j])]
            else:
                parsed = self._slow_line(raw)
                if parsed is None:
                    fr.blank += 1
                    continue
                if isinstance(parsed, FieldError):
                    err = parsed
                else:
                    slow.append((li, *parsed))
                    continue
            category, reason = err.category, err.reason
            if last_open and li == n_lines - 1:
                category, reason = "truncated", f"truncated last line (no newline at end of file): {reason}"
            self.report.reject(fr, first_line + li, category, reason, raw)
        if slow:
            s_lines, s_rid, s_time, s_sub, s_value, s_code, s_kind = (np.array(c) for c in zip(*slow, strict=True))
            lines = np.concatenate([lines, s_lines])
            order = np.argsort(lines, kind="stable")
            lines = lines[order]
            rid_g = np.concatenate([rid_g, s_rid])[order]
            time_ns = np.concatenate([time_ns, s_time])[order]
            subsecond = np.concatenate([subsecond, s_sub])[order]
            value = np.concatenate([value, s_value])[order]
            data_code = np.concatenate([data_code, s_code])[order]
            data_kind = np.concatenate([data_kind, s_kind])[order]
        out = DiagChunk(
            file_id=file_id,
            # Every column is a fresh array already: convert, never copy.
            register_id=rid_g.astype(np.int32, copy=False),
            time_ns=time_ns.astype(np.int64, copy=False),
            subsecond=subsecond.astype(bool, copy=False),
            value=value.astype(np.int64, copy=False),
            data_code=data_code.astype(np.int32, copy=False),
            data_kind=data_kind.astype(np.int8, copy=False),
            line=lines.astype(np.int64, copy=False) + first_line,
        )
        fr.records += len(out)
        reg.count_records(out.register_id)
        return out

    def _slow_line(self, raw: bytes) -> tuple[int, int, bool, int, int, int] | FieldError | None:
        """Parse one line in Python with the same field rules (None: blank).

        Returns (register id, time ns, subsecond, value, data code, kind code).
        """
        if not raw.strip():
            return None
        parts = raw.split(b"\t")
        if len(parts) != len(FIELD_KEYS):
            spaced = _spaced_fields(raw)
            if spaced is None:
                return FieldError(*_shape_reason(raw, len(parts)))
            parts = spaced
        rid = self.registry.register_id(b"\t".join(parts[:9]))
        if isinstance(rid, FieldError):
            return rid
        val = self.registry.value(b"\t".join(parts[9:11]))
        if isinstance(val, FieldError):
            return val
        try:
            tod, subsecond = parse_time(parts[11])
        except FieldError as exc:
            return exc
        code, value, kind, day_ns = val
        return rid, day_ns + tod, subsecond, value, code, kind


# A record whose tabs became spaces (copied from an e-mail, a PDF, a terminal): its fields are cut before each
# key instead.  The keys are fixed and in order; a label keeps its inner spaces ("Label:Software V").
_SPACED_FIELDS = re.compile(("[ \t]+(?=(?:" + "|".join(FIELD_KEYS[1:]) + "):)").encode())


def _spaced_fields(raw: bytes) -> list[bytes] | None:
    """A record's twelve fields when spaces stand for its tabs; None when it is no such record."""
    parts = _SPACED_FIELDS.split(raw.strip())
    if len(parts) != len(FIELD_KEYS):
        return None
    if any(part.partition(b":")[0] != key.encode() for part, key in zip(parts, FIELD_KEYS, strict=True)):
        return None
    return parts


def _shape_reason(raw: bytes, n_fields: int) -> tuple[str, str]:
    if b"\0" in raw or sum(b < 32 and b not in (9, 13) for b in raw[:256]) > 2:
        return "binary", "binary data, not a text record"
    return "fields", f"expected {len(FIELD_KEYS)} tab-separated Key:Value fields, found {n_fields}"


def read_diag(paths: Iterable[Path | str], **kwargs: object) -> tuple[pd.DataFrame, ParseReport]:
    """Parse diagnostic files (plain or gzip) into one record table and a report."""
    reader = DiagReader([Path(p) for p in paths], **kwargs)  # type: ignore[arg-type]
    chunks = list(reader.chunks())
    return chunks_to_frame(chunks, reader.registry), reader.report
