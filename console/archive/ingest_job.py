"""One ingest's new manifest, and its pass over the inputs: each file planned against the ledger and read.

A file the ledger has seen whole is skipped; a grown diagnostic log is read from where the last ingest
stopped, any other file read again whole; a rotated one replaces its old entry.  On a cluster the diagnostic
logs are queued here and parsed by the workers (:mod:`console.archive.ingest_cluster`).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from console import __version__
from console.archive import arrow_np, ledger
from console.archive.day_rows import DayRows
from console.archive.derive import Derivation
from console.archive.group_ingest import Prescan
from console.archive.ingest_summary import FileOutcome
from console.archive.parse_pass import RECORD_ORDER, REJECTED_BATCH_ROWS, parse_one_pass, rejected_row
from console.archive.parts import PartWriter, write_small
from console.archive.records import expand_records
from console.archive.store import TMP, ArchiveError, Manifest
from console.archive.whole_files import STORED_ELSEWHERE, read_whole
from console.inputs.recognise import DIAGNOSTIC
from parsers.report import ParseReport


def _kind(path: Path) -> tuple[str, str]:
    from console.inputs.recognise import recognise

    fmt, note = recognise(path)
    return fmt, note


class IngestJob:
    """The new manifest an ingest builds (the next generation), the parts it wrote and its ledger rows."""

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
            self.flush_rejected()

    def flush_rejected(self) -> None:
        """The rejected lines gathered so far, to the rejected table's writer."""
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
            # Parsed on a worker, with the other files (ingest_cluster.parse_queued): what it says is taken in later.
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
        self.take_report(e, p, out, report)

    def take_report(self, e: dict[str, Any], p: ledger.Plan, out: FileOutcome, report: ParseReport) -> None:
        """A diagnostic log's parse report into its ledger entry ``e`` and its outcome (here or on a worker)."""
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
        name, arrow, report = read_whole(source, kind, e["path"], int(e["file_seq"]))
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
