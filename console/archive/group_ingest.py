"""Ingest on a cluster: the new diagnostic files planned by independent group of heads, and each set of files
parsed, stored and derived in one pass by one task, as the local ingest does.

The groups are the derivation's (:func:`console.archive.derive_groups.group_key_of`: the heads of sections that
share heads, and per device the heads no section uses).  Files that hold records of one group must be read
by one task, in file order, through the group's one pipeline; so the files are joined where they share a
group, and each joined set is a task (:func:`plan_tasks`).  A task (:func:`ingest_files`) parses its files
with the local ingest's one pass (:func:`console.archive.parse_pass.parse_one_pass`): each chunk's records
go to the ``records`` table, and the chunk, split by group, to each group's pipeline, restored from its saved
state or started afresh.  At the end it saves each group's state and tail, as the local ingest saves the
line's.  No record is read back from the archive (unless a group must be made again from all its records:
older records than its state had closed, as on every engine).

**The plan is a hint, checked.**  Which heads a file holds is known only once it is parsed; the plan reads
a few small blocks of each file for the devices and counting heads they name (:func:`heads_hint`).  Where
that misses a shared group (a head that only appears in the middle of a file), two tasks meet the same
group: neither's rows of it are kept, and that group is derived afterwards from its archived records, the
way the Dask engine derived every group before (:meth:`console.archive.derive.Derivation.take_ingested`).
The records are right either way; only the time differs.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from console.archive.derive_groups import group_key_of
from console.archive.group_records import older_records
from console.archive.group_run import GroupResult, GroupRun
from console.archive.ledger import Scan, try_scan
from console.archive.parse_pass import (
    RECORD_ORDER,
    RejectedRows,
    parse_one_pass,
)
from console.archive.parts import PartWriter
from console.archive.records import ChunkRebuilder, ChunkTranslator, expand_records
from console.archive.store import Manifest, sync_parts
from console.engine.pipeline import PipelineSettings
from parsers.diag.records import DiagChunk
from parsers.diag.registry import DiagRegistry

# The hint reads this many blocks of this size, spread over each file (the start, the end and between).
HINT_BLOCKS = 4
HINT_BLOCK_BYTES = 16 << 10
# ``ID:`` and ``Trackinfo:`` of a whole diagnostic line (the 2nd and 6th of its 12 fields, the last ``Time:``):
# a hint, the parser decides.  A cut line names no head (a file of damaged lines would join every group).
_HINT = re.compile(
    rb"^[^\t\n]*\tID:\s*(\d{1,10})\t[^\t\n]*\t[^\t\n]*\t[^\t\n]*\tTrackinfo:([^\t\n]*)\t(?:[^\t\n]*\t){5}Time:[^\t\n]*$",
    re.MULTILINE,
)


def heads_hint(path: Path) -> set[tuple[int, str]]:
    """(device id, counting head) named in a few blocks of ``path``: the file's heads, as far as they show."""
    try:
        size = path.stat().st_size
        found: set[tuple[int, str]] = set()
        with path.open("rb") as f:
            span = max(0, size - HINT_BLOCK_BYTES)
            starts = sorted({span * i // max(1, HINT_BLOCKS - 1) for i in range(HINT_BLOCKS)})
            for at in starts:
                f.seek(at)
                block = f.read(HINT_BLOCK_BYTES)
                found.update((int(m[1]), m[2].decode("utf-8", "replace")) for m in _HINT.finditer(block))
        return found
    except OSError:
        return set()  # the task's parse says what is wrong with it


@dataclass
class Prescan:
    """What a worker learnt of one input before the ledger plans it: its scan (None: not readable there),
    its kind and note (:func:`console.inputs.recognise.recognise`; None: the client recognises it) and, for a
    diagnostic log, the heads a few of its blocks name (:func:`heads_hint`)."""

    scan: Scan | None
    kind: tuple[str, str] | None
    hint: set[tuple[int, str]]


def prescan_files(files: list[dict[str, Any]]) -> list[Prescan]:
    """One task: several inputs (``path``, ``prefix_len``) hashed, recognised and hinted, in order.  Done by the
    client one file after another, this was the larger part of its serial work on many small files."""
    from console.inputs.recognise import recognise
    from parsers.sources import InputError

    out: list[Prescan] = []
    for f in files:
        path = Path(f["path"])
        try:
            kind: tuple[str, str] | None = recognise(path)
        except (InputError, OSError):
            kind = None  # the client says what is wrong with it
        hint = heads_hint(path) if kind is not None and kind[0] == "diagnostic" else set()
        out.append(Prescan(try_scan(path, f["prefix_len"]), kind, hint))
    return out


def plan_tasks(hints: Sequence[set[tuple[int, str]]], key_of: Callable[[int, Any], str]) -> list[list[int]]:
    """The files (by index) joined where their hinted heads share a group; each set in file order, the sets
    in the order of their first file."""
    parent = list(range(len(hints)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    owner: dict[str, int] = {}
    for i, heads in enumerate(hints):
        for dev, name in heads:
            key = key_of(dev, name)
            j = owner.setdefault(key, i)
            a, b = find(i), find(j)
            if a != b:
                parent[max(a, b)] = min(a, b)
    sets: dict[int, list[int]] = {}
    for i in range(len(hints)):
        sets.setdefault(find(i), []).append(i)
    return sorted(sets.values(), key=lambda s: s[0])


def task_name(hints: Sequence[set[tuple[int, str]]], key_of: Callable[[int, Any], str]) -> str:
    """A task in a few words: the groups its files' hints name, sections first."""
    keys = sorted({key_of(d, n) for heads in hints for d, n in heads}, key=lambda k: (not k.startswith("s"), k))
    return ",".join(keys) or "files"


@dataclass
class IngestedFiles:
    """What one task wrote and knows: its files' parse reports (in the order given), the parts of records and
    rejected lines, each group's derivation, and where each head it met first appears (file_seq, line)."""

    reports: list[Any]
    records: list[str]
    rejected: list[str]
    groups: list[GroupResult]
    first_seen: list[tuple[int, int, int, Any]] = field(default_factory=list)  # (file_seq, line, device, head)


class _Group:
    """One group's pipeline in a task, and the register ids of its registry by what they are."""

    def __init__(self, run: GroupRun) -> None:
        self.run = run
        if run.state.rebuilder is None:
            # Kept in the state: a later ingest that reads the group's records back numbers them the same.
            run.state.rebuilder = ChunkRebuilder(run.registry)
        self.rids = run.state.rebuilder.registers_by_key
        self.heads: set[tuple[int, Any]] = set()


class _Router:
    """One file's chunks (keyed into the file's own registry) split by group, each part keyed into its group's
    registry and fed to its pipeline."""

    def __init__(
        self,
        key_of: Callable[[int, Any], str],
        open_group: Callable[[str], _Group],
        file_seq: int,
        first_line: int,
        first_seen: list[tuple[int, int, int, Any]],
        seen: set[tuple[int, Any]],
    ) -> None:
        self.registry = DiagRegistry()  # a file's own, as the other engines parse a file (its report's counts)
        self.key_of, self.open_group = key_of, open_group
        self.file_seq, self.first_line = file_seq, first_line
        self.first_seen, self.seen = first_seen, seen
        self.group_of = np.zeros(0, np.int32)  # per register: index into keys
        self.head_of = np.zeros(0, np.int32)  # per register: index into heads
        self.keys: list[str] = []
        self.heads: list[tuple[int, Any]] = []
        self.translators: dict[str, ChunkTranslator] = {}

    def _extend(self) -> None:
        reg = self.registry
        old, n = len(self.group_of), reg.n_registers
        a = reg.arrays()
        # Per distinct head among the new registers (not per register: a log may name a head per record).
        pairs = np.stack([a["device_id"][old:n].astype(np.int64), a["counting_head"][old:n].astype(np.int64)], 1)
        uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)
        index = {k: i for i, k in enumerate(self.keys)}
        head_index = {h: i for i, h in enumerate(self.heads)}
        g = np.empty(len(uniq), np.int32)
        h = np.empty(len(uniq), np.int32)
        for u, (dev, code) in enumerate(uniq.tolist()):
            head = (int(dev), reg.heads.value(int(code)))
            key = self.key_of(*head)
            g[u] = index.setdefault(key, len(index))
            if len(index) > len(self.keys):
                self.keys.append(key)
            h[u] = head_index.setdefault(head, len(head_index))
            if len(head_index) > len(self.heads):
                self.heads.append(head)
        self.group_of = np.r_[self.group_of, g[inverse.reshape(-1)]]
        self.head_of = np.r_[self.head_of, h[inverse.reshape(-1)]]

    def feed(self, chunk: DiagChunk) -> None:
        if not len(chunk):
            return
        if len(self.group_of) < self.registry.n_registers:
            known = len(self.heads)
            self._extend()
            if len(self.heads) > known:
                self._note_first(chunk)
        g = self.group_of[chunk.register_id]
        first = int(g[0])
        if bool((g == first).all()):
            parts = [(first, chunk)]
        else:
            parts = [(k, chunk.take(g == k)) for k in np.unique(g).tolist()]
        for k, part in parts:
            key = self.keys[k]
            group = self.open_group(key)
            tr = self.translators.get(key)
            if tr is None:
                tr = self.translators[key] = ChunkTranslator(self.registry, group.run.registry, group.rids)
            group.run.feed(tr.translate(part))

    def _note_first(self, chunk: DiagChunk) -> None:
        """Where the heads not met before begin (the archive's order of heads: a read of every file's)."""
        head = self.head_of[chunk.register_id]
        codes, first = np.unique(head, return_index=True)
        for code, at in zip(codes.tolist(), first.tolist(), strict=True):
            h = self.heads[code]
            if h not in self.seen:
                self.seen.add(h)
                self.first_seen.append((self.file_seq, int(chunk.line[at]) + self.first_line, *h))

    def group_heads(self) -> dict[str, set[tuple[int, Any]]]:
        out: dict[str, set[tuple[int, Any]]] = {}
        for head in self.heads:
            out.setdefault(self.key_of(*head), set()).add(head)
        return out


def group_settings(settings: PipelineSettings, key: str, key_of: Callable[[int, Any], str]) -> PipelineSettings:
    """A group's pipeline settings: the sections of its group only, and no start rows (the ingest writes
    those once, at the line's first event)."""
    import dataclasses

    lay = settings.sections
    if lay is None:
        return settings
    # A section's group is its first head's (every head of a section is in its group); no device is needed.
    mine = tuple(sec for sec in lay.sections if sec.bounds and key_of(0, sec.bounds[0].head) == key)
    return dataclasses.replace(
        settings, sections=dataclasses.replace(lay, sections=mine) if mine else None, start_rows=False
    )


def ingest_files(
    root: Path,
    manifest: Manifest,
    settings: PipelineSettings,
    known: list[tuple[int, Any]],
    new_seqs: list[int],
    files: list[dict[str, Any]],
    salt: str,
    key: str = "",
) -> IngestedFiles:
    """One task: ``files`` (source, shown, file_seq, first_line; in file order) parsed once, their records and
    rejected lines written to parts of this task, every chunk fed to its group's pipeline; each group's state
    and tail saved.  ``manifest`` is the ingest's new one (nothing of this ingest's records listed yet);
    ``known``: the heads of earlier ingests; ``new_seqs``: every file this ingest reads (all tasks')."""
    del key  # the task's name, for the engine's messages
    generation = manifest.generation
    key_of = group_key_of(settings.sections)
    first_seq = int(files[0]["file_seq"])
    records = PartWriter(root, "records", generation, f"r{first_seq}-", sort_by=RECORD_ORDER, expand=expand_records)
    rejected = PartWriter(root, "rejected", generation, f"l{first_seq}-", by_device=False, by_day=False)
    rows = RejectedRows(rejected)
    groups: dict[str, _Group] = {}
    heads_of: dict[str, set[tuple[int, Any]]] = {}
    first_seen: list[tuple[int, int, int, Any]] = []
    seen: set[tuple[int, Any]] = set()

    def open_group(k: str) -> _Group:
        found = groups.get(k)
        if found is None:
            run = GroupRun(root, manifest, group_settings(settings, k, key_of), k, salt=salt)
            if not run.resumed:
                run.rebuild = False  # a group seen first now: its records are fed as they come (see finish)
            run.begin_file()
            found = groups[k] = _Group(run)
        return found

    reports: list[Any] = []
    try:
        for f in files:
            seq, shown, first_line = int(f["file_seq"]), str(f["shown"]), int(f["first_line"])
            for g in groups.values():
                g.run.begin_file()
            router = _Router(key_of, open_group, seq, first_line, first_seen, seen)
            report = parse_one_pass(
                Path(f["source"]),
                shown,
                seq,
                first_line,
                records,
                rows.adder(shown, seq, first_line, generation),
                registry=router.registry,
                on_chunk=router.feed,
            )
            reports.append(report)
            for k, hs in router.group_heads().items():
                heads_of.setdefault(k, set()).update(hs)
        rows.flush()
        record_parts, rejected_parts = records.close(), rejected.close()
        # A group made again from all its records reads this task's too (no other task holds any of them).
        mine = copy.copy(manifest)
        mine.tables = {**manifest.tables, "records": [*manifest.parts("records"), *record_parts]}
        results: list[GroupResult] = []
        for k in sorted(groups):
            run = groups[k].run
            run.heads = frozenset({*heads_of.get(k, set()), *(h for h in known if key_of(*h) == k)})
            run.manifest = mine
            if not run.resumed and manifest.parts("records") and older_records(root, manifest, run.heads, new_seqs):
                run.must_rebuild()  # the group's heads have older records: made from all of them
            results.append(run.finish())
        # Made durable here, side by side with the other tasks, not one by one by the client as it publishes.
        sync_parts(root, [*record_parts, *rejected_parts, *(rel for r in results for rel in r.written)])
        return IngestedFiles(reports, record_parts, rejected_parts, results, first_seen)
    except BaseException:
        records.abort()
        rejected.abort()
        for g in groups.values():
            g.run.abort()
        raise
