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
fixes, a CAN or sensor frame log's as frames.  Cutting the bytes into lines
is :class:`~console.inputs.line_source.LineSource`'s, shared with a stream
(a pipe: :mod:`console.inputs.stream`); this module only says which bytes.
"""

from __future__ import annotations

import os
import stat
import threading
from pathlib import Path

from console.inputs.base import SourceError
from console.inputs.line_source import LineSource
from parsers.kinds import HEAD_BYTES

READ_BYTES = 1 << 20
SIGNATURE_BYTES = 64
POLL_S = 0.05  # without inotify: 20 stat calls a second, negligible CPU
CHECK_S = 1.0  # with inotify: a safety re-check, in case an event was missed


class FileSource(LineSource):
    kind = "file"

    def __init__(self, uri: str, path: Path, from_start: bool = False, force_polling: bool = False) -> None:
        super().__init__(uri, path)
        self.from_start = from_start
        self.force_polling = force_polling
        self._fd: int | None = None
        self._ident: tuple[int, int] | None = None
        self._pos = 0
        self._head = b""  # first bytes of the current file, to recognise its copy
        self._tail = b""  # last bytes read, to notice truncate-and-regrow
        self._generation = 0
        self._wake = threading.Event()
        self._told_not_a_file = False
        self.rotations = 0
        self.truncations = 0

    def check(self) -> None:
        if self.path.is_dir():
            raise SourceError(f"{self.path}: is a directory, expected a log file")
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
            # A directory, FIFO or device made at the path after follow started (an operator's mistake, a rotation
            # gone wrong): reading a directory raises; a FIFO opened here would block, then fail at the first
            # positioned read (given at the start, it is read as a stream: console.inputs.stream).  The old file is
            # finished; a log file there again is read.
            if self._fd is not None:
                self._read_to_end()
            detail = (
                "not a file now (a directory, a FIFO or a device): waiting for the log file; "
                "a FIFO is read when given to follow"
            )
            if not self._told_not_a_file:  # said once, even when it was already "waiting for the file"
                self._told_not_a_file = True
                self.note("disconnected", f"{self.path}: {detail}")
            self.set_connected(False, detail)
            return
        self._told_not_a_file = False
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
        self._restart_lines()
        self._pos, self._tail = 0, b""
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
