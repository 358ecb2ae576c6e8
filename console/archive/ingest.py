"""Ingest files into the archive: once each, growing files from their last offset, published atomically.

One ingest runs under the writers' lock: it removes what killed ingests
left behind, reads every input the ledger says is new (or new bytes of a
grown file), writes Parquet parts under fresh names, recomputes the derived
tables (:mod:`console.archive.derive`) and publishes one new manifest.
Nothing is visible to readers before the publish; a failure (a full disk,
a bad input, ``kill -9``) leaves the previous state current.
"""

from __future__ import annotations

import contextlib
import copy
import os
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from console import __version__
from console.archive import arrow_np, ledger
from console.archive.day_rows import DayRows
from console.archive.derive import Derivation
from console.archive.group_ingest import Prescan
from console.archive.parse_pass import (
    RECORD_ORDER,
    REJECTED_BATCH_ROWS,
    ParsedFile,
    RejectedRows,
    parse_one_pass,
    rejected_row,
)
from console.archive.parts import COMPACT_MAX_ROWS, PartWriter, compact, part_rows, read_part, write_part, write_small
from console.archive.records import expand_records
from console.archive.store import (
    TMP,
    ArchiveError,
    Manifest,
    collect_garbage,
    ensure_layout,
    missing_part,
    publish,
    read_current,
    writer_lock,
)
from console.inputs.recognise import DIAGNOSTIC
from parsers.report import ParseReport

# Kinds the archive stores, by the report's recognition (console.inputs.recognise.recognise).
STORED_ELSEWHERE = {"nmea": "fixes", "gnss-csv": "fixes", "gnss-jsonl": "fixes", "centre": "fixes"}
STDIN_NAME = "<stdin>"


@dataclass
class FileOutcome:
    path: str
    kind: str
    action: str  # new, grown, replace, skip, not-read
    note: str
    records: int = 0
    rejected: int = 0
    bytes_read: int = 0
    # Bytes after the last line end, not read yet: an unfinished line (a log still being written), read
    # once the file grows; or a file whose lines end in CR alone, which the archive does not take.
    held_back_bytes: int = 0


@dataclass
class IngestSummary:
    archive: Path
    generation: int
    files: list[FileOutcome] = field(default_factory=list)
    seconds: float = 0.0
    published: bool = False
    # Wall seconds per step: read (parse and write the inputs), records (close, compact), derive, publish.
    phases: dict[str, float] = field(default_factory=dict)
    # Each step's end: (wall ``perf_counter``, this process's ``process_time``), for benchmarks/bench_fleet.py.
    phase_ends: dict[str, tuple[float, float]] = field(default_factory=dict)
    # What the inputs held but the ingest did not read, and why (a directory's dangling links, FIFOs, hidden
    # entries; a file given twice): the report's words (console.inputs.recognise.expand).
    warnings: list[str] = field(default_factory=list)

    @property
    def records(self) -> int:
        return sum(f.records for f in self.files)

    @property
    def rejected(self) -> int:
        return sum(f.rejected for f in self.files)

    @property
    def added(self) -> list[FileOutcome]:
        return [f for f in self.files if f.action in ("new", "grown", "replace")]

    @property
    def skipped(self) -> list[FileOutcome]:
        return [f for f in self.files if f.action in ("skip", "not-read")]

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": "trackside.ingest/1",
            "archive": str(self.archive),
            "generation": self.generation,
            "published": self.published,
            "records": self.records,
            "rejected": self.rejected,
            "seconds": round(self.seconds, 3),
            "phase_seconds": {k: round(v, 3) for k, v in self.phases.items()},
            "warnings": self.warnings,
            "files": [f.__dict__ for f in self.files],
        }


def _kind(path: Path) -> tuple[str, str]:
    from console.inputs.recognise import recognise

    fmt, note = recognise(path)
    return fmt, note


class _Ingest:
    def __init__(
        self, root: Path, manifest: Manifest, on_bytes: Callable[[int], None] | None, derivation: Derivation | None
    ) -> None:
        self.root = root
        self.derivation = derivation
        self.old = manifest
        self.new = copy.deepcopy(manifest)
        self.new.generation = manifest.generation + 1
        self.gen = self.new.generation
        self.on_bytes = on_bytes
        self.records = PartWriter(root, "records", self.gen, "r", sort_by=RECORD_ORDER, expand=expand_records)
        # The per-day inventory figures of the records stored here (merged with the stored rows at the end).
        self.day_rows = DayRows()
        self.new_parts: list[str] = []
        self.ingest_rows: list[dict[str, Any]] = []
        # Every rejected line, written out as it comes (a hostile file may reject millions of lines).
        self.rejected = PartWriter(root, "rejected", self.gen, "l", by_device=False, by_day=False)
        self._rejected_rows: list[dict[str, Any]] = []
        self.touched: set[str] = set()  # tables whose inputs changed
        self.started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        self._tmp_count = 0
        self.dropped_seqs: set[int] = set()  # diagnostic files replaced: their records leave
        self.new_diag_seqs: list[int] = []  # diagnostic files (or their new bytes) read by this ingest
        self.on_cluster = False  # diagnostic files are parsed on the cluster's workers (Dask engine)
        self.queued: list[tuple[Path, Path, dict[str, Any], ledger.Plan, FileOutcome]] = []
        # What the cluster's workers learnt of each input (prescan), by the name a file is known by: (prefix
        # asked, what they learnt); and the hints of the diagnostic logs they read, by path.
        self.prescanned: dict[str, tuple[int | None, Prescan]] = {}
        self.hints: dict[str, set[tuple[int, str]]] = {}
        self.synced: set[str] = set()  # parts the workers made durable (publish fsyncs the others)
        # The layout file among the inputs that the derivation uses (report's rule), and --layout.
        self.layout_file: Path | None = None
        self.layout_spec: str | None = None

    def _reject(self, row: dict[str, Any]) -> None:
        self._rejected_rows.append(row)
        if len(self._rejected_rows) >= REJECTED_BATCH_ROWS:
            self._flush_rejected()

    def _flush_rejected(self) -> None:
        if self._rejected_rows:
            self.rejected.add(arrow_np.table_from_rows(self._rejected_rows))
            self._rejected_rows = []

    def _next_seq(self) -> int:
        return max((int(e["file_seq"]) for e in self.new.files), default=-1) + 1

    def _tmp(self) -> Path:
        self._tmp_count += 1
        return self.root / TMP / f"g{self.gen:06d}-{self._tmp_count}.part"

    def _range_file(self, path: Path, start: int, end: int, size: int) -> Path:
        """The bytes [start, end) as a file the parsers can open (the file itself when it is all of it)."""
        if start == 0 and end == size:
            return path
        out = self._tmp()
        with path.open("rb") as src, out.open("wb") as dst:
            src.seek(start)
            left = end - start
            while left > 0:
                block = src.read(min(ledger.BLOCK, left))
                if not block:
                    break
                dst.write(block)
                left -= len(block)
        return out

    def add_file(self, path: Path, shown: str) -> FileOutcome:
        pre = self.prescanned.pop(shown, None)
        kind, note = pre[1].kind if pre is not None and pre[1].kind is not None else _kind(path)
        if kind == "layout":
            from console.inputs.recognise import layout_note

            note = layout_note(path, self.layout_file, self.layout_spec)
        if kind not in (DIAGNOSTIC, *STORED_ELSEWHERE, "frames", "can", "voltages"):
            why = note or f"{kind}: not archived"
            self._ledger_row(shown, kind, "not-read", why, None, 0, 0, None)
            return FileOutcome(shown, kind, "not-read", why)
        entry = ledger.find_entry(self.new.files, shown)
        prefix_len = entry["bytes"] if entry is not None else None
        found = pre[1].scan if pre is not None and pre[0] == prefix_len else None
        if found is None and kind == DIAGNOSTIC and not self.on_cluster:
            # A diagnostic log new by its size alone is parsed while it is hashed: the hash goes in the ledger.
            z = ledger.sizes(path)
            p_new = ledger.new_by_size(self.new.files, entry, z)
            if p_new is not None:
                return self._add_hashing(path, shown, kind, p_new, ledger.BackgroundScan(path, z))
        s = found if found is not None else ledger.scan(path, prefix_len)
        if pre is not None and pre[1].kind is not None:
            self.hints[str(path)] = pre[1].hint  # of the whole file: used where the whole file is read
        p = ledger.plan(self.new.files, shown, s, entry)
        if kind != DIAGNOSTIC and p.action == "grown":
            # Fixes and frames are parsed whole (their parsers keep state across lines).
            p = ledger.Plan("replace", entry, 0, s.complete_bytes, 0, "grown: read again whole")
        if p.action == "skip":
            self._ledger_row(shown, kind, "skip", p.note, s, 0, 0, None)
            return FileOutcome(shown, kind, "skip", p.note)
        if p.action == "replace" and p.entry is not None:
            self._drop_entry(p.entry)
        e = p.entry if p.action == "grown" and p.entry is not None else self._new_entry(shown, kind)
        # Fixes and frames are parsed from the file itself (GNSS names a device after its file).
        source = self._range_file(path, p.start, p.end, s.size) if kind == DIAGNOSTIC else path
        outcome = FileOutcome(shown, kind, p.action, p.note)
        if kind == DIAGNOSTIC and self.on_cluster:
            # Parsed on a worker, with the other files (parse_diag_file): what it says is taken in later.
            self.queued.append((source, path, e, p, outcome))
        elif kind == DIAGNOSTIC:
            self._diag(source, e, p, outcome)
        else:
            self._other(source, kind, e, outcome)
        return self._read_done(path, shown, kind, source, e, p, s, outcome)

    def _new_entry(self, shown: str, kind: str) -> dict[str, Any]:
        e = {"file_seq": self._next_seq(), "path": shown, "kind": kind, "bytes": 0, "lines": 0, "active": True}
        e.update({"records": 0, "blank": 0, "rejected": 0, "parts": [], "sha256": "", "complete_sha256": ""})
        e["encoding"] = "utf-8"
        self.new.files.append(e)
        return e

    def _add_hashing(
        self, path: Path, shown: str, kind: str, p: ledger.Plan, hashing: ledger.BackgroundScan
    ) -> FileOutcome:
        """A new diagnostic log read (as :meth:`add_file` would) while ``hashing`` hashes it."""
        try:
            e = self._new_entry(shown, kind)
            source = self._range_file(path, p.start, p.end, hashing.sizes.size)
            outcome = FileOutcome(shown, kind, p.action, p.note)
            self._diag(source, e, p, outcome)
            s = hashing.result()
        finally:
            hashing.cancel()  # on a failure, the hash is not waited for
        if hashing.changed(s):
            raise ArchiveError(f"{shown}: changed while it was read (rewritten, not appended to)")
        return self._read_done(path, shown, kind, source, e, p, s, outcome)

    def _read_done(
        self,
        path: Path,
        shown: str,
        kind: str,
        source: Path,
        e: dict[str, Any],
        p: ledger.Plan,
        s: ledger.Scan,
        outcome: FileOutcome,
    ) -> FileOutcome:
        """The ledger entry and the ingest's row of a file read (or queued for the cluster)."""
        outcome.bytes_read = p.end - p.start
        if kind == DIAGNOSTIC:
            outcome.held_back_bytes = max(0, s.size - p.end)
        e["bytes"] = s.complete_bytes
        e["sha256"] = s.sha256
        e["complete_sha256"] = s.complete_sha256
        e["size_seen"] = s.size
        self._ledger_row(shown, kind, p.action, p.note, s, p.start, p.end, e)
        if source != path and not (kind == DIAGNOSTIC and self.on_cluster):
            source.unlink()
        return outcome

    def prescan(self, inputs: list[tuple[Path, str]]) -> None:
        """On a cluster, every input hashed, recognised and (a diagnostic log) hinted by the workers, side by
        side, before the ledger plans them: a task per run of files, a few tasks per worker thread (a task per
        file cost the scheduler, in this process, more than the work)."""
        from console.archive.group_ingest import prescan_files
        from console.fleet.engine import in_flight, map_partitions

        files: list[dict[str, Any]] = []
        for path, shown in inputs:
            entry = ledger.find_entry(self.new.files, shown)
            files.append({"path": str(path), "prefix_len": entry["bytes"] if entry is not None else None})
        n = max(1, min(len(files), 2 * in_flight()))
        runs = [files[i * len(files) // n : (i + 1) * len(files) // n] for i in range(n)]
        found = [
            pre for run in map_partitions(prescan_files, [{"files": r} for r in runs], label="scan") for pre in run
        ]
        for (_path, shown), f, pre in zip(inputs, files, found, strict=True):
            self.prescanned[shown] = (f["prefix_len"], pre)

    def parse_queued(self) -> None:
        """The diagnostic files queued for the cluster: one task each, their parts and accounting taken in
        in file order; or, where the new records continue the derivation, one task per set of files sharing
        a group of heads, each parsing and deriving in one pass (:meth:`_ingest_groups`)."""
        from console.fleet.engine import map_partitions

        if not self.queued:
            return
        self.day_rows.complete = False  # records stored by the workers
        d = self.derivation
        if (
            d is not None
            and d.grouped
            and not self.dropped_seqs
            and not d.rebuild_all
            and (d.same or not self.old.parts("records"))
        ):
            self._ingest_groups(d)
            return
        items = [
            {"source": str(src), "shown": e["path"], "file_seq": int(e["file_seq"]), "first_line": p.first_line}
            for src, _path, e, p, _out in self.queued
        ]
        common = {"root": self.root, "generation": self.gen}
        results = map_partitions(parse_diag_file, items, common=common, label="parse")
        for (src, path, e, p, out), res in zip(self.queued, results, strict=True):
            self.new_parts += res.records + res.rejected
            self.new.tables.setdefault("records", []).extend(res.records)
            self.new.tables.setdefault("rejected", []).extend(res.rejected)
            self.new_diag_seqs.append(int(e["file_seq"]))
            self._take_report(e, p, out, res.report)
            if src != path:
                src.unlink()
        self.queued = []

    def _ingest_groups(self, d: Derivation) -> None:
        """The queued files parsed, stored and derived in one pass on the workers, a task per set of files
        sharing a group (:mod:`console.archive.group_ingest`); their parts, accounting and derivations taken
        in.  (Another version's, layout's or engine's derivation, or a file replaced: the two-step way.)"""
        from console.archive.derive import group_key_of
        from console.archive.group_ingest import heads_hint, ingest_files, plan_tasks, task_name
        from console.fleet.engine import map_partitions

        key_of = group_key_of(d.settings.sections)
        # The workers' hints where they read the whole file; a grown file's new bytes are hinted here.
        hints = [self.hints[str(src)] if str(src) in self.hints else heads_hint(src) for src, *_ in self.queued]
        plan = plan_tasks(hints, key_of)
        new_seqs = [int(e["file_seq"]) for _src, _path, e, _p, _out in self.queued]
        known = [(int(dev), n) for dev, n in self.new.derived.get("heads", [])] if d.same else []
        items = [
            {
                "key": task_name([hints[i] for i in files], key_of),
                "salt": f"-p{n}",
                "files": [
                    {"source": str(src), "shown": e["path"], "file_seq": int(e["file_seq"]), "first_line": p.first_line}
                    for src, _path, e, p, _out in (self.queued[i] for i in files)
                ],
            }
            for n, files in enumerate(plan)
        ]
        common = {"root": self.root, "manifest": self.new, "settings": d.settings, "known": known}
        results = map_partitions(ingest_files, items, common={**common, "new_seqs": new_seqs}, label="derive")
        reports: dict[int, ParseReport] = {}
        first_seen: list[tuple[int, int, int, Any]] = []
        for files, res in zip(plan, results, strict=True):
            self.new_parts += res.records + res.rejected
            self.new.tables.setdefault("records", []).extend(res.records)
            self.new.tables.setdefault("rejected", []).extend(res.rejected)
            reports.update(zip(files, res.reports, strict=True))
            first_seen += res.first_seen
            self.synced.update([*res.records, *res.rejected, *(rel for g in res.groups for rel in g.written)])
        for i, (src, path, e, p, out) in enumerate(self.queued):
            self.new_diag_seqs.append(int(e["file_seq"]))
            self._take_report(e, p, out, reports[i])
            if src != path:
                src.unlink()
        # The heads in the order a read of every file meets them: the earlier ingests' first, then the new ones
        # where they first appear (a grown file's new lines sit among older files: the archive is asked then).
        order = None
        if not any(p.action == "grown" for _src, _path, _e, p, _out in self.queued):
            old = set(known)
            new: dict[tuple[int, Any], None] = {}
            for _seq, _line, dev, head in sorted(first_seen, key=lambda t: (t[0], t[1])):
                if (dev, head) not in old:
                    new.setdefault((dev, head), None)
            order = [*known, *new]
        d.take_ingested([r.groups for r in results], order)
        self.queued = []

    def _drop_entry(self, entry: dict[str, Any]) -> None:
        """A replaced file: its parts leave the manifest (the records of a diagnostic log too)."""
        entry["active"] = False
        gone = set(entry.get("parts", []))
        for table, parts in self.new.tables.items():
            if gone & set(parts):
                self.new.tables[table] = [p for p in parts if p not in gone]
                self.touched.add(table)
        if entry["kind"] == DIAGNOSTIC:
            self.dropped_seqs.add(int(entry["file_seq"]))
            if self.derivation is not None:
                self.derivation.must_rebuild()  # its records leave the history: made again without them

    def _diag(self, source: Path, e: dict[str, Any], p: ledger.Plan, out: FileOutcome) -> None:
        seq, gen = int(e["file_seq"]), self.gen
        derive = self.derivation
        registry = None
        if derive is not None and derive.registry is not None:
            # One registry for the pipeline's whole history: the chunks go to it as they are stored.
            registry = derive.registry
            derive.begin_file()
        self.new_diag_seqs.append(seq)
        report = parse_one_pass(
            source,
            e["path"],
            seq,
            p.first_line,
            self.records,
            # The archive keeps every rejection: each goes to the rejected table as it is found.
            lambda r: self._reject(rejected_row(r, e["path"], seq, p.first_line, gen)),
            registry=registry,
            on_chunk=derive.feed if derive is not None else None,
            on_bytes=self.on_bytes,
            day_rows=self.day_rows,
        )
        self._take_report(e, p, out, report)

    def _take_report(self, e: dict[str, Any], p: ledger.Plan, out: FileOutcome, report: ParseReport) -> None:
        fr = report.files[0]
        e["lines"] = int(e["lines"]) + fr.lines_read
        e["records"] = int(e["records"]) + fr.records
        e["blank"] = int(e["blank"]) + fr.blank
        e["rejected"] = int(e["rejected"]) + fr.rejected
        if p.start == 0:
            e["encoding"] = fr.encoding
            e["compressed"] = fr.compressed
        e["ends_without_newline"] = fr.ends_without_newline
        ledger.merge_report(e, report, grown=p.action == "grown")
        out.records, out.rejected = fr.records, fr.rejected
        self.touched.add("records")

    def _other(self, source: Path, kind: str, e: dict[str, Any], out: FileOutcome) -> None:

        report: ParseReport
        if kind in STORED_ELSEWHERE:
            from parsers.gnss_files import parse_gnss

            table, report, _states = parse_gnss([source])
            name = "fixes"
        elif kind == "voltages":
            from parsers.voltages import read_voltages

            table, report = read_voltages([source])
            name = "voltages"
        elif kind == "frames":
            from parsers.frames.sensor import parse_frames

            table, report = parse_frames([source])
            name = "frames"
        else:
            from parsers.frames.can import parse_can

            table, report = parse_can([source])
            name = "frames"
        table = table.copy()
        if name == "fixes":
            # The archive's one time type: naive UTC, nanoseconds (TIMESTAMP_NS), as every other table's times.
            table["time"] = _naive_utc(table["time"])
        if "file" in table.columns:
            table["file"] = e["path"]
        table["file_seq"] = np.int32(e["file_seq"])
        arrow = pa.Table.from_pandas(table, preserve_index=False)
        rel = write_small(self.root, name, self.gen, f"f{int(e['file_seq'])}", arrow)
        if rel is not None:
            self.new.tables.setdefault(name, []).append(rel)
            self.new_parts.append(rel)
            e["parts"] = [*e.get("parts", []), rel]
            # The rows its parts hold, for `trackside verify`: an NMEA file's fixes are its epochs, not its sentences.
            e["rows"] = int(e.get("rows", 0)) + arrow.num_rows
        for r in report.rejections:
            self._reject(
                {
                    "file": e["path"],
                    "file_seq": int(e["file_seq"]),
                    "line": r.line,
                    "reason": r.reason,
                    "text": r.text,
                    "generation": self.gen,
                }
            )
        ledger.merge_report(e, report, grown=False)
        e["lines"] = report.lines_read
        e["records"] = report.records
        e["blank"] = report.blank
        e["rejected"] = report.rejected
        out.records, out.rejected = report.records, report.rejected
        self.touched.add(name)

    def _ledger_row(
        self,
        path: str,
        kind: str,
        action: str,
        note: str,
        s: ledger.Scan | None,
        start: int,
        end: int,
        e: dict[str, Any] | None,
    ) -> None:
        self.ingest_rows.append(
            {
                "generation": self.gen,
                "ingested_at": self.started,
                "path": path,
                "kind": kind,
                "action": action,
                "note": note,
                "file_seq": int(e["file_seq"]) if e is not None else None,
                "size_bytes": s.size if s is not None else None,
                "byte_start": start,
                "byte_end": end,
                "sha256": s.sha256 if s is not None else None,
                "prefix_sha256": s.complete_sha256 if s is not None else None,
                "tool_version": __version__,
            }
        )

    def finish_records(self) -> None:
        written = self.records.close()
        if written:
            self.new.tables.setdefault("records", []).extend(written)
            self.new_parts += written
        if self.dropped_seqs:
            self.day_rows.complete = False  # the stored rows count records that leave
            self._rewrite_records_without(self.dropped_seqs)
        self._compact_records(set(written))

    def _compact_records(self, fresh: set[str]) -> None:
        """Partitions this ingest added a part to, that hold other parts: the small ones merged into one.

        Each ingest of a growing file would otherwise leave one more part per day and board, and a
        query pays for every part its view lists.  The merged part gets a fresh name and replaces the
        parts it holds in the same manifest (old parts are garbage after the publish, as ever).
        """
        by_dir: dict[str, list[str]] = {}
        for rel in self.new.tables.get("records", []):
            by_dir.setdefault(os.path.dirname(rel), []).append(rel)
        for folder, rels in sorted(by_dir.items()):
            if len(rels) < 2 or not fresh.intersection(rels):
                continue
            rows = {rel: part_rows(self.root, rel) for rel in rels}
            chosen: list[str] = []
            total = 0
            for rel in sorted(rels, key=lambda r: rows[r]):  # smallest first: big parts stay as they are
                if total + rows[rel] > COMPACT_MAX_ROWS:
                    break
                chosen.append(rel)
                total += rows[rel]
            if len(chosen) < 2:
                continue
            out = compact(self.root, chosen, os.path.join(folder, f"g{self.gen:06d}-c.parquet"), RECORD_ORDER)
            gone = set(chosen)
            self.new.tables["records"] = [r for r in self.new.tables["records"] if r not in gone] + [out]
            for rel in gone.intersection(self.new_parts):
                (self.root / rel).unlink()  # written by this ingest, listed nowhere
            self.new_parts = [r for r in self.new_parts if r not in gone] + [out]

    def _rewrite_records_without(self, seqs: set[int]) -> None:
        """Records of replaced diagnostic files leave the partitions that hold them (rewritten once)."""
        kept: list[str] = []
        for rel in self.new.tables.get("records", []):
            if rel in self.new_parts:
                kept.append(rel)
                continue
            table = read_part(self.root, rel)
            mask = ~np.isin(table.column("file_seq").to_numpy(), np.fromiter(seqs, np.int32))
            if mask.all():
                kept.append(rel)
                continue
            if mask.any():
                new_rel = rel.replace(".parquet", f"-x{self.gen:06d}.parquet")
                write_part(self.root, new_rel, table.filter(pa.array(mask)))
                kept.append(new_rel)
                self.new_parts.append(new_rel)
        self.new.tables["records"] = kept

    def finish_ledger(self) -> None:
        if self.ingest_rows:
            rel = write_small(self.root, "ingests", self.gen, "l", arrow_np.table_from_rows(self.ingest_rows))
            if rel is not None:
                self.new.tables.setdefault("ingests", []).append(rel)
                self.new_parts.append(rel)
        self._flush_rejected()
        written = self.rejected.close()
        if written:
            self.new.tables.setdefault("rejected", []).extend(written)
            self.new_parts += written


def parse_diag_file(root: Path, generation: int, source: str, shown: str, file_seq: int, first_line: int) -> ParsedFile:
    """One file's records and rejected lines into parts of their own (a Dask task: it reads one file and
    writes parts no other task names; the client lists them in the manifest it publishes)."""
    records = PartWriter(root, "records", generation, f"r{file_seq}-", sort_by=RECORD_ORDER, expand=expand_records)
    rejected = PartWriter(root, "rejected", generation, f"l{file_seq}-", by_device=False, by_day=False)
    rows = RejectedRows(rejected)
    try:
        report = parse_one_pass(
            Path(source),
            shown,
            file_seq,
            first_line,
            records,
            rows.adder(shown, file_seq, first_line, generation),
        )
        rows.flush()
        return ParsedFile(records.close(), rejected.close(), report)
    except BaseException:
        records.abort()
        rejected.abort()
        raise


def _naive_utc(times: Any) -> Any:
    """Zone-aware times (the GNSS parser's, UTC) as naive UTC; naive ones as they are."""
    if getattr(times.dt, "tz", None) is None:
        return times
    return times.dt.tz_convert("UTC").dt.tz_localize(None)


class _PhaseClock:
    """Wall seconds of consecutive steps, into ``phases`` (the summary's, also in ``ingest --json``), and when
    each ended, into ``ends``."""

    def __init__(self, phases: dict[str, float], ends: dict[str, tuple[float, float]]) -> None:
        self.phases, self.ends = phases, ends
        self.t = time.perf_counter()

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.phases[name] = self.phases.get(name, 0.0) + now - self.t
        self.ends[name] = (now, time.process_time())
        self.t = now


def expand_inputs(paths: Sequence[Path], root: Path, warnings: list[str] | None = None) -> list[tuple[Path, str]]:
    """(file to read, name it is known by): directories read whole (the report's order), ``-`` is stdin.

    ``warnings`` gets what the inputs hold but is not read, and why (the report's words)."""
    from console.inputs.recognise import ReportInputError, expand

    out: list[tuple[Path, str]] = []
    files: list[Path] = []
    said = warnings if warnings is not None else []

    def expanded(given: list[Path]) -> list[tuple[Path, str]]:
        found, notes = expand(given, exclude=None)
        said.extend(notes)
        return [(f, str(f.resolve())) for f in found]

    if sum(str(p) == "-" for p in paths) > 1:
        raise ArchiveError("-: standard input given twice")  # as every other command says
    for p in paths:
        if str(p) == "-":
            if files:
                out += expanded(files)
                files = []
            tmp = root / TMP / f"stdin-{time.time_ns()}"
            with tmp.open("wb") as dst:
                shutil.copyfileobj(sys.stdin.buffer, dst)
            out.append((tmp, STDIN_NAME))
        else:
            files.append(p)
    try:
        if files:
            out += expanded(files)
    except ReportInputError as exc:
        raise ArchiveError(str(exc)) from None
    return out


def _inputs_layout(job: _Ingest, inputs: list[tuple[Path, str]], layout: str | None) -> str | None:
    """The layout the derivation uses: ``--layout``, else a layout file among the inputs, by ``report``'s rule."""
    from console.inputs.recognise import chosen_layout_file
    from console.layout import LayoutError, load_layout

    job.layout_spec = layout
    job.layout_file = chosen_layout_file([p for p, _ in inputs], layout)
    if job.layout_file is None:
        return layout
    try:
        load_layout(job.layout_file)  # a bad layout fails before anything is read
    except LayoutError as exc:
        raise ArchiveError(str(exc)) from None
    return str(job.layout_file.resolve())


def run_ingest(
    paths: Sequence[Path],
    root: Path,
    *,
    layout: str | None = None,
    wait: bool = True,
    on_wait: Callable[[], None] | None = None,
    on_bytes: Callable[[int], None] | None = None,
    on_file: Callable[[str], None] | None = None,
) -> IngestSummary:
    """Ingest ``paths`` into the archive at ``root``; the summary of what was added, skipped and rejected."""
    from console.fleet.engine import map_partitions, on_cluster, warm_workers
    from console.memory import one_malloc_arena, read_memory, trim_heap

    t0 = time.perf_counter()
    one_malloc_arena()  # before the reader's and the writer's threads start
    # The modules of the ingest's tasks (the prescan recognises files as the report does), imported by the
    # workers while this process expands the inputs and takes the lock.
    warm_workers(["console.archive.group_ingest", "console.inputs.recognise"])
    ensure_layout(root)
    # An ingest's phases (read, derive, publish) each need their memory, one after the other.
    with read_memory(), writer_lock(root, wait=wait, on_wait=on_wait):
        current = read_current(root)
        lost = missing_part(root, current)
        if lost is not None:
            # Built on, the archive would stay damaged under a new generation, with nothing said.
            raise ArchiveError(
                f"{root}: the archive is damaged: {lost} is missing or not a file"
                " (`trackside verify` lists what is damaged); nothing ingested"
            )
        collect_garbage(root, current)
        job = _Ingest(root, current, on_bytes, None)
        summary = IngestSummary(root, current.generation)
        try:
            clock = _PhaseClock(summary.phases, summary.phase_ends)
            inputs = expand_inputs(paths, root, summary.warnings)
            layout = _inputs_layout(job, inputs, layout)
            # The derivation writes into the new manifest, as the records do; on a cluster, per group of heads.
            job.derivation = Derivation(root, job.new, layout, grouped=on_cluster())
            job.derivation.day_rows = job.day_rows
            job.on_cluster = on_cluster()
            if job.on_cluster:
                job.prescan(inputs)
            for path, shown in inputs:
                if on_file is not None:
                    on_file(shown)
                summary.files.append(job.add_file(path, shown))
            job.parse_queued()
            clock.lap("read")
            job.finish_records()
            trim_heap()  # what the read freed, given back before the derivation needs its own
            clock.lap("records")
            relayout = layout is not None and layout != current.derived.get("layout")
            if summary.added or relayout:
                mapper = None
                if on_cluster():

                    def mapper(fn: Any, items: list[Any], common: dict[str, Any]) -> list[Any]:
                        return map_partitions(fn, items, common=common, label="derive")

                job.new_parts += job.derivation.finish(job.new_diag_seqs, mapper)
            clock.lap("derive")
            job.finish_ledger()
            # Nothing new (every file already ingested): no new generation at all.
            if summary.added or relayout:
                publish(root, job.new, [rel for rel in job.new_parts if rel not in job.synced])
                summary.generation = job.gen
                summary.published = True
            else:
                for rel in job.new_parts:  # the ledger's rows of files seen before: no manifest will name them
                    with contextlib.suppress(OSError):
                        (root / rel).unlink()
            clock.lap("publish")
        except BaseException:
            job.records.abort()
            job.rejected.abort()
            if job.derivation is not None:
                job.derivation.abort()
            # No manifest names them: remove this run's parts now (a full disk wants its space
            # back); what a kill leaves behind, the next ingest's collect_garbage removes.
            for rel in job.new_parts:
                with contextlib.suppress(OSError):
                    (root / rel).unlink()
            raise
    summary.seconds = time.perf_counter() - t0
    return summary
