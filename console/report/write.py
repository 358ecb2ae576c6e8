"""Atomic file writes: a reader sees the old report or the new one, never half of one.

The bytes go to a temporary file in the target's own directory (so the
final rename never crosses a file system), written as they are made
(:func:`atomic_file`), then flushed and fsynced, and the temporary file is
renamed over the target with :func:`os.replace`, which is atomic on POSIX
and on Windows.  The directory is fsynced too, so the rename survives a
power cut.  On any failure (an error, Ctrl-C, SIGTERM) the temporary file is
removed and the old target is left untouched.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO


def _new_file_mode(target: Path) -> int:
    """The mode the target would get from a plain open(): kept from the old file, else 0666 & ~umask."""
    try:
        return stat.S_IMODE(target.stat().st_mode)
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _fsync_directory(directory: Path) -> None:
    # Best effort: not every platform or file system lets a directory be opened.
    flags = getattr(os, "O_DIRECTORY", None)
    if flags is None:
        return
    try:
        fd = os.open(directory, os.O_RDONLY | flags)
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):
            os.fsync(fd)
    finally:
        os.close(fd)


@contextmanager
def atomic_file(target: Path) -> Iterator[BinaryIO]:
    """A new file to write in pieces; it replaces ``target`` when the block ends without an error.

    OSError on failure; on any exception the temporary file is removed and ``target`` is untouched.
    """
    directory = target.parent if str(target.parent) else Path(".")
    mode = _new_file_mode(target)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    _fsync_directory(directory)


def write_atomic(target: Path, data: bytes) -> None:
    """Replace ``target`` with ``data`` atomically (OSError on failure, target untouched)."""
    with atomic_file(target) as f:
        f.write(data)
