"""``-``, a FIFO or a character device: a stream read as it comes, until its writer closes it.

``ssh box tail -F /var/log/diag.log | trackside follow -``, ``gpspipe -r | trackside follow -``, a named
FIFO (``mkfifo``), ``/dev/stdin`` or a process substitution (``<(…)``) that is a pipe:

* Bytes are read as they arrive, never by position: there is nothing to seek, so no rotation or
  truncation to notice, and ``--from-start`` changes nothing (a stream is read from where it is).
* What happens to the bytes is the followed file's (:class:`~console.inputs.line_source.LineSource`):
  complete lines only, the kind told from the first lines by the one recogniser, the same parsers.
* End of stream (the writer closed it) ends the source: an unfinished last line is handed over and
  accounted for, the readers of the kind finish, and :attr:`input_ended` says so.
* A named FIFO with no writer yet is waited for (as a file not there yet is).
* Asked to stop (Ctrl-C): what the writer has written (what the pipe holds at that moment) is read and
  analysed, not what it writes after.  Abandoned (a second Ctrl-C): nothing more is read.
* Its reader waits while the engine catches up (the backlog): the pipe fills and its writer waits, so
  memory stays bounded however fast the writer is.
"""

from __future__ import annotations

import array
import contextlib
import fcntl
import os
import select
import stat
import sys
import termios
import threading
from pathlib import Path

from console.inputs.base import SourceError
from console.inputs.line_source import LineSource

STDIN = "-"  # the source spec that means standard input (bare, or file:-)
STDIN_FD = 0
READ_BYTES = 1 << 20  # gathered from the pipe before the lines go on: blocks as big as a file's
PIPE_BYTES = 1 << 20  # Linux's default pipe-max-size: what an unprivileged reader may ask for
WAKE_BYTE = b"w"


class StreamSource(LineSource):
    """Standard input (``path`` is ``-``) or a FIFO / character device at ``path``, read to its end."""

    kind = "stream"

    def __init__(self, uri: str, path: Path) -> None:
        super().__init__(uri, path)
        self.watching = "stream"
        self._fd: int | None = None
        self._wake_r = self._wake_w = -1  # interrupt() writes here: a blocked poll wakes at once (made by run)
        self._wake_lock = threading.Lock()

    @property
    def is_stdin(self) -> bool:
        return str(self.path) == STDIN

    @property
    def label(self) -> str:
        # As the batch commands name standard input in rejections and reports.
        return STDIN if self.is_stdin else str(self.path)

    def identity(self) -> tuple[int, int]:
        """The stream's (device, inode): one pipe given twice, as ``-`` and ``/dev/stdin``, is one."""
        try:
            if self.is_stdin and sys.stdin is None:
                raise OSError
            st = os.fstat(STDIN_FD) if self.is_stdin else os.stat(self.path)
        except OSError:
            return (-1, id(self))  # not there: check says so
        return (st.st_dev, st.st_ino)

    def check(self) -> None:
        if self.is_stdin:
            try:
                if sys.stdin is None:  # closed when we started: fd 0 may since be a file of ours
                    raise OSError
                os.fstat(STDIN_FD)
            except OSError:
                raise SourceError("-: standard input is closed") from None
            if os.isatty(STDIN_FD):
                raise SourceError(
                    "-: standard input is a terminal; pipe a log into it (… | trackside follow -) or give a file"
                )
            return
        try:
            st = os.stat(self.path)
        except OSError as exc:
            raise SourceError(f"{self.path}: cannot open ({exc.strerror or exc})") from None
        if stat.S_ISCHR(st.st_mode) and is_this_terminal(st):
            raise SourceError(f"{self.path}: is this terminal; pipe a log into trackside follow - or give a file")

    def interrupt(self) -> None:
        with self._wake_lock:  # never a write to a closed descriptor's number, reused by then
            if self._wake_w >= 0:
                with contextlib.suppress(BlockingIOError):  # the wake pipe is full: woken already
                    os.write(self._wake_w, WAKE_BYTE)

    # -- thread ------------------------------------------------------------
    def run(self) -> None:
        with self._wake_lock:  # a stop asked before this is seen by the loop's first check
            self._wake_r, self._wake_w = os.pipe()
            os.set_blocking(self._wake_w, False)
        try:
            self._open_and_read()
        finally:
            if self._fd is not None and not self.is_stdin:
                os.close(self._fd)
            with self._wake_lock:
                os.close(self._wake_r)
                os.close(self._wake_w)
                self._wake_r = self._wake_w = -1

    def _open_and_read(self) -> None:
        try:
            # Not blocking: a FIFO with no writer yet is waited for in poll, where a stop can wake us.
            self._fd = STDIN_FD if self.is_stdin else os.open(self.path, os.O_RDONLY | os.O_NONBLOCK)
        except OSError as exc:
            self.note("disconnected", f"{self.label}: cannot open: {exc.strerror or exc}")
            self._end(f"cannot open: {exc.strerror or exc}")
            return
        _widen_pipe(self._fd)
        self.set_connected(True, "reading the stream")
        self._hand_over(self.files.start(self.label, b""))
        ended = self._read_until_stopped()
        if not ended and not self.abandoned:
            self._read_what_is_there()
        if not self.abandoned:
            self._flush_carry("end of stream" if ended else "stop")
            self._hand_over(self.files.finish())
        self._end("end of stream (the writer closed it)" if ended else "stopped")

    def _end(self, why: str) -> None:
        # After its last items were handed over: follow may end once they are analysed.
        self.set_ended(f"{self.label}: {why}")

    def _read_until_stopped(self) -> bool:
        """Read as it comes until the stream ends (True) or the source is asked to stop (False)."""
        assert self._fd is not None
        poller = select.poll()
        poller.register(self._fd, select.POLLIN)
        poller.register(self._wake_r, select.POLLIN)
        while not self.stopping:
            poller.poll()  # data, the writer gone (POLLHUP), or a wake-up
            if self.stopping:
                return False
            try:
                block = os.read(self._fd, READ_BYTES)
            except BlockingIOError:  # woken with nothing to read (a FIFO whose writer is not there yet)
                continue
            except OSError as exc:  # a device that fails (EIO): the stream ends here, said so
                self.note("disconnected", f"{self.label} line {self._line}: read failed: {exc.strerror or exc}")
                return True
            if not block:
                return True
            self._deliver(block + self._more(len(block)))
        return False

    def _more(self, have: int) -> bytes:
        """What else is there at once, up to :data:`READ_BYTES`: a pipe gives 64 KiB a read, the engine is
        faster on bigger blocks."""
        assert self._fd is not None
        parts: list[bytes] = []
        while have < READ_BYTES and select.select([self._fd], [], [], 0)[0]:
            try:
                part = os.read(self._fd, READ_BYTES - have)
            except OSError:
                break  # the next read in the loop meets it (EAGAIN: nothing after all)
            if not part:
                break  # end of stream: the next read in the loop sees it
            parts.append(part)
            have += len(part)
        return b"".join(parts)

    def _read_what_is_there(self) -> None:
        """Stopping: what the writer had written by now (the pipe's content) is read, nothing it writes after."""
        assert self._fd is not None
        waiting = array.array("i", [0])
        try:
            fcntl.ioctl(self._fd, termios.FIONREAD, waiting, True)
        except OSError:
            return
        left = waiting[0]
        while left > 0 and not self.abandoned:
            try:
                block = os.read(self._fd, min(READ_BYTES, left))
            except OSError:
                return
            if not block:
                return
            left -= len(block)
            self._deliver(block)


def _widen_pipe(fd: int) -> None:
    """A pipe of :data:`PIPE_BYTES`, not 64 KiB: a fast writer and this reader switch 16× less often."""
    try:
        if stat.S_ISFIFO(os.fstat(fd).st_mode):
            fcntl.fcntl(fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
    except OSError:  # over the system's pipe-max-size, or not allowed: the pipe stays as it is
        pass


def is_this_terminal(st: os.stat_result) -> bool:
    """A character device that is our terminal (``/dev/tty``, or the one standard input is)."""
    if st.st_rdev == os.makedev(5, 0):  # /dev/tty: the controlling terminal, whichever it is
        return True
    try:
        return os.isatty(STDIN_FD) and os.fstat(STDIN_FD).st_rdev == st.st_rdev
    except OSError:
        return False


def is_stream(path: Path) -> bool:
    """A path to read as a stream: a FIFO or a character device (``/dev/stdin`` when it is a pipe too)."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False  # not there (yet): a file to wait for
    return stat.S_ISFIFO(mode) or stat.S_ISCHR(mode)
