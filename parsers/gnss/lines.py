"""Lines of a GNSS file, counted: the reading every GNSS parser shares.

Built on :mod:`parsers.sources` (plain, gzip, UTF-8 BOM, UTF-16 with a BOM).
Two more shapes exports arrive in are handled here:

* UTF-16 without a BOM (LE or BE): recognised from the head, where every
  other byte of ASCII text is NUL in a regular pattern, and transcoded;
* CR-only line ends (classic Mac exports): when the head holds CRs and no
  LF, each CR ends a line.

Lines are yielded with their line end (``raw``) so that binary packets that
happen to contain 0x0A can be put back together; :func:`text_of` strips it.
"""

from __future__ import annotations

import codecs
import io
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from parsers.report import FileReport, ParseReport
from parsers.sources import OverlongLine, ReadFailure, SourceInfo, iter_chunks, open_input

HEAD_BYTES = 64 * 1024


class _Prefixed(io.RawIOBase):
    """A stream whose first bytes were already read: served again, then the rest, optionally transcoded."""

    def __init__(self, head: bytes, rest: IO[bytes], *, cr_to_lf: bool = False, utf16: str = "") -> None:
        self._rest = rest
        self._cr_to_lf = cr_to_lf
        self._decoder = codecs.getincrementaldecoder(utf16)(errors="replace") if utf16 else None
        self._pending = self._convert(head)

    def _convert(self, data: bytes, final: bool = False) -> bytes:
        if self._decoder is not None:
            data = self._decoder.decode(data, final).encode("utf-8")
        if self._cr_to_lf:
            data = data.replace(b"\r", b"\n")
        return data

    def readable(self) -> bool:
        return True

    def readinto(self, b: bytearray | memoryview) -> int:  # type: ignore[override]
        while len(self._pending) < len(b):
            more = self._rest.read(1 << 20)
            if not more:
                if self._decoder is not None:
                    self._pending += self._convert(b"", final=True)
                    self._decoder = None
                break
            self._pending += self._convert(more)
        n = min(len(b), len(self._pending))
        b[:n] = self._pending[:n]
        self._pending = self._pending[n:]
        return n


def utf16_without_bom(head: bytes) -> str:
    """``"utf-16-le"``/``"utf-16-be"`` when the head looks like BOM-less UTF-16 text, else ``""``."""
    sample = head[: 4096 - (len(head[:4096]) % 2)]
    if len(sample) < 4:
        return ""
    even, odd = sample[0::2], sample[1::2]
    # ASCII text in UTF-16: NUL in one byte of (nearly) every pair, almost never in the other.
    if odd.count(0) >= 0.9 * len(odd) and even.count(0) <= 0.05 * len(even):
        return "utf-16-le"
    if even.count(0) >= 0.9 * len(even) and odd.count(0) <= 0.05 * len(odd):
        return "utf-16-be"
    return ""


def open_gnss_stream(path: Path) -> tuple[IO[bytes], IO[bytes], str, bool]:
    """(stream of UTF-8-ish bytes with LF line ends, raw file, encoding, compressed)."""
    # parsers.sources recognises UTF-16 without a BOM and CR-only line ends itself, and holds a corrupt
    # gzip's failure back until the lines before it are read: no second layer (it lost those lines).
    stream, raw, info = open_input(path)
    encoding = info.encoding + (" (CR line ends)" if info.line_ends == "cr" else "")
    return stream, raw, encoding, info.compressed


def open_lines(
    path: Path, report: ParseReport, *, keep_ends: bool = False
) -> tuple[FileReport, Iterator[tuple[int, bytes]]]:
    """Open a file: its :class:`FileReport` (appended to ``report``) and its lines.

    The iterator yields (line number, line) and counts ``lines_read``; the
    caller counts each yielded line as a record, blank or rejection.  A line
    is yielded without its end, or with it (``\\n``, as read) if
    ``keep_ends``.  Lines too long to be a GNSS record are rejected here.
    :class:`parsers.sources.InputError` if the file cannot be read.
    """
    stream, raw, encoding, compressed = open_gnss_stream(path)
    name = str(path)
    fr = FileReport(file=name, encoding=encoding, compressed=compressed)
    report.files.append(fr)

    def lines() -> Iterator[tuple[int, bytes]]:
        source = SourceInfo()
        number = 0
        try:
            for item in iter_chunks(stream, source, name=name):
                if isinstance(item, ReadFailure):  # corrupt gzip: the lines before it are kept
                    number += 1
                    fr.lines_read += 1
                    report.reject(fr, number, "corrupt", item.message(number - 1), item.head)
                    continue
                if isinstance(item, OverlongLine):
                    number += 1
                    fr.lines_read += 1
                    reason = f"line of {item.length} bytes is too long to be a GNSS record"
                    report.reject(fr, number, "too long", reason, item.head)
                    continue
                data = bytes(item.data)
                if keep_ends:
                    chunk = split_lf(data)
                else:
                    chunk = data.split(b"\n")
                    if chunk[-1] == b"":
                        chunk.pop()
                for text in chunk:
                    number += 1
                    fr.lines_read += 1
                    yield number, text if keep_ends else text.removesuffix(b"\r")
            fr.bytes_read = raw.tell()
        finally:
            stream.close()
            raw.close()
        fr.ends_without_newline = source.ends_without_newline

    return fr, lines()


def split_lf(data: bytes) -> list[bytes]:
    """Split after every LF only (``splitlines`` would also split at CR, VT, FF, 0x1c-0x1e…)."""
    parts = data.split(b"\n")
    out = [p + b"\n" for p in parts[:-1]]
    if parts[-1]:
        out.append(parts[-1])
    return out


def text_of(raw: bytes) -> bytes:
    """A line without its end."""
    return raw.removesuffix(b"\n").removesuffix(b"\r")
