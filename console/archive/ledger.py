"""The ingest ledger: what was read from which file, so nothing is read twice.

Each logical input file has one entry in the manifest (``files``): its path,
kind, the byte range read so far (always ending on a line end), the SHA-256
of that prefix, the lines it held, and the parts written from it.  Before a
file is read, :func:`plan` decides what to do with it:

* its whole content hashes to what some entry already holds → **skip**;
* it is an entry's file grown (same path, longer, the stored prefix hashes
  the same) → read **from the stored offset**, line numbers continuing;
* same path but the prefix changed (rotated, rewritten) → a **new file**,
  and the note in ``ingests`` says why;
* otherwise → a new file.

Only complete lines are read: bytes after the last newline are left for the
next ingest (a writer may be in the middle of that line).
"""

from __future__ import annotations

import hashlib
import os
import threading
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from parsers.sources import GZIP_MAGIC, UTF16_BOMS

BLOCK = 1 << 20


@dataclass(frozen=True)
class Scan:
    """One pass over a file's bytes."""

    size: int
    sha256: str  # whole file
    complete_bytes: int  # up to and including the last newline
    complete_sha256: str
    prefix_sha256: str | None  # of the first ``prefix_len`` bytes, when asked
    whole_only: bool  # gzip or UTF-16: read whole or not at all


def scan(
    path: Path, prefix_len: int | None = None, limit: int | None = None, stop: threading.Event | None = None
) -> Scan:
    """Hash a file once: whole, up to its last newline, and a given prefix.

    Each byte is hashed once: the hash up to the last newline is the whole hash as it stood before the
    last block holding a newline, plus that block up to its newline (kept until a later block has one).
    ``limit``: only the file's first ``limit`` bytes (its size when it was planned; it may be growing).
    ``stop``: set by another thread, the scan ends early (its result is then meaningless).
    """
    whole = hashlib.sha256()
    upto_nl = whole.copy()  # the hash up to the last newline so far
    prefix: str | None = None
    pos = 0
    last_nl_end = 0
    head = b""
    # Read into one buffer, hashed through views: a fresh block per read, and a copy of each block up to its
    # newline, cost as much CPU as the hash itself.
    buf = bytearray(BLOCK)
    view = memoryview(buf)
    with path.open("rb") as f:
        while True:
            n = f.readinto(view if limit is None else view[: min(BLOCK, limit - pos)])
            if stop is not None and stop.is_set():
                n = 0
            block = view[:n]
            if prefix_len is not None and prefix is None and pos + n >= prefix_len:
                h = whole.copy()
                h.update(block[: prefix_len - pos])
                prefix = h.hexdigest()
            if not n:
                break
            if pos == 0:
                head = bytes(block[:4])
            nl = buf.rfind(b"\n", 0, n)
            if nl >= 0:
                whole.update(block[: nl + 1])
                upto_nl = whole.copy()
                last_nl_end = pos + nl + 1
                whole.update(block[nl + 1 :])
            else:
                whole.update(block)
            pos += n
    whole_only = head.startswith(GZIP_MAGIC) or head.startswith(UTF16_BOMS)
    if whole_only:
        return Scan(pos, whole.hexdigest(), pos, whole.hexdigest(), prefix, True)
    return Scan(pos, whole.hexdigest(), last_nl_end, upto_nl.hexdigest(), prefix, False)


def try_scan(path: Path, prefix_len: int | None = None) -> Scan | None:
    """:func:`scan`, or None where the file cannot be read (the ingest then scans it itself, and says why)."""
    try:
        return scan(path, prefix_len)
    except OSError:
        return None


@dataclass(frozen=True)
class Sizes:
    """What a file's size and last newline say, read without hashing it (its first and last bytes)."""

    size: int
    complete_bytes: int  # up to and including the last newline (the whole file if read whole only)
    whole_only: bool


def sizes(path: Path) -> Sizes:
    """A file's :class:`Sizes`: its size, its head, and a search for the last newline from the end."""
    with path.open("rb") as f:
        size = os.fstat(f.fileno()).st_size
        head = f.read(4)
        if head.startswith(GZIP_MAGIC) or head.startswith(UTF16_BOMS):
            return Sizes(size, size, True)
        end = size
        while end > 0:
            start = max(0, end - BLOCK)
            f.seek(start)
            block = f.read(end - start)
            nl = block.rfind(b"\n")
            if nl >= 0:
                return Sizes(size, start + nl + 1, False)
            end = start
    return Sizes(size, 0, False)


def new_by_size(files: list[dict[str, Any]], entry: dict[str, Any] | None, z: Sizes) -> Plan | None:
    """The plan of a file the ledger cannot hold yet, proved by sizes alone; None where only its hash can tell.

    A file is skipped only when its content (whole, or up to its last newline) hashes as an entry's whole file
    (``size_seen`` bytes) or an entry's lines (``bytes``); content of another length cannot.  With no entry of
    its path either, :func:`plan` would call it new, whatever its hash: so it can be read while it is hashed.
    """
    if entry is not None:
        return None
    for e in files:
        seen = e.get("size_seen")
        if seen is None or int(seen) in (z.size, z.complete_bytes) or int(e["bytes"]) in (z.size, z.complete_bytes):
            return None
    return Plan("new", None, 0, z.complete_bytes, 0, "new file")


class BackgroundScan:
    """:func:`scan` of a file's first ``size`` bytes on a thread of its own, while the file is parsed
    (hashlib and the reads let go of the GIL: on two cores the hash costs the ingest little wall time)."""

    def __init__(self, path: Path, z: Sizes) -> None:
        self.sizes = z
        self._stop = threading.Event()
        self._future: Future[Scan] = Future()
        self._thread = threading.Thread(target=self._run, args=(path,), name="ingest-hash", daemon=True)
        self._thread.start()

    def _run(self, path: Path) -> None:
        try:
            self._future.set_result(scan(path, None, self.sizes.size, self._stop))
        except BaseException as exc:  # handed to result()
            self._future.set_exception(exc)

    def result(self) -> Scan:
        return self._future.result()

    def changed(self, s: Scan) -> bool:
        """The file changed under the ingest: another size or last line than planned (its bytes were rewritten)."""
        return (s.size, s.complete_bytes, s.whole_only) != (
            self.sizes.size,
            self.sizes.complete_bytes,
            self.sizes.whole_only,
        )

    def cancel(self) -> None:
        self._stop.set()
        self._thread.join()


@dataclass
class Plan:
    action: str  # "skip", "new", "grown", "replace"
    entry: dict[str, Any] | None  # the ledger entry it continues or replaces
    start: int  # first byte to read
    end: int  # one past the last byte to read
    first_line: int  # line number of the first line read, minus one
    note: str


def find_entry(files: list[dict[str, Any]], path: str) -> dict[str, Any] | None:
    """The latest ledger entry for this path (a rotated file leaves older ones behind)."""
    found = [e for e in files if e["path"] == path and e.get("active", True)]
    return found[-1] if found else None


def plan(files: list[dict[str, Any]], path: str, s: Scan, entry: dict[str, Any] | None) -> Plan:
    """What to read of a scanned file, given the ledger."""
    for e in files:
        if s.sha256 in (e["sha256"], e.get("complete_sha256")) or (
            s.whole_only is False and s.complete_bytes == e["bytes"] and s.complete_sha256 == e["complete_sha256"]
        ):
            same = "" if e["path"] == path else f" as {e['path']}"
            return Plan("skip", e, 0, 0, 0, f"already ingested: same content{same}")
    if entry is not None:
        if s.whole_only:
            return Plan("replace", entry, 0, s.complete_bytes, 0, "compressed or UTF-16 file changed: read again whole")
        if s.prefix_sha256 == entry["complete_sha256"] and s.complete_bytes >= entry["bytes"]:
            if s.complete_bytes == entry["bytes"]:
                return Plan("skip", entry, 0, 0, 0, "no complete new line since the last ingest")
            return Plan(
                "grown",
                entry,
                entry["bytes"],
                s.complete_bytes,
                entry["lines"],
                f"grown: read from byte {entry['bytes']} (line {entry['lines'] + 1})",
            )
        why = "shorter than before" if s.size < entry["bytes"] else "its first bytes changed"
        return Plan("new", None, 0, s.complete_bytes, 0, f"rotated or rewritten ({why}): ingested as a new file")
    return Plan("new", None, 0, s.complete_bytes, 0, "new file")


_SUMMED = ("lines_read", "records", "blank", "rejected", "bytes_read", "overlap_records")


def merge_report(entry: dict[str, Any], report: Any, *, grown: bool) -> None:
    """Keep a file's parse accounting in its ledger entry (summed over the pieces of a grown file)."""
    fr = report.files[0].to_dict() if report.files else {}
    old = entry.get("report") if grown else None
    if old:
        for k in _SUMMED:
            if k in fr:
                fr[k] = int(fr[k]) + int(old.get(k, 0))
        for k in ("encoding", "compressed"):
            if k in old:
                fr[k] = old[k]
    fr["file"] = entry["path"]
    entry["report"] = fr
    for name in ("rejected_by_reason", "skipped"):
        counts = dict(entry.get(name, {})) if grown else {}
        for k, v in getattr(report, name, {}).items():
            counts[k] = counts.get(k, 0) + int(v)
        entry[name] = counts
