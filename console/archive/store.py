"""Where the archive lives on disk, its manifest, the writers' lock and publishing.

Layout of an archive directory::

    CURRENT                      name of the current manifest (atomically replaced)
    manifests/manifest-000007.json
    data/<table>/day=YYYY-MM-DD/device_id=<n>/g000007-0003.parquet
    tmp/                         scratch of a running ingest (never read)
    lock                         fcntl.flock: one writer at a time

Readers open ``CURRENT``, then only the files its manifest lists.  A writer
writes new Parquet parts under fresh names (the generation is in the name),
fsyncs them, writes the next manifest, fsyncs it, and renames a new
``CURRENT`` over the old one: a ``kill -9`` at any moment leaves either the
old manifest current (the new parts are unlisted garbage) or the new one
(every part it lists is complete on disk).  Garbage is removed by the next
writer, under the lock.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import stat
import time
from collections.abc import Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from console.safe_text import show_path

SCHEMA = "trackside.archive"
SCHEMA_VERSION = 1
CURRENT = "CURRENT"
MANIFESTS = "manifests"
DATA = "data"
TMP = "tmp"
LOCK = "lock"
# Manifests kept besides the current one: a query that opened the previous
# manifest just before an ingest published still finds its files.
KEEP_MANIFESTS = 2


class ArchiveError(Exception):
    """An archive that cannot be used as asked: one line for the user, exit 2."""


class ArchiveDamaged(ArchiveError):
    """The archive's own pointer or manifest is damaged (emptied, cut, edited by hand): ``verify`` says so with
    exit 1, as of any damage it finds; the other commands cannot read the archive (exit 2)."""


class ArchiveBusy(ArchiveError):
    """Another ingest holds the lock (and --no-wait was given)."""


def archive_dir(given: Path | None) -> Path:
    """``--archive DIR``, else ``$TRACKSIDE_ARCHIVE``, else ``$XDG_DATA_HOME/trackside/archive``."""
    if given is not None:
        return given
    env = os.environ.get("TRACKSIDE_ARCHIVE")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(xdg) / "trackside" / "archive"


@dataclass
class Manifest:
    """One published state of the archive: the Parquet parts of every table and the ingest ledger."""

    generation: int = 0
    tables: dict[str, list[str]] = field(default_factory=dict)  # table → parts, relative to the archive
    files: list[dict[str, Any]] = field(default_factory=list)  # the ledger: one entry per logical input file
    derived: dict[str, Any] = field(default_factory=dict)  # settings the derived tables were computed with
    schema_version: int = SCHEMA_VERSION
    created: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": f"{SCHEMA}/{self.schema_version}",
            "schema_version": self.schema_version,
            "generation": self.generation,
            "created": self.created,
            "tables": {k: sorted(v) for k, v in sorted(self.tables.items())},
            "files": self.files,
            "derived": self.derived,
        }

    @classmethod
    def from_dict(cls, doc: dict[str, Any]) -> Manifest:
        """TypeError or ValueError where a field is not of its kind (a part's name not a string, …)."""
        version = int(doc.get("schema_version", 0))
        doc = migrate(doc, version)
        tables = {str(k): list(v) for k, v in doc["tables"].items()}
        if not all(isinstance(p, str) for parts in tables.values() for p in parts):
            raise TypeError("a part's name is not a string")
        files = list(doc["files"])
        if not all(isinstance(f, dict) for f in files):
            raise TypeError("a file's entry is not an object")
        return cls(
            generation=int(doc["generation"]),
            tables=tables,
            files=files,
            derived=dict(doc.get("derived", {})),
            schema_version=SCHEMA_VERSION,
            created=str(doc.get("created", "")),
        )

    def parts(self, table: str) -> list[str]:
        return self.tables.get(table, [])


def migrate(doc: dict[str, Any], version: int) -> dict[str, Any]:
    """Bring a manifest written by an older trackside up to SCHEMA_VERSION.

    Each step is one function from version n to n+1; a newer archive than
    this trackside knows is refused rather than misread.
    """
    if version > SCHEMA_VERSION:
        raise ArchiveError(
            f"archive schema version {version} is newer than this trackside reads ({SCHEMA_VERSION}): upgrade trackside"
        )
    if version < 1:
        raise ArchiveDamaged(f"not a trackside archive manifest (schema version {version})")
    steps: dict[int, Any] = {}  # e.g. {1: _v1_to_v2}; none yet
    while version < SCHEMA_VERSION:
        doc = steps[version](doc)
        version += 1
    return doc


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def manifest_name(generation: int) -> str:
    return f"manifest-{generation:06d}.json"


def read_current(root: Path) -> Manifest:
    """The published manifest (an empty one for a new or empty archive)."""
    pointer = root / CURRENT
    try:
        name = pointer.read_text(encoding="utf-8").strip()
    except (FileNotFoundError, NotADirectoryError):
        if root.exists() and not root.is_dir():
            # Said of the path given (it was "ROOT/CURRENT: cannot read (Not a directory)").
            raise ArchiveError(f"{root}: not a directory (an archive is a folder)") from None
        return Manifest()
    except OSError as exc:
        raise ArchiveError(f"{pointer}: cannot read ({exc.strerror or exc})") from None
    if not name or "/" in name or name in (".", ".."):
        raise ArchiveDamaged(f"{pointer}: names no manifest ({name!r}): the archive is damaged")
    path = root / MANIFESTS / name
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (FileNotFoundError, NotADirectoryError, ValueError) as exc:  # gone or cut: damage, not a permission
        raise ArchiveDamaged(f"{path}: unreadable manifest ({exc})") from None
    except OSError as exc:
        raise ArchiveError(f"{path}: unreadable manifest ({exc})") from None
    if not isinstance(doc, dict) or not str(doc.get("schema", "")).startswith(SCHEMA + "/"):
        raise ArchiveDamaged(f"{path}: not a trackside archive manifest")
    try:
        return Manifest.from_dict(doc)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        # A manifest edited by hand or damaged on disk: said of the file, never an internal error.
        raise ArchiveDamaged(f"{path}: damaged manifest ({type(exc).__name__}: {exc})") from None


ARCHIVE_ENTRIES = frozenset({CURRENT, MANIFESTS, DATA, TMP, LOCK, f".{CURRENT}.tmp"})


def ensure_layout(root: Path) -> None:
    """``root`` made an archive: a new or empty directory, or an archive already (never a folder of other
    files: ``--archive ""`` is the current directory, and a typo must not scatter an archive among a
    user's files)."""
    if root.exists() and not root.is_dir():
        raise ArchiveError(f"{root}: not a directory")
    try:
        others = sorted(e.name for e in os.scandir(root) if e.name not in ARCHIVE_ENTRIES) if root.exists() else []
    except OSError as exc:
        raise ArchiveError(f"{root}: cannot read the archive ({exc.strerror or exc})") from None
    if others and not (root / CURRENT).exists() and not (root / MANIFESTS).is_dir():
        raise ArchiveError(
            f"{show_path(root)}: holds other files ({show_path(Path(others[0]))}…) and no archive; "
            "give a new or empty directory"
        )
    try:
        for sub in (MANIFESTS, DATA, TMP):
            (root / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ArchiveError(f"{root}: cannot create the archive ({exc.strerror or exc})") from None


# fsyncs in flight at once.  An ingest's parts are a few per day and board (140 files in 133 folders for a
# 3 M-record log of 40 boards): one after the other they took 0.25-0.5 s on a virtual disk, 16 at a time
# 0.03-0.07 s (the journal commits them together).
SYNC_THREADS = 16


def sync_paths(paths: Iterable[Path]) -> None:
    """fsync files (or directories), several at a time."""
    todo = list(paths)
    if len(todo) < 2:
        for p in todo:
            fsync_file(p)
        return
    with ThreadPoolExecutor(min(SYNC_THREADS, len(todo)), thread_name_prefix="fsync") as pool:
        for _ in pool.map(fsync_file, todo):  # the first failure raised
            pass


def sync_parts(root: Path, rels: list[str]) -> None:
    """fsync each part, then each directory holding one: a manifest may name them now."""
    sync_paths(root / rel for rel in rels)
    sync_paths(sorted({(root / rel).parent for rel in rels}))


def publish(root: Path, manifest: Manifest, new_parts: list[str]) -> None:
    """Make ``manifest`` current: fsync its new parts (those :func:`sync_parts` has not), write it, then swap
    CURRENT atomically."""
    sync_parts(root, new_parts)
    manifest.created = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    name = manifest_name(manifest.generation)
    mdir = root / MANIFESTS
    tmp = mdir / f".{name}.tmp"
    payload = json.dumps(manifest.to_dict(), indent=1, ensure_ascii=False).encode("utf-8")
    _write_synced(tmp, payload)
    os.replace(tmp, mdir / name)
    _fsync_dir(mdir)
    pointer_tmp = root / f".{CURRENT}.tmp"
    _write_synced(pointer_tmp, (name + "\n").encode())
    os.replace(pointer_tmp, root / CURRENT)
    _fsync_dir(root)


def _write_synced(path: Path, payload: bytes) -> None:
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        view = memoryview(payload)
        while view:
            n = os.write(fd, view)
            view = view[n:]
        os.fsync(fd)
    finally:
        os.close(fd)


READING = ".reading"  # in a reader's spill folder under tmp/: flock-ed (shared) for as long as it reads


def spill_in_use(folder: Path) -> bool:
    """Whether a reader still holds ``folder`` (its lock on READING): a live read's spill, not a killed one's."""
    try:
        fd = os.open(folder / READING, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # and with it the lock just taken
    return False


def missing_part(root: Path, m: Manifest) -> str | None:
    """The first part ``m`` names that is not a file under ``root`` (None: all there).  A stat each: an ingest
    asks before it builds on the archive (``trackside verify`` reads every part, and counts)."""
    for rels in m.tables.values():
        for rel in rels:
            try:
                if stat.S_ISREG((root / rel).lstat().st_mode):
                    continue
            except OSError:
                pass
            return rel
    return None


def kept_parts(root: Path, current: Manifest) -> tuple[list[str], list[str], set[str]]:
    """(every manifest's name, the kept ones': the current and the KEEP_MANIFESTS before it, the parts they
    name).  A part no kept manifest names is garbage (a killed ingest's, a replaced one)."""
    mdir = root / MANIFESTS
    names = sorted(p.name for p in mdir.glob("manifest-*.json")) if mdir.is_dir() else []
    current_name = manifest_name(current.generation)
    kept = [n for n in names if n <= current_name][-(KEEP_MANIFESTS + 1) :]
    listed: set[str] = {rel for rels in current.tables.values() for rel in rels}
    for n in kept:
        try:
            doc = json.loads((mdir / n).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        for parts in doc.get("tables", {}).values():
            listed.update(parts)
    return names, kept, listed


def collect_garbage(root: Path, current: Manifest) -> int:
    """Remove what no kept manifest lists: parts of killed ingests, replaced parts, scratch files.

    Runs under the writers' lock.  The previous manifests (KEEP_MANIFESTS)
    and their parts stay, for queries that opened them a moment ago.
    """
    mdir = root / MANIFESTS
    names, kept, listed = kept_parts(root, current)
    removed = 0
    for n in names:
        if n not in kept:
            with contextlib.suppress(OSError):
                (mdir / n).unlink()
                removed += 1
    for p in mdir.glob(".*.tmp"):
        with contextlib.suppress(OSError):
            p.unlink()
    data = root / DATA
    if data.is_dir():
        for dirpath, _dirs, files in os.walk(data, topdown=False):
            for f in files:
                rel = os.path.relpath(os.path.join(dirpath, f), root)
                if rel not in listed:
                    with contextlib.suppress(OSError):
                        os.unlink(os.path.join(dirpath, f))
                        removed += 1
            with contextlib.suppress(OSError):
                os.rmdir(dirpath)  # only succeeds when empty
    tmp = root / TMP
    if tmp.is_dir():
        for p in tmp.iterdir():
            with contextlib.suppress(OSError):
                if p.is_dir():
                    if spill_in_use(p):
                        continue  # a report or replay reading now: DuckDB may spill there yet
                    shutil.rmtree(p)  # a killed ingest's or reader's sort spill
                else:
                    p.unlink()
                removed += 1
    return removed


@contextlib.contextmanager
def writer_lock(root: Path, wait: bool = True, on_wait: Any = None) -> Iterator[None]:
    """Hold the archive's writer lock; a second ingest waits (``on_wait`` is told) or fails clearly."""
    ensure_layout(root)
    fd = os.open(root / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if not wait:
                raise ArchiveBusy(
                    f"{root}: another ingest is writing this archive (try again, or drop --no-wait)"
                ) from None
            if on_wait is not None:
                on_wait()
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # closing releases the lock
