"""``file:PATH`` — follow a growing log like ``tail -F``.

* Starts at the end (after the last complete line) or, with ``from_start``,
  at the beginning.
* Hands over complete lines only: an unfinished last line waits for its
  newline.
* Rotation (the file renamed, a new one created under the name): the old
  file is read to its end through the still-open descriptor, then the new
  one from its start.
* Truncation (``copytruncate``): noticed when the file is shorter than what
  was read, or when the bytes just before the read position changed (the
  file was truncated and has grown again since).  Whatever the writer added
  between our last read and the copy is taken from the copy (a sibling file
  whose content starts with what we read), so nothing is lost or repeated.
* Wakes on inotify through watchfiles; polls when watchfiles cannot watch.

What the lines are is recognised per file (:mod:`console.inputs.file_lines`):
a diagnostic log's lines go on as :class:`LineBlock`, a GNSS file's as
fixes, a CAN or sensor frame log's as frames.
"""

from __future__ import annotations

import contextlib
import os
import stat
import threading
import time
from pathlib import Path
from typing import Any

from console.inputs.base import Item, LineBlock, Source, SourceError
from console.inputs.file_lines import FileLines
from parsers.kinds import HEAD_BYTES

READ_BYTES = 1 << 20
MAX_LINE_BYTES = 4 << 20
PIECE_BYTES = 64 << 10
SIGNATURE_BYTES = 64
POLL_S = 0.05  # without inotify: 20 stat calls a second, negligible CPU
CHECK_S = 1.0  # with inotify: a safety re-check, in case an event was missed


class FileSource(Source):
    kind = "file"

    def __init__(self, uri: str, path: Path, from_start: bool = False, force_polling: bool = False) -> None:
        super().__init__(uri)
        self.path = path
        self.from_start = from_start
        self.force_polling = force_polling
        self._fd: int | None = None
        self._ident: tuple[int, int] | None = None
        self._pos = 0
        self._line = 1
        self._carry = b""
        self._overlong = False  # inside a runaway line whose start was handed over
        self._head = b""  # first bytes of the current file, to recognise its copy
        self._tail = b""  # last bytes read, to notice truncate-and-regrow
        self._generation = 0
        self._wake = threading.Event()
        self.rotations = 0
        self.truncations = 0
        self.watching = "poll"
        self.files = FileLines(self, path)

    def check(self) -> None:
        if self.path.is_dir():
            raise SourceError(f"{self.path}: is a directory, expected a log file")
        with contextlib.suppress(OSError):  # not there yet: waited for
            if not stat.S_ISREG(os.stat(self.path).st_mode):
                # A pipe cannot be read again from a position (the source stopped: "Illegal seek").
                raise SourceError(f"{self.path}: not a regular file (a pipe or a device), expected a log file")
        if not self.path.parent.is_dir():
            raise SourceError(f"{self.path}: no such directory {self.path.parent}")

    @property
    def bytes_read(self) -> int:
        """How far the current file has been read (its size once the reader has caught up)."""
        return self._pos

    @property
    def label(self) -> str:
        return str(self.path) if self._generation <= 1 else f"{self.path}#{self._generation}"

    # -- thread ------------------------------------------------------------
    def run(self) -> None:
        watcher = None if self.force_polling else self._start_watcher()
        first = True
        while not self.stopping:
            self._pump(first)
            first = False
            self._wake.wait(CHECK_S if watcher is not None and watcher.is_alive() else POLL_S)
            self._wake.clear()
        if not self.abandoned:
            self._pump(first)  # still first when stopped before the loop ran: the file is then met at its end
            self._flush_carry("end")
            self._hand_over(self.files.finish())
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def interrupt(self) -> None:
        self._wake.set()

    def _start_watcher(self) -> threading.Thread | None:
        try:
            import watchfiles
        except ImportError:
            return None
        name = self.path.name

        def ours(_change: object, p: str) -> bool:
            # The file and its rotated siblings (log.1, log-20260101…), nothing else in the directory.
            return Path(p).name.startswith(name)

        def body() -> None:
            try:
                for changes in watchfiles.watch(
                    self.path.parent,
                    watch_filter=ours,
                    stop_event=self._stop,
                    debounce=25,
                    step=10,  # the watcher thread wakes this often (ms): latency vs idle CPU
                    rust_timeout=500,
                    yield_on_timeout=True,
                    recursive=False,
                    ignore_permission_denied=True,
                ):
                    if changes:
                        self._wake.set()
            except Exception as exc:  # inotify unavailable or exhausted: the loop polls instead
                self.note("info", f"inotify unavailable ({exc}); polling")
                self.watching = "poll"

        t = threading.Thread(target=body, name=f"watch {self.path}", daemon=True)
        t.start()
        self.watching = "inotify"
        return t

    # -- reading -----------------------------------------------------------
    def _pump(self, first: bool) -> None:
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            if self._fd is not None:
                self._read_to_end()  # renamed away, the new one not there yet: finish the old
            self.set_connected(False, "waiting for the file")
            return
        except OSError as exc:
            self.set_connected(False, f"cannot stat: {exc.strerror}")
            return
        if not stat.S_ISREG(st.st_mode):
            # Replaced by a directory or a FIFO: reading a directory raised and stopped the source for good,
            # opening a FIFO would block it.  Finish the old file; wait for a log file there again.
            if self._fd is not None:
                self._read_to_end()
            self.set_connected(False, "not a regular file there; waiting for the log file")
            return
        ident = (st.st_dev, st.st_ino)
        if self._fd is None:
            self._open(first)
        elif ident != self._ident:
            self._read_to_end()
            self._flush_carry("rotated")
            os.close(self._fd)
            self._fd = None
            self.rotations += 1
            self.note("rotated", f"{self.path} was rotated; reading the new file from its start")
            self._open(False)
        elif st.st_size < self._pos or not self._same_tail():
            self._truncated()
        self._read_to_end()

    def _open(self, first: bool) -> None:
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except OSError as exc:
            self.set_connected(False, f"cannot open: {exc.strerror}")
            return
        st = os.fstat(fd)
        self._fd, self._ident = fd, (st.st_dev, st.st_ino)
        self._generation += 1
        self._pos, self._line, self._carry, self._tail = 0, 1, b"", b""
        self._overlong = False
        self._head = os.pread(fd, SIGNATURE_BYTES, 0)
        skipped = b""
        if first and not self.from_start:
            self._skip_to_end(st.st_size)
            # The lines skipped are not delivered, but the first of them tell what the file is.
            skipped = os.pread(fd, min(HEAD_BYTES, self._pos), 0)
            skipped = skipped[: skipped.rfind(b"\n") + 1]
        self.set_connected(True, f"following ({self.watching})")
        self._hand_over(self.files.start(self.label, skipped))

    def _skip_to_end(self, size: int) -> None:
        """Start after the last complete line, counting the lines skipped (numbers stay true)."""
        assert self._fd is not None
        pos = lines = 0
        last_nl = 0
        while pos < size:
            block = os.pread(self._fd, min(READ_BYTES, size - pos), pos)
            if not block:
                break
            lines += block.count(b"\n")
            nl = block.rfind(b"\n")
            if nl >= 0:
                last_nl = pos + nl + 1
            pos += len(block)
        self._pos = last_nl
        self._line = 1 + lines
        self._tail = os.pread(self._fd, min(SIGNATURE_BYTES, last_nl), last_nl - min(SIGNATURE_BYTES, last_nl))

    def _same_tail(self) -> bool:
        if self._fd is None or not self._tail:
            return True
        k = len(self._tail)
        return os.pread(self._fd, k, self._pos - k) == self._tail

    def _truncated(self) -> None:
        """copytruncate: take what we missed from the copy, then start the file again."""
        assert self._fd is not None
        copy = self._find_copy()
        if copy is not None:
            with copy.open("rb") as f:
                f.seek(self._pos)
                while block := f.read(READ_BYTES):
                    self._deliver(block)
        self._flush_carry("truncated")
        self.truncations += 1
        where = f"; the rest of the old content read from {copy.name}" if copy else ""
        self.note("truncated", f"{self.path} was truncated (copytruncate){where}; reading again from its start")
        self._generation += 1
        self._pos, self._line, self._tail = 0, 1, b""
        self._head = os.pread(self._fd, SIGNATURE_BYTES, 0)
        self._hand_over(self.files.start(self.label, b""))

    def _find_copy(self) -> Path | None:
        """A sibling that starts like the file did and holds at least what we read."""
        try:
            siblings = sorted(
                (p for p in self.path.parent.iterdir() if p.name.startswith(self.path.name) and p != self.path),
                key=lambda p: p.stat().st_mtime,
                reverse=True,
            )
        except OSError:
            return None
        for p in siblings[:5]:
            try:
                with p.open("rb") as f:
                    if f.read(len(self._head)) != self._head:
                        continue
                    k = len(self._tail)
                    f.seek(max(0, self._pos - k))
                    if f.read(k) == self._tail and p.stat().st_size >= self._pos:
                        return p
            except OSError:
                continue
        return None

    def _read_to_end(self) -> None:
        if self._fd is None:
            return
        while not self.abandoned:
            block = os.pread(self._fd, READ_BYTES, self._pos)
            if not block:
                return
            self._pos += len(block)
            if len(self._head) < SIGNATURE_BYTES:
                self._head = os.pread(self._fd, SIGNATURE_BYTES, 0)
            self._tail = (self._tail + block)[-SIGNATURE_BYTES:]
            self._deliver(block)

    def _deliver(self, block: bytes) -> None:
        if self._overlong:
            # The rest of a runaway line already handed over (as one line, as a batch read counts it).
            nl = block.find(b"\n")
            if nl < 0:
                return
            self._overlong, block = False, block[nl + 1 :]
        data = self._carry + block if self._carry else block
        cut = data.rfind(b"\n") + 1
        if cut == 0:
            self._carry = data
            if len(data) > MAX_LINE_BYTES:  # a runaway line: hand it over, the parser rejects it
                self._flush_carry("overlong")
                self._overlong = True
            return
        self._carry = data[cut:]
        self._emit(data[:cut])

    def _emit(self, lines: bytes) -> None:
        start = 0
        while start < len(lines):
            # A file read here (not a diagnostic log: the engine parses those) goes in pieces, so that
            # its items, and the count of its lines, keep flowing while a big file is read.
            cut = len(lines)
            if self.files.kind != "diag" and cut - start > PIECE_BYTES:
                cut = lines.rfind(b"\n", start, start + PIECE_BYTES) + 1
                if cut <= start:  # one line longer than a piece
                    cut = lines.index(b"\n", start) + 1
            piece = lines[start:cut] if start or cut < len(lines) else lines
            n = piece.count(b"\n")
            block = LineBlock(self.uri, self.label, self._line, piece, time.monotonic())
            self._line += n
            self.count_messages(n)
            self._hand_over(self.files.lines(block))
            start = cut

    def _hand_over(self, items: list[Item]) -> None:
        for item in items:
            self.emit(item, messages=0)

    def file_reports(self) -> list[dict[str, Any]]:
        return self.files.reports()

    def _flush_carry(self, why: str) -> None:
        """An unfinished line when the file ends for good: handed over, so it is accounted for."""
        if self._carry:
            carry, self._carry = self._carry, b""
            self.note("info", f"{self.label} line {self._line}: unfinished line ({len(carry)} bytes) at {why}")
            self._emit(carry + b"\n")
