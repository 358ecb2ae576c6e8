"""The end of an ingest's read: its parts closed and listed in the new manifest.

The records' parts of replaced diagnostic logs rewritten without them, and small parts of a partition
merged (compaction); the ledger's rows and the rejected lines written.
"""

from __future__ import annotations

import os

import numpy as np
import pyarrow as pa

from console.archive import arrow_np
from console.archive.ingest_job import IngestJob
from console.archive.parse_pass import RECORD_ORDER
from console.archive.parts import COMPACT_MAX_ROWS, compact, part_rows, read_part, write_part, write_small


def finish_records(job: IngestJob) -> None:
    """The records' parts closed and listed; those of replaced diagnostic logs rewritten, small ones merged."""
    written = job.records.close()
    if written:
        job.new.tables.setdefault("records", []).extend(written)
        job.new_parts += written
    if job.dropped_seqs:
        job.day_rows.complete = False  # the stored rows count records that leave
        _rewrite_records_without(job, job.dropped_seqs)
    _compact_records(job, set(written))


def _compact_records(job: IngestJob, fresh: set[str]) -> None:
    """Partitions this ingest added a part to, that hold other parts: the small ones merged into one.

    Each ingest of a growing file would otherwise leave one more part per day and board, and a
    query pays for every part its view lists.  The merged part gets a fresh name and replaces the
    parts it holds in the same manifest (old parts are garbage after the publish, as ever).
    """
    by_dir: dict[str, list[str]] = {}
    for rel in job.new.tables.get("records", []):
        by_dir.setdefault(os.path.dirname(rel), []).append(rel)
    for folder, rels in sorted(by_dir.items()):
        if len(rels) < 2 or not fresh.intersection(rels):
            continue
        rows = {rel: part_rows(job.root, rel) for rel in rels}
        chosen: list[str] = []
        total = 0
        for rel in sorted(rels, key=lambda r: rows[r]):  # smallest first: big parts stay as they are
            if total + rows[rel] > COMPACT_MAX_ROWS:
                break
            chosen.append(rel)
            total += rows[rel]
        if len(chosen) < 2:
            continue
        out = compact(job.root, chosen, os.path.join(folder, f"g{job.gen:06d}-c.parquet"), RECORD_ORDER)
        gone = set(chosen)
        job.new.tables["records"] = [r for r in job.new.tables["records"] if r not in gone] + [out]
        for rel in gone.intersection(job.new_parts):
            (job.root / rel).unlink()  # written by this ingest, listed nowhere
        job.new_parts = [r for r in job.new_parts if r not in gone] + [out]


def _rewrite_records_without(job: IngestJob, seqs: set[int]) -> None:
    """Records of replaced diagnostic files leave the partitions that hold them (rewritten once)."""
    kept: list[str] = []
    for rel in job.new.tables.get("records", []):
        if rel in job.new_parts:
            kept.append(rel)
            continue
        table = read_part(job.root, rel)
        mask = ~np.isin(table.column("file_seq").to_numpy(), np.fromiter(seqs, np.int32))
        if mask.all():
            kept.append(rel)
            continue
        if mask.any():
            new_rel = rel.replace(".parquet", f"-x{job.gen:06d}.parquet")
            write_part(job.root, new_rel, table.filter(pa.array(mask)))
            kept.append(new_rel)
            job.new_parts.append(new_rel)
    job.new.tables["records"] = kept


def finish_ledger(job: IngestJob) -> None:
    """The ledger's rows of this ingest and its rejected lines written and listed."""
    if job.ingest_rows:
        rel = write_small(job.root, "ingests", job.gen, "l", arrow_np.table_from_rows(job.ingest_rows))
        if rel is not None:
            job.new.tables.setdefault("ingests", []).append(rel)
            job.new_parts.append(rel)
    job.flush_rejected()
    written = job.rejected.close()
    if written:
        job.new.tables.setdefault("rejected", []).extend(written)
        job.new_parts += written
