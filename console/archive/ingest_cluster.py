"""An ingest on a cluster: the inputs prescanned by the workers, and the queued diagnostic logs parsed there.

The local ingest (:mod:`console.archive.ingest_job`) queues the diagnostic logs it plans; here they go to
the workers, one task per file, or per set of files sharing a group of heads
(:mod:`console.archive.group_ingest`), and what the tasks wrote and counted is taken into the ingest.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from console.archive import ledger
from console.archive.derive import Derivation
from console.archive.ingest_job import IngestJob
from console.archive.parse_pass import RECORD_ORDER, ParsedFile, RejectedRows, parse_one_pass
from console.archive.parts import PartWriter
from console.archive.records import expand_records
from parsers.report import ParseReport


def prescan(job: IngestJob, inputs: list[tuple[Path, str]]) -> None:
    """On a cluster, every input hashed, recognised and (a diagnostic log) hinted by the workers, side by
    side, before the ledger plans them: a task per run of files, a few tasks per worker thread (a task per
    file cost the scheduler, in this process, more than the work)."""
    from console.archive.group_ingest import prescan_files
    from console.fleet.engine import in_flight, map_partitions

    files: list[dict[str, Any]] = []
    for path, shown in inputs:
        entry = ledger.find_entry(job.new.files, shown)
        files.append({"path": str(path), "prefix_len": entry["bytes"] if entry is not None else None})
    n = max(1, min(len(files), 2 * in_flight()))
    runs = [files[i * len(files) // n : (i + 1) * len(files) // n] for i in range(n)]
    found = [pre for run in map_partitions(prescan_files, [{"files": r} for r in runs], label="scan") for pre in run]
    for (_path, shown), f, pre in zip(inputs, files, found, strict=True):
        job.prescanned[shown] = (f["prefix_len"], pre)


def parse_queued(job: IngestJob) -> None:
    """The diagnostic files queued for the cluster: one task each, their parts and accounting taken in
    in file order; or, where the new records continue the derivation, one task per set of files sharing
    a group of heads, each parsing and deriving in one pass (:func:`_ingest_groups`)."""
    from console.fleet.engine import map_partitions

    if not job.queued:
        return
    job.day_rows.complete = False  # records stored by the workers
    d = job.derivation
    if (
        d is not None
        and d.grouped
        and not job.dropped_seqs
        and not d.rebuild_all
        and (d.same or not job.old.parts("records"))
    ):
        _ingest_groups(job, d)
        return
    items = [
        {"source": str(src), "shown": e["path"], "file_seq": int(e["file_seq"]), "first_line": p.first_line}
        for src, _path, e, p, _out in job.queued
    ]
    common = {"root": job.root, "generation": job.gen}
    results = map_partitions(parse_diag_file, items, common=common, label="parse")
    for (src, path, e, p, out), res in zip(job.queued, results, strict=True):
        job.new_parts += res.records + res.rejected
        job.new.tables.setdefault("records", []).extend(res.records)
        job.new.tables.setdefault("rejected", []).extend(res.rejected)
        job.new_diag_seqs.append(int(e["file_seq"]))
        job.take_report(e, p, out, res.report)
        if src != path:
            src.unlink()
    job.queued = []


def _ingest_groups(job: IngestJob, d: Derivation) -> None:
    """The queued files parsed, stored and derived in one pass on the workers, a task per set of files
    sharing a group (:mod:`console.archive.group_ingest`); their parts, accounting and derivations taken
    in.  (Another version's, layout's or engine's derivation, or a file replaced: the two-step way.)"""
    from console.archive.derive_groups import group_key_of
    from console.archive.group_ingest import heads_hint, ingest_files, plan_tasks, task_name
    from console.fleet.engine import map_partitions

    key_of = group_key_of(d.settings.sections)
    # The workers' hints where they read the whole file; a grown file's new bytes are hinted here.
    hints = [job.hints[str(src)] if str(src) in job.hints else heads_hint(src) for src, *_ in job.queued]
    plan = plan_tasks(hints, key_of)
    new_seqs = [int(e["file_seq"]) for _src, _path, e, _p, _out in job.queued]
    known = [(int(dev), n) for dev, n in job.new.derived.get("heads", [])] if d.same else []
    items = [
        {
            "key": task_name([hints[i] for i in files], key_of),
            "salt": f"-p{n}",
            "files": [
                {"source": str(src), "shown": e["path"], "file_seq": int(e["file_seq"]), "first_line": p.first_line}
                for src, _path, e, p, _out in (job.queued[i] for i in files)
            ],
        }
        for n, files in enumerate(plan)
    ]
    common = {"root": job.root, "manifest": job.new, "settings": d.settings, "known": known}
    results = map_partitions(ingest_files, items, common={**common, "new_seqs": new_seqs}, label="derive")
    reports: dict[int, ParseReport] = {}
    first_seen: list[tuple[int, int, int, Any]] = []
    for files, res in zip(plan, results, strict=True):
        job.new_parts += res.records + res.rejected
        job.new.tables.setdefault("records", []).extend(res.records)
        job.new.tables.setdefault("rejected", []).extend(res.rejected)
        reports.update(zip(files, res.reports, strict=True))
        first_seen += res.first_seen
        job.synced.update([*res.records, *res.rejected, *(rel for g in res.groups for rel in g.written)])
    for i, (src, path, e, p, out) in enumerate(job.queued):
        job.new_diag_seqs.append(int(e["file_seq"]))
        job.take_report(e, p, out, reports[i])
        if src != path:
            src.unlink()
    # The heads in the order a read of every file meets them: the earlier ingests' first, then the new ones
    # where they first appear (a grown file's new lines sit among older files: the archive is asked then).
    order = None
    if not any(p.action == "grown" for _src, _path, _e, p, _out in job.queued):
        old = set(known)
        new: dict[tuple[int, Any], None] = {}
        for _seq, _line, dev, head in sorted(first_seen, key=lambda t: (t[0], t[1])):
            if (dev, head) not in old:
                new.setdefault((dev, head), None)
        order = [*known, *new]
    d.take_ingested([r.groups for r in results], order)
    job.queued = []


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
