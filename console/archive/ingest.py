"""Ingest files into the archive: once each, growing files from their last offset, published atomically.

One ingest runs under the writers' lock: it removes what killed ingests
left behind, reads every input the ledger says is new (or new bytes of a
grown file), writes Parquet parts under fresh names, recomputes the derived
tables (:mod:`console.archive.derive`) and publishes one new manifest.
Nothing is visible to readers before the publish; a failure (a full disk,
a bad input, ``kill -9``) leaves the previous state current.

The steps have modules of their own: the inputs (:mod:`console.archive.ingest_inputs`), the pass over
the files (:mod:`console.archive.ingest_job`; on a cluster :mod:`console.archive.ingest_cluster`), the
parts closed (:mod:`console.archive.ingest_finish`) and the summary (:mod:`console.archive.ingest_summary`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from console.archive.derive import Derivation
from console.archive.ingest_cluster import parse_queued, prescan
from console.archive.ingest_finish import finish_ledger, finish_records
from console.archive.ingest_inputs import chosen_layout, expand_inputs
from console.archive.ingest_job import IngestJob
from console.archive.ingest_summary import IngestSummary, PhaseClock
from console.archive.store import (
    ArchiveError,
    collect_garbage,
    ensure_layout,
    missing_part,
    publish,
    read_current,
    writer_lock,
)


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
        job = IngestJob(root, current, on_bytes, None)
        summary = IngestSummary(root, current.generation)
        try:
            clock = PhaseClock(summary.phases, summary.phase_ends)
            inputs = expand_inputs(paths, root, summary.warnings)
            job.layout_spec = layout
            job.layout_file, layout = chosen_layout(inputs, layout)
            # The derivation writes into the new manifest, as the records do; on a cluster, per group of heads.
            job.derivation = Derivation(root, job.new, layout, grouped=on_cluster())
            job.derivation.day_rows = job.day_rows
            job.on_cluster = on_cluster()
            if job.on_cluster:
                prescan(job, inputs)
            for path, shown in inputs:
                if on_file is not None:
                    on_file(shown)
                summary.files.append(job.add_file(path, shown))
            parse_queued(job)
            clock.lap("read")
            finish_records(job)
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
            finish_ledger(job)
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
