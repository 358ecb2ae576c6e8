"""Where a command may write: never over an input, never replacing a special file.

Every command that writes files (``report -o``, ``simulate -o``, the future
``ingest``) asks here first:

* the target is the same file as an input (same device and inode, so
  through another spelling of the path, a symlink or a hard link too):
  refused;
* a character device or a FIFO (``-o /dev/stdout``, ``-o >(gzip > x)``):
  written through, opened without creating or truncating, never replaced
  by a regular file;
* a directory where a file is expected, a block device or a socket:
  refused;
* a parent directory that is missing or not writable: refused before any
  work is done.

A regular file is written atomically, in pieces into a temporary file
(:func:`open_output`, :func:`atomic_file`): a reader,
or an interrupted run, sees the old file or the new one,
never half of one.  A symlink to a regular file keeps being a link: the
file it points to is replaced.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import shutil
import socket
import stat
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from console.safe_text import show_path

STDOUT = "-"


class OutputError(Exception):
    """An output path the command refuses: one line for the user, exit 2."""


@dataclass(frozen=True)
class OutputTarget:
    """A checked output file: ``path`` to write, ``stream`` when it is a device or FIFO written through."""

    path: Path
    stream: bool = False


def file_identity(path: Path) -> tuple[int, int] | None:
    """(st_dev, st_ino) of what ``path`` names after following links; None when it names nothing."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def input_identities(inputs: Iterable[Path]) -> dict[tuple[int, int], Path]:
    """The identity of every regular input file (standard input and streams are never written over)."""
    found: dict[tuple[int, int], Path] = {}
    for p in inputs:
        if os.fsdecode(p) == STDOUT:
            continue
        try:
            st = os.stat(p)
        except (OSError, ValueError):
            continue
        if stat.S_ISREG(st.st_mode):
            found.setdefault((st.st_dev, st.st_ino), p)
    return found


def _refuse_input(target: Path, identity: tuple[int, int] | None, inputs: dict[tuple[int, int], Path]) -> None:
    if identity is not None and identity in inputs:
        given = inputs[identity]
        same = "" if os.fsdecode(given) == os.fsdecode(target) else f" (the same file as {show_path(given)})"
        raise OutputError(f"{show_path(target)}: is an input{same}; refusing to write over it")


def _check_parent(target: Path, what: str) -> None:
    parent = target.parent if str(target.parent) else Path(".")
    try:
        st = os.stat(parent)
    except FileNotFoundError:
        raise OutputError(f"{show_path(parent)}: no such directory for the {what}") from None
    except OSError as exc:
        raise OutputError(f"{show_path(parent)}: cannot write the {what} there ({exc.strerror or exc})") from None
    if not stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{show_path(parent)}: not a directory, cannot hold the {what}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{show_path(parent)}: directory not writable, cannot write the {what} there")


def check_output_file(target: Path, inputs: Iterable[Path], what: str = "output") -> OutputTarget:
    """``target`` checked as an output file against ``inputs`` (files read); OutputError when refused."""
    known = input_identities(inputs)
    try:
        st = os.stat(target)
    except FileNotFoundError:
        if os.path.islink(target):
            # A dangling link: writing would replace the link, not create what it names.
            raise OutputError(f"{show_path(target)}: a symlink to nothing, not writing through it") from None
        _check_parent(target, what)
        return OutputTarget(target)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OutputError(f"{show_path(target)}: symlink loop") from None
        raise OutputError(f"{show_path(target)}: cannot write the {what} ({exc.strerror or exc})") from None
    _refuse_input(target, (st.st_dev, st.st_ino), known)
    mode = st.st_mode
    if stat.S_ISDIR(mode):
        raise OutputError(f"{show_path(target)}: is a directory, expected a file name for the {what}")
    if stat.S_ISCHR(mode) or stat.S_ISFIFO(mode):
        return OutputTarget(target, stream=True)
    if not stat.S_ISREG(mode):
        kind = "a block device" if stat.S_ISBLK(mode) else "a socket" if stat.S_ISSOCK(mode) else "a special file"
        raise OutputError(f"{show_path(target)}: is {kind}, not writing the {what} there")
    real = Path(os.path.realpath(target))
    _check_parent(real, what)
    return OutputTarget(real)


def check_outside(target: Path, directory: Path, what: str = "output") -> None:
    """OutputError when ``target`` lies inside ``directory`` (an archive the command reads), through links too."""
    home = file_identity(directory)
    if home is None:
        return
    here = Path(os.path.realpath(target)).parent
    for folder in (here, *here.parents):
        if file_identity(folder) == home:
            raise OutputError(
                f"{show_path(target)}: inside {show_path(directory)}, which is read; not writing the {what} there"
            )


def check_output_directory(target: Path, what: str = "output") -> None:
    """``target`` usable as a directory to write into (it may not exist yet); OutputError when not."""
    try:
        st = os.stat(target)
    except FileNotFoundError:
        if os.path.islink(target):
            raise OutputError(f"{show_path(target)}: a symlink to nothing, not writing through it") from None
        _check_parent(target, what)
        return
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise OutputError(f"{show_path(target)}: symlink loop") from None
        raise OutputError(f"{show_path(target)}: cannot write the {what} ({exc.strerror or exc})") from None
    if not stat.S_ISDIR(st.st_mode):
        raise OutputError(f"{show_path(target)}: exists and is not a directory")
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputError(f"{show_path(target)}: directory not writable")


RUN_MARKER = "truth.json"
RUN_SCHEMA_PREFIX = "trackside.truth/"


def files_below(directory: Path) -> list[Path]:
    """Every file below ``directory`` (not directories, not a stage of ours); empty when it does not exist."""
    if not directory.is_dir():
        return []
    return sorted(
        p
        for p in directory.rglob("*")
        if not p.is_dir() and not any(part.startswith(".trackside-") for part in p.relative_to(directory).parts)
    )


def _is_earlier_run(directory: Path) -> bool:
    try:
        doc = json.loads((directory / RUN_MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(doc, dict) and str(doc.get("schema", "")).startswith(RUN_SCHEMA_PREFIX)


def check_run_directory(target: Path, replace: bool, what: str = "run") -> bool:
    """``target`` fit to receive a simulated run; True when it holds an earlier run that ``replace`` lets go.

    A run is a directory of its own: new, or empty (empty folders, such as
    one made for a follower to wait in, do not count), or an earlier run's
    (its ``truth.json``) when ``replace`` is given.  Anything else is refused
    (OutputError), so a run never lands among a user's own files, and never
    silently mixes with an earlier run's.
    """
    check_output_directory(target, what)
    held = files_below(target)
    if not held:
        return False
    if not _is_earlier_run(target):
        raise OutputError(
            f"{show_path(target)}: holds files that are not a simulated run ({show_path(held[0])}…); "
            f"refusing to write a {what} among them: give a new or empty directory"
        )
    if not replace:
        raise OutputError(f"{show_path(target)}: holds an earlier run; --replace replaces it, or give a new directory")
    return True


def remove_files(files: Iterable[Path]) -> None:
    """Remove ``files`` (an earlier run's); folders stay, a follower may be waiting in them."""
    for f in files:
        with contextlib.suppress(FileNotFoundError):
            f.unlink()


@contextmanager
def staged_directory(
    target: Path, inputs: Iterable[Path], what: str = "output", replace: Iterable[Path] = ()
) -> Iterator[Path]:
    """A hidden directory inside ``target`` to write a run into; its files move into ``target`` on success.

    Nothing half-written is ever left under its final name: on any error,
    Ctrl-C or SIGTERM the stage is removed (and ``target`` too, when this
    call created it and it is still empty).  Before the first file moves,
    each is checked not to replace an input (OutputError otherwise).
    ``replace``: an earlier run's files; those the new run does not write
    again are removed once it is published, so the two never mix.
    """
    check_output_directory(target, what)
    created = not target.exists()
    target.mkdir(exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".trackside-", dir=target))
    try:
        yield stage
        known = input_identities(inputs)
        moves = [(p, target / p.relative_to(stage)) for p in sorted(stage.rglob("*")) if not p.is_dir()]
        for _, dest in moves:
            _refuse_input(dest, file_identity(dest), known)
            if dest.is_dir():
                raise OutputError(f"{show_path(dest)}: is a directory, cannot write the {what} file there")
        for src, dest in moves:
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dest)
        published = {dest for _, dest in moves}
        remove_files(p for p in replace if p not in published)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
        if created:
            with contextlib.suppress(OSError):
                target.rmdir()  # only when empty: the run failed before anything was published


@contextmanager
def open_output(target: OutputTarget) -> Iterator[BinaryIO]:
    """A checked target to write in pieces: through a device or FIFO, else atomically to a file.

    OSError on failure; a file target keeps its old content unless the block ends without an error.
    """
    if target.stream:
        # No O_CREAT, no O_TRUNC: the special file stays what it is.
        fd = os.open(target.path, os.O_WRONLY | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "wb") as f:
            yield f
        return
    with atomic_file(target.path) as f:
        yield f


# -- atomic files: a reader sees the old output or the new one, never half of one --------------------------


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


def _host() -> str:
    return socket.gethostname().replace(".", "_")[:32]  # a file name has 255 bytes at most


def _remove_stale_temporaries(directory: Path, name: str) -> None:
    """Who writes a temporary file is in its name (``.report.html.HOST-PID.XXXXXXXX.tmp``): a writer killed
    before its rename (kill -9, a power cut) leaves one, removed here, at the next write of the same target,
    once that process is gone.  The host keeps a shared folder's other machines' writes, whose processes are
    not ours to see."""
    host = _host()
    mine = re.compile(rf"\.{re.escape(name)}\.{re.escape(host)}-(\d+)\.[^.]+\.tmp")
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return
    for entry in entries:
        m = mine.fullmatch(entry.name)
        if m is None or int(m[1]) == os.getpid() or _alive(int(m[1])):
            continue
        with contextlib.suppress(OSError):
            os.unlink(entry.path)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's: alive
        return True
    return True


@contextmanager
def atomic_file(target: Path) -> Iterator[BinaryIO]:
    """A new file to write in pieces; it replaces ``target`` when the block ends without an error.

    OSError on failure; on any exception the temporary file is removed and ``target`` is untouched.
    """
    directory = target.parent if str(target.parent) else Path(".")
    mode = _new_file_mode(target)
    _remove_stale_temporaries(directory, target.name)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.{_host()}-{os.getpid()}.", suffix=".tmp", dir=directory)
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
