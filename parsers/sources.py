"""Read an input as a stream of line-aligned byte chunks.

One reader for every parser, whatever the input is:

* a regular file, ``-`` (standard input), a FIFO, ``/dev/stdin`` or a process
  substitution (``/dev/fd/63``).  Streams are never seeked: what a parser
  peeks at is put back in front.  A stream is opened once per process and the
  bytes read from it are kept (up to :data:`REPLAY_LIMIT_BYTES`), so a parser
  that first looks at the head and then reads the whole input gets the same
  bytes twice, as it would from a file;
* gzip (recognised by its magic bytes, not by name; several members are one
  stream).  A truncated file, corrupt data or junk after the end is not an
  error of the whole input: the complete lines before it are delivered and
  then one :class:`ReadFailure` ("corrupt gzip after N lines") that the parser
  rejects like a line;
* UTF-8 (a BOM is skipped), UTF-16 LE/BE with a BOM or without one (told by
  the NUL bytes in every other position of the head), transcoded to UTF-8 on
  the fly; other 8-bit encodings are passed through for the parser to decode;
* LF, CRLF (the parser drops the CR) and CR-only line ends (old Mac exports,
  told by a head with CRs, no LF and no NUL: each CR becomes a line end;
  binary receiver data, which has NULs, keeps its CRs);
* lines of any length: a line longer than ``max_line_bytes`` is cut off and
  reported as an :class:`OverlongLine` instead of growing a buffer without
  bound.
"""

from __future__ import annotations

import codecs
import io
import os
import stat
import sys
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

DEFAULT_CHUNK_BYTES = 4 << 20
DEFAULT_MAX_LINE_BYTES = 4 << 20
STDIN_NAME = "-"

GZIP_MAGIC = b"\x1f\x8b"
UTF8_BOM = codecs.BOM_UTF8
UTF16_BOMS = (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)
BLF_MAGIC = b"LOGG"  # Vector BLF: binary, its NULs are not UTF-16

HEAD_BYTES = 4096  # what open_input looks at to recognise compression, encoding and line ends
REPLAY_LIMIT_BYTES = 16 << 20  # bytes of a stream kept for a later open (a parser's peek, then its read)
_GZIP_BLOCK_BYTES = 64 << 10
_RECOVER_PIECE_BYTES = 256  # after corrupt gzip data, re-decompress in pieces this small to keep what precedes it
_UTF16_MIN_SHARE = 0.9  # share of 2-byte units with one NUL byte (on the same side) that makes a head UTF-16

# What a failing read raises, from the OS, zlib or our own layers.
READ_ERRORS: tuple[type[BaseException], ...] = (OSError, EOFError, zlib.error)


class InputError(Exception):
    """An input that cannot be read at all (missing, a directory, unreadable)."""


class CorruptInput(InputError):
    """Bytes that cannot be decoded past some point (corrupt or truncated gzip, a failing device)."""

    def __init__(self, name: str, detail: str) -> None:
        super().__init__(f"{name}: {detail}")
        self.detail = detail


# What a layer holds back and raises once the bytes before it are delivered.
_LAYER_ERRORS: tuple[type[BaseException], ...] = (*READ_ERRORS, InputError)


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
class ReadFailure(OverlongLine):
    """The input cannot be read past this point; it stands in place of the rest.

    The consumer counts it as one rejected line (category ``"corrupt"``) with
    :meth:`message`; ``head`` holds the start of the unfinished line the
    failure cut, ``length`` its length.  It is an :class:`OverlongLine` so a
    consumer that knows only those still accounts for it.
    """

    detail: str = ""

    def message(self, lines_before: int) -> str:
        return f"{self.detail} after {lines_before} lines; the rest of the input is not read"


@dataclass
class SourceInfo:
    encoding: str = "utf-8"
    compressed: bool = False
    ends_without_newline: bool = False
    line_ends: str = "lf"  # "lf" (LF or CRLF) or "cr" (CR only)
    stream: bool = False  # a pipe, FIFO or standard input rather than a file


# ------------------------------------------------------------------ layers


class _Layer(io.RawIOBase):
    """A read-only byte stream built on another.

    ``readinto`` fills as much of the buffer as it can.  A failure after some
    bytes were produced is held back: those bytes are returned first and the
    failure is raised by the next call (and every call after it), so the
    lines before a corrupt spot are not lost with it.
    """

    def __init__(self) -> None:
        super().__init__()
        self._error: BaseException | None = None

    def readable(self) -> bool:
        return True

    def _read_some(self, view: memoryview) -> int:
        raise NotImplementedError

    def readinto(self, b: Any) -> int:
        view = memoryview(b).cast("B")
        got = 0
        while got < len(view):
            if self._error is not None:
                if got:
                    break
                raise self._error
            try:
                n = self._read_some(view[got:])
            except _LAYER_ERRORS as exc:
                # Without its traceback: the frames it holds would keep views of the caller's buffer.
                self._error = exc.with_traceback(None)
                continue
            if n == 0:
                break
            got += n
        return got

    def read(self, size: int | None = -1) -> bytes:
        if size is None or size < 0:
            return self.readall()
        buf = bytearray(size)
        n = self.readinto(buf)
        return bytes(memoryview(buf)[:n])

    def readall(self) -> bytes:
        parts = []
        while piece := self.read(1 << 20):
            parts.append(piece)
        return b"".join(parts)


class _Prefixed(_Layer):
    """``head`` (bytes already taken from ``lower``) followed by the rest of ``lower``."""

    def __init__(self, head: bytes, lower: Any) -> None:
        super().__init__()
        self._head = head
        self._lower = lower

    def _read_some(self, view: memoryview) -> int:
        if self._head:
            n = min(len(view), len(self._head))
            view[:n] = self._head[:n]
            self._head = self._head[n:]
            return n
        return int(self._lower.readinto(view))

    def close(self) -> None:
        self._lower.close()
        super().close()


class _Gunzip(_Layer):
    """Decompress gzip (one or more members) with bounded memory.

    A corrupt spot, a truncation or junk after the last member raises
    :class:`CorruptInput` once everything decodable before it was delivered.
    """

    def __init__(self, lower: IO[bytes], name: str) -> None:
        super().__init__()
        self._lower = lower
        self._name = name
        self._d = zlib.decompressobj(16 + zlib.MAX_WBITS)
        self._out = b""
        self._done = False

    def _corrupt(self, detail: str) -> CorruptInput:
        return CorruptInput(self._name, f"corrupt gzip ({detail})")

    def _next_member(self) -> None:
        rest = self._d.unused_data
        while len(rest) < 2:
            more = self._lower.read(_GZIP_BLOCK_BYTES)
            if not more:
                break
            rest += more
        if not rest.strip(b"\0"):
            # Zero padding (tape blocks) after the last member is allowed, as gzip(1) does.
            while more := self._lower.read(_GZIP_BLOCK_BYTES):
                if more.strip(b"\0"):
                    raise self._corrupt("junk after the end of the compressed data")
            self._done = True
            return
        if not rest.startswith(GZIP_MAGIC):
            raise self._corrupt("junk after the end of the compressed data")
        self._d = zlib.decompressobj(16 + zlib.MAX_WBITS)
        self._pending_input = rest

    _pending_input = b""

    def _read_some(self, view: memoryview) -> int:
        while not self._out:
            if self._done:
                return 0
            if self._d.eof:
                self._next_member()
                continue
            data = self._d.unconsumed_tail or self._pending_input or self._lower.read(_GZIP_BLOCK_BYTES)
            self._pending_input = b""
            if not data:
                raise self._corrupt("truncated: the data ends before the end of the compressed stream")
            saved = self._d.copy()
            try:
                self._out = self._d.decompress(data, max(len(view), 1 << 16))
            except zlib.error as exc:
                self._out = self._recover(saved, data)
                self._error = self._corrupt(str(exc).removeprefix("Error -3 while decompressing data: "))
                if not self._out:
                    raise self._error from None
        n = min(len(view), len(self._out))
        view[:n] = self._out[:n]
        self._out = self._out[n:]
        return n

    @staticmethod
    def _recover(d: Any, data: bytes) -> bytes:
        """What decompresses of ``data`` before its corrupt spot, fed in small pieces."""
        out = []
        for i in range(0, len(data), _RECOVER_PIECE_BYTES):
            try:
                out.append(d.decompress(data[i : i + _RECOVER_PIECE_BYTES]))
            except zlib.error:
                break
            if d.eof:
                break
        return b"".join(out)

    def readinto(self, b: Any) -> int:
        # _read_some may set _error itself after producing the recovered bytes.
        view = memoryview(b).cast("B")
        got = 0
        while got < len(view):
            if self._error is not None and not self._out:
                if got:
                    break
                raise self._error
            try:
                n = self._read_some(view[got:])
            except _LAYER_ERRORS as exc:
                exc = exc if isinstance(exc, CorruptInput) else self._corrupt(f"{type(exc).__name__}: {exc}")
                self._error = exc.with_traceback(None)
                continue
            if n == 0:
                break
            got += n
        return got

    def close(self) -> None:
        self._lower.close()
        super().close()


class _Transcode(_Layer):
    """A UTF-16 byte stream presented as UTF-8 (undecodable units become U+FFFD)."""

    def __init__(self, lower: IO[bytes], encoding: str) -> None:
        super().__init__()
        self._lower = lower
        self._decoder = codecs.getincrementaldecoder(encoding)(errors="replace")
        self._pending = b""
        self._eof = False

    def _read_some(self, view: memoryview) -> int:
        while not self._pending:
            if self._eof:
                return 0
            block = self._lower.read(1 << 20)
            self._eof = not block
            self._pending = self._decoder.decode(block, final=self._eof).encode("utf-8")
        n = min(len(view), len(self._pending))
        view[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n

    def close(self) -> None:
        self._lower.close()
        super().close()


class _CrToLf(_Layer):
    """CR-only line ends read as LF (the byte count does not change)."""

    def __init__(self, lower: IO[bytes]) -> None:
        super().__init__()
        self._lower = lower

    def _read_some(self, view: memoryview) -> int:
        n: int = self._lower.readinto(view)  # type: ignore[attr-defined]
        if n:
            view[:n] = bytes(view[:n]).replace(b"\r", b"\n")
        return n

    def close(self) -> None:
        self._lower.close()
        super().close()


# ------------------------------------------------------------------ streams


class _SharedStream:
    """A non-seekable input, opened once per process.

    The bytes read from it are kept while they fit under
    :data:`REPLAY_LIMIT_BYTES`, so that every :class:`_Replay` reader starts
    at byte 0.  Past that, only one reader can go on.
    """

    def __init__(self, file: IO[bytes], name: str, owned: bool) -> None:
        self.file = file
        self.name = name
        self.owned = owned  # opened by us (a FIFO); standard input is not ours to close
        self.kept = bytearray()
        self.overflowed = False
        self.live_pos = 0


class _Replay(_Layer):
    """One reader of a :class:`_SharedStream`, from byte 0; ``tell`` counts bytes read."""

    def __init__(self, shared: _SharedStream) -> None:
        super().__init__()
        self._shared = shared
        self._pos = 0

    def tell(self) -> int:
        return self._pos

    def _read_some(self, view: memoryview) -> int:
        s = self._shared
        if self._pos < len(s.kept) and not s.overflowed:
            n = min(len(view), len(s.kept) - self._pos)
            view[:n] = s.kept[self._pos : self._pos + n]
        else:
            if self._pos != s.live_pos:
                raise InputError(
                    f"{s.name}: a stream can be read only once past its first "
                    f"{REPLAY_LIMIT_BYTES >> 20} MiB; give a file instead"
                )
            n = s.file.readinto(view)  # type: ignore[attr-defined]
            n = n or 0
            if n and not s.overflowed:
                if len(s.kept) + n <= REPLAY_LIMIT_BYTES:
                    s.kept += view[:n]
                else:
                    s.overflowed = True
                    s.kept = bytearray()
            s.live_pos += n
        self._pos += n
        return n

    def close(self) -> None:
        # The stream stays open for the next reader (released by release_streams).
        super().close()


_streams: dict[tuple[str, int, int], _SharedStream] = {}


def release_streams() -> None:
    """Close the streams opened so far (FIFOs, process substitutions); a command calls this when done."""
    for shared in _streams.values():
        if shared.owned:
            shared.file.close()
    _streams.clear()


def _open_shared(path: Path, st: os.stat_result | None) -> _Replay:
    if str(path) == STDIN_NAME:
        stdin = sys.stdin.buffer
        key = (STDIN_NAME, id(stdin), 0)
        if key not in _streams or _streams[key].file is not stdin:
            _streams[key] = _SharedStream(stdin, "standard input", owned=False)
        return _Replay(_streams[key])
    assert st is not None
    key = (str(path), st.st_dev, st.st_ino)
    if key not in _streams:
        try:
            file = open(path, "rb", buffering=0)  # noqa: SIM115 - kept open for later readers
        except OSError as exc:
            raise InputError(f"{path}: cannot open ({exc.strerror or exc})") from None
        _streams[key] = _SharedStream(file, str(path), owned=True)
    return _Replay(_streams[key])


def _read_head(stream: Any, size: int) -> bytes:
    """Up to ``size`` bytes (fewer only at the end or at a read failure, which is held back)."""
    parts: list[bytes] = []
    got = 0
    while got < size:
        try:
            piece = stream.read(size - got)
        except _LAYER_ERRORS:
            break
        if not piece:
            break
        parts.append(piece)
        got += len(piece)
    return b"".join(parts)


def utf16_without_bom(head: bytes) -> str | None:
    """``"utf-16-le"`` / ``"utf-16-be"`` when the head reads as BOM-less UTF-16 text, else None.

    Text in UTF-16 is mostly ASCII or Latin: one byte of each 2-byte unit is
    NUL, always on the same side.  UTF-8 and 8-bit text have no NULs at all.
    """
    units = len(head) // 2
    if units == 0:
        return None
    even, odd = head[0 : units * 2 : 2], head[1 : units * 2 : 2]
    le = sum(1 for a, b in zip(even, odd, strict=True) if a and not b)
    be = sum(1 for a, b in zip(even, odd, strict=True) if b and not a)
    if le >= _UTF16_MIN_SHARE * units:
        return "utf-16-le"
    if be >= _UTF16_MIN_SHARE * units:
        return "utf-16-be"
    return None


def open_input(path: Path | str) -> tuple[IO[bytes], IO[bytes], SourceInfo]:
    """Open an input for reading bytes; returns (stream, underlying raw input, info).

    ``path`` is a file, ``-`` for standard input, or a FIFO / device such as
    ``/dev/stdin``.  The raw input's ``tell()`` gives progress in bytes as
    stored (compressed).  Close both when done.  :class:`InputError` when it
    cannot be opened at all.
    """
    path = Path(path)
    info = SourceInfo()
    st: os.stat_result | None = None
    if str(path) != STDIN_NAME:
        try:
            st = os.stat(path)
        except FileNotFoundError:
            raise InputError(f"{path}: no such file") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot open ({exc.strerror or exc})") from None
        if stat.S_ISDIR(st.st_mode):
            raise InputError(f"{path}: is a directory, expected a log file")
    raw: Any
    if st is not None and stat.S_ISREG(st.st_mode):
        try:
            raw = path.open("rb")
        except OSError as exc:
            raise InputError(f"{path}: cannot open ({exc.strerror or exc})") from None
    else:
        raw = _open_shared(path, st)
        info.stream = True
    head = _read_head(raw, HEAD_BYTES)
    seekable = not info.stream
    if seekable:
        raw.seek(0)
        lower: Any = raw
    else:
        lower = _Prefixed(head, raw)
    if head.startswith(GZIP_MAGIC):
        info.compressed = True
        gz = _Gunzip(lower, str(path))
        head = _read_head(gz, HEAD_BYTES)
        lower = _Prefixed(head, gz)
    stream = lower
    transformed = not seekable or info.compressed
    if head.startswith(BLF_MAGIC):
        encoding = None
    elif head.startswith(UTF16_BOMS):
        encoding = "utf-16"
    else:
        encoding = utf16_without_bom(head)
    if encoding is not None:
        info.encoding = encoding
        stream = _Transcode(stream, encoding)
        head = head.decode(encoding, errors="replace").encode("utf-8")
        transformed = True
    elif head.startswith(UTF8_BOM):
        info.encoding = "utf-8-sig"
        stream.read(len(UTF8_BOM))
        head = head[len(UTF8_BOM) :]
    # CR-only line ends (classic Mac exports): text, never binary (a receiver's UBX stream may hold CRs and
    # no LF in its first bytes; its zero bytes tell it from text, and CRs inside its packets must stay CRs).
    if b"\r" in head and b"\n" not in head and b"\0" not in head and not head.startswith(BLF_MAGIC):
        info.line_ends = "cr"
        stream = _CrToLf(stream)
        transformed = True
    if not transformed:
        return raw, raw, info  # a plain file: the parser reads it directly, no layer in between
    return stream, raw, info


# ------------------------------------------------------------------ chunks


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

    A read that fails (corrupt or truncated gzip, an I/O error) ends the
    iteration with one :class:`ReadFailure` after the complete lines before
    it; the unfinished line it cut is not delivered as a line.

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
        except _LAYER_ERRORS as exc:
            yield _failure(exc, carry, skipping, info)
            return
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


def _failure(exc: BaseException, carry: bytes, skipping: OverlongLine | None, info: SourceInfo) -> ReadFailure:
    if isinstance(exc, CorruptInput):
        detail = exc.detail
    elif isinstance(exc, InputError):
        detail = str(exc)
    else:
        what = "corrupt gzip" if info.compressed else "read failed"
        detail = f"{what} ({type(exc).__name__}: {exc})"
    if skipping is not None:
        return ReadFailure(skipping.head, skipping.length, detail)
    return ReadFailure(carry[:200], len(carry), detail)
