"""Read an input file as a stream of line-aligned byte chunks.

Handles plain and gzip files (by magic bytes, not by name), a UTF-8 BOM,
UTF-16 exports (transcoded to UTF-8 on the fly), and lines of any length:
a line longer than ``max_line_bytes`` is cut off and reported as an
``OverlongLine`` instead of growing a buffer without bound.
"""

from __future__ import annotations

import codecs
import gzip
import io
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

DEFAULT_CHUNK_BYTES = 4 << 20
DEFAULT_MAX_LINE_BYTES = 4 << 20

GZIP_MAGIC = b"\x1f\x8b"
UTF8_BOM = codecs.BOM_UTF8
UTF16_BOMS = (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)


class InputError(Exception):
    """An input that cannot be read at all (missing, a directory, corrupt gzip)."""


@dataclass
class Chunk:
    """Complete lines: ``data`` ends with a newline unless it is the file's last
    piece and the file ends without one.  Line numbers are assigned by the
    consumer, in order, so the reader never has to count lines."""

    data: memoryview | bytes
    final: bool

    def ends_with_newline(self) -> bool:
        return len(self.data) > 0 and self.data[-1] in (10, b"\n")


@dataclass
class OverlongLine:
    """A line longer than the limit: only its head is kept, for the report."""

    head: bytes
    length: int


@dataclass
class SourceInfo:
    encoding: str = "utf-8"
    compressed: bool = False
    ends_without_newline: bool = False


class _Utf16ToUtf8(io.RawIOBase):
    """A UTF-16 byte stream presented as UTF-8 bytes."""

    def __init__(self, raw: IO[bytes], encoding: str) -> None:
        self._text = io.TextIOWrapper(raw, encoding=encoding, errors="replace", newline="")
        self._pending = b""

    def readable(self) -> bool:
        return True

    def readinto(self, b: bytearray | memoryview) -> int:  # type: ignore[override]
        while len(self._pending) < len(b):
            text = self._text.read(1 << 20)
            if not text:
                break
            self._pending += text.encode("utf-8")
        n = min(len(b), len(self._pending))
        b[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n


def open_input(path: Path) -> tuple[IO[bytes], IO[bytes], SourceInfo]:
    """Open path for reading bytes; returns (stream, underlying raw file, info).

    The raw file's position tells progress in on-disk bytes.
    """
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, expected a log file")
    try:
        raw: IO[bytes] = path.open("rb")
    except OSError as exc:
        raise InputError(f"{path}: cannot open ({exc.strerror or exc})") from None
    info = SourceInfo()
    head = raw.read(4)
    raw.seek(0)
    stream: IO[bytes] = raw
    if head.startswith(GZIP_MAGIC):
        info.compressed = True
        stream = gzip.GzipFile(fileobj=raw, mode="rb")  # type: ignore[assignment]
        try:
            head = stream.read(4)
        except (OSError, EOFError, zlib.error) as exc:
            raise InputError(f"{path}: not a readable gzip file ({exc})") from None
        stream = gzip.GzipFile(fileobj=raw, mode="rb")  # type: ignore[assignment]
        raw.seek(0)
    if head.startswith(UTF16_BOMS):
        info.encoding = "utf-16"
        stream = io.BufferedReader(_Utf16ToUtf8(stream, "utf-16"))
    elif head.startswith(UTF8_BOM):
        info.encoding = "utf-8-sig"
        stream.read(len(UTF8_BOM))
    return stream, raw, info


def iter_chunks(
    stream: IO[bytes],
    info: SourceInfo,
    *,
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    max_line_bytes: int = DEFAULT_MAX_LINE_BYTES,
    on_bytes: Callable[[], None] | None = None,
    name: str = "",
    recycle: list[bytearray] | None = None,
) -> Iterator[Chunk | OverlongLine]:
    """Yield line-aligned chunks, and overlong lines in their place in the file.

    Each chunk is read straight into its own buffer (one copy, from the
    kernel or the decompressor); only the unfinished last line is carried
    over.  Memory stays within about ``chunk_bytes + max_line_bytes`` per
    chunk in flight.

    ``recycle``: buffers the consumer has finished with (it appends a chunk's
    ``data.obj`` once nothing refers to the chunk any more); they are read
    into again instead of allocating, and faulting in, fresh memory.
    """
    carry = b""
    skipping: OverlongLine | None = None  # inside an overlong line, discarding to its end
    while True:
        need = len(carry) + chunk_bytes
        buf = recycle.pop() if recycle else None
        if buf is None or len(buf) < need:
            # A little slack, so that the buffer fits again with the next carry.
            buf = bytearray(need + (1 << 16 if recycle is not None else 0))
        buf[: len(carry)] = carry
        try:
            n = stream.readinto(memoryview(buf)[len(carry) : need])  # type: ignore[attr-defined]
        except (OSError, EOFError, zlib.error) as exc:
            raise InputError(f"{name}: read failed, the file is corrupt or truncated ({exc})") from None
        if on_bytes is not None:
            on_bytes()
        if not n:
            if skipping is not None:
                info.ends_without_newline = True
                yield skipping
            elif carry:
                info.ends_without_newline = True
                yield Chunk(carry, final=True)
            return
        total = len(carry) + n
        view = memoryview(buf)[:total]
        start = 0
        if skipping is not None:
            nl = buf.find(b"\n", 0, total)
            if nl < 0:
                skipping.length += total
                carry = b""
                continue
            skipping.length += nl
            yield skipping
            skipping = None
            start = nl + 1
        cut = buf.rfind(b"\n", start, total) + 1
        if cut == 0:
            if total - start > max_line_bytes:
                skipping = OverlongLine(bytes(buf[start : start + 200]), total - start)
                carry = b""
            else:
                carry = bytes(buf[start:total])
            continue
        carry = bytes(buf[cut:total])
        if len(carry) > max_line_bytes:
            skipping = OverlongLine(carry[:200], len(carry))
            carry = b""
        yield Chunk(view[start:cut], final=False)
