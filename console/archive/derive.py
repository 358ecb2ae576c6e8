"""Derived tables: the pipeline's results, written as the records are ingested.

An ingest parses each new file once.  Every chunk of records goes to the
``records`` table and, in the same pass, into the one
:class:`~console.engine.pipeline.Pipeline` that the batch commands drive; its
results are written as they are made (:class:`ArchiveSink`): passages and
axles (partitioned by day and device, a passage and its axles on the day the
passage starts), section states, the count ledger and the channel events
health reads.

**Resuming.**  At the end of an ingest the pipeline's state is saved
(pickled, as a part of the archive): the open passages, the counters, the
events held below the watermark, the section engine.  The rows it would
still give if the data ended there (the *tail*: the open passages closed,
the held events released) are written from a copy of that state and
replaced at the next ingest, which restores the state and feeds only the
new records.  So two ingests give what one ingest of both gives, and a
later ingest never reads the archived records again.

**Rebuilding.**  When the new records do not continue the history (a file
replaced, records older than what the state already closed, another
layout, another version of trackside), the derived tables are made again
from every archived record, read back in ingest order through a fresh
pipeline: the same rows as the ingests that would have given them.

At the end of every ingest, what needs the whole archive is computed from
tables, not records: health findings (the health registers' records and
the channel events), crossing timelines (the fixes), and sections from
sensor frames where there is no diagnostic log.

This module is the ingest's side: one group's run is :mod:`console.archive.group_run`, the groups
:mod:`console.archive.derive_groups`, the settings and fingerprint :mod:`console.archive.derive_settings`,
the reads of a group's archived records :mod:`console.archive.group_records`.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.diag_events import DiagEventSettings
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.stream import EventStream
from console.archive.at_end_empty import at_end_is_empty
from console.archive.day_rows import DayRows
from console.archive.derive_groups import LINE, group_tag, plan_groups
from console.archive.derive_settings import derive_settings, fingerprint
from console.archive.derive_sink import ArchiveSink, arrow_table, day_column
from console.archive.group_run import STATE_TABLE, GroupResult, GroupRun, derive_group
from console.archive.head_days import days_of_parts, derive_days
from console.archive.history import at_end_tables
from console.archive.parts import write_small
from console.archive.reader import heads_in, layout_of
from console.archive.store import Manifest
from console.memory import trim_heap
from parsers.diag.registry import DiagRegistry
from parsers.units import NS_PER_DAY

if TYPE_CHECKING:
    from parsers.diag.records import DiagChunk

# Written by the pipeline as records are fed (committed, or the tail of the last ingest).
STREAMED = ("passages", "axles", "section_states", "count_ledger", "channel_events")
# Computed over the archive's tables at the end of each ingest.
AT_END = ("health_findings", "crossing_timelines")
DERIVED = (*STREAMED, *AT_END)


class Derivation:
    """One ingest's derivation: the pipelines of its groups, and what is computed over the archive at the end.

    Local (the default): one group, the whole line, fed as the files are parsed.  Dask (``mapper``): after
    the records are written, one task per group of heads (:func:`~console.archive.derive_groups.plan_groups`),
    each reading its new records back and carrying its own state; the results come back in group order, so the
    archive does not depend on the engine or the number of workers.
    """

    def __init__(self, root: Path, manifest: Manifest, layout_spec: str | None, grouped: bool = False) -> None:
        self.root = root
        self.manifest = manifest
        self.spec = layout_spec if layout_spec is not None else manifest.derived.get("layout")
        self.layout = layout_of(self.spec)
        self.settings = derive_settings(manifest, self.layout)
        self.fingerprint = fingerprint(self.settings, self.spec)
        self.grouped = grouped
        self.generation = manifest.generation
        old = manifest.derived
        self.same = old.get("fingerprint") == self.fingerprint and (LINE in old.get("states", {})) != grouped
        if not self.same:  # another version, layout or engine: every group made again from the records
            self._drop_parts({t: manifest.parts(t) for t in DERIVED})
            manifest.derived = {"layout": self.spec, "fingerprint": self.fingerprint}
        else:
            for rels in old.get("tails", {}).values():  # the last ingest's tails are made again
                self._drop_parts(rels)
        self.line = None if grouped else GroupRun(root, manifest, self.settings, LINE)
        self.rebuild_all = False
        self.results: list[GroupResult] = []
        # Groups the ingest's own tasks derived as they parsed (group_ingest), by key; None: none did.
        self.ingested: dict[str, GroupResult] | None = None
        self.ingested_heads: list[tuple[int, Any]] = []
        self.ingested_twice: list[str] = []  # groups two tasks met: derived again from their records
        self.head_order: list[tuple[int, Any]] | None = None
        # The per-day inventory figures the ingest's read gathered (console.archive.day_rows); None: none.
        self.day_rows: DayRows | None = None
        self.records_before = bool(manifest.parts("records"))  # the archive held records before this ingest

    def _drop_parts(self, tables: dict[str, list[str]]) -> None:
        for table, rels in tables.items():
            gone = set(rels)
            self.manifest.tables[table] = [r for r in self.manifest.parts(table) if r not in gone]

    @property
    def registry(self) -> DiagRegistry | None:
        """The registry the files are parsed into (the local engine's pipeline's own), else None."""
        return self.line.registry if self.line is not None else None

    def begin_file(self) -> None:
        if self.line is not None:
            self.line.begin_file()

    def feed(self, chunk: DiagChunk) -> None:
        if self.line is not None:
            self.line.feed(chunk)

    def must_rebuild(self) -> None:
        self.rebuild_all = True
        if self.line is not None:
            self.line.must_rebuild()

    def take_ingested(self, results: list[list[GroupResult]], head_order: list[tuple[int, Any]] | None) -> None:
        """The groups the ingest's tasks derived as they parsed (:mod:`console.archive.group_ingest`).

        A group that two tasks met (the plan's hint missed a head they share) is kept from neither: their
        parts of it are removed, and :meth:`finish` derives it from its archived records instead.
        ``head_order``: the archive's heads in the order a read of every file meets them, if known.
        """
        by_key: dict[str, list[GroupResult]] = {}
        for rs in results:
            for r in rs:
                by_key.setdefault(r.key, []).append(r)
        self.ingested = {}
        for key, rs in sorted(by_key.items()):
            self.ingested_heads += [h for r in rs for h in r.heads]
            if len(rs) == 1:
                self.ingested[key] = rs[0]
                continue
            self.ingested_twice.append(key)
            for rel in [rel for r in rs for rel in r.written]:
                with contextlib.suppress(OSError):
                    (self.root / rel).unlink()
        self.head_order = head_order

    def finish(self, new_seqs: list[int], mapper: Any = None) -> list[str]:
        """After the records are written: every group's pipeline finished, its state and tail saved, and the
        tables computed over the archive at the end; the parts written (the manifest updated, not published)."""
        if self.line is not None:
            self.results = [self.line.finish()]
        else:
            self.results = self._run_groups(new_seqs, mapper)
        parts: list[str] = []
        derived = self.manifest.derived
        states: dict[str, str] = {}
        tails: dict[str, dict[str, list[str]]] = {}
        overlap: dict[str, dict[str, int]] = {}
        finals: dict[str, tuple[str, int, int, int, str]] = {}
        for r in self.results:
            if r.rebuilt:  # the group's rows of earlier ingests are replaced
                mine = f"-{group_tag(r.key)}" if r.key != LINE else ""
                for table in STREAMED:
                    self.manifest.tables[table] = [
                        rel for rel in self.manifest.parts(table) if mine not in os.path.basename(rel)
                    ]
        for r in self.results:
            parts += r.written
            states[r.key] = r.state
            tails[r.key] = r.tail
            overlap[r.key] = r.overlap_by_day
            finals.update(r.final)
            for table in STREAMED:
                self.manifest.tables[table] = (
                    self.manifest.parts(table) + r.committed.get(table, []) + r.tail.get(table, [])
                )
        self.manifest.tables[STATE_TABLE] = sorted(states.values())
        if self.line is None:
            parts += self._start_rows()
        heads = self._head_order()
        order = {s.id: i for i, s in enumerate(self.layout.sections)} if self.layout is not None else {}
        derived.update(
            {
                "layout": self.spec,
                "tables": list(DERIVED),
                "fingerprint": self.fingerprint,
                "states": states,
                "tails": tails,
                "heads": [[int(d), n] for d, n in heads],
                # The report of the whole archive shows each section's final state (report --archive reads it).
                "sections_final": {sid: list(finals[sid]) for sid in sorted(finals, key=lambda s: order.get(s, 0))},
                # Records set aside as another file's overlap, per group and day (a report counts its window's).
                "overlap_by_day": overlap,
            }
        )
        parts += self._at_end(heads)
        # The inventory's figures per day: the days this ingest's records lie in, or every day when the
        # derivation was made again (another version, a file replaced).
        fresh = None if not self.same or self.rebuild_all else days_of_parts(self._records_of_this_ingest())
        if fresh is None and not self.records_before and self.day_rows is not None:
            # A new archive: every day is this ingest's, no earlier rows to merge with.
            self.day_rows.first = True
            fresh = days_of_parts(self.manifest.parts("records"))
        trim_heap()  # the at-end tables' freed memory given back before DuckDB's aggregates take their own
        parts += derive_days(self.root, self.manifest, self.generation, fresh, self.day_rows)
        return parts

    def _records_of_this_ingest(self) -> list[str]:
        mine = f"g{self.generation:06d}-"
        return [rel for rel in self.manifest.parts("records") if os.path.basename(rel).startswith(mine)]

    def _run_groups(self, new_seqs: list[int], mapper: Any) -> list[GroupResult]:
        old = self.manifest.derived
        known = [(int(d), n) for d, n in old.get("heads", [])] if self.same else []
        done = self.ingested or {}
        # The new files' heads: as the ingest's tasks met them, else from the records they wrote.
        fresh = self.ingested_heads if self.ingested is not None else heads_in(self.root, self.manifest, new_seqs)
        groups = plan_groups(self.layout, dict.fromkeys([*known, *fresh]))
        tasks: list[dict[str, Any]] = [
            {"key": key, "heads": heads, "new_seqs": new_seqs, "rebuild": self.rebuild_all}
            for key, heads in sorted(groups.items())
            if key not in done  # the groups no task met (no new record), or two did: derived here
        ]
        common: dict[str, Any] = {"root": self.root, "manifest": self.manifest, "settings": self.settings}
        if not tasks:
            ran: list[GroupResult] = []
        elif mapper is None:
            ran = [derive_group(**common, **t) for t in tasks]
        else:
            ran = list(mapper(derive_group, tasks, common))
        by_key = {**done, **{r.key: r for r in ran}}
        return [by_key[k] for k in sorted(by_key)]

    def _start_rows(self) -> list[str]:
        """The sections' start rows, at the line's first event (the groups' pipelines give none): one small part,
        made again at each ingest (an older record may move the start)."""
        lay = self.settings.sections
        derived = self.manifest.derived
        firsts = [r.first_event_ns for r in self.results if r.first_event_ns is not None]
        old = derived.get("sections_start_ns")
        if old is not None:
            firsts.append(int(old))
        for rel in derived.get("start_parts", []):
            self._drop_parts({"section_states": [rel]})
        derived["start_parts"] = []
        if lay is None or not firsts:
            return []

        start = min(firsts)
        derived["sections_start_ns"] = start
        sink = ArchiveSink(self.root, self.generation, "d-start")
        sink.transitions(SectionEngine(lay, initial=self.settings.initial, start_ns=start).take_history()[0])
        written = sink.close()
        rels = written.get("section_states", [])
        self.manifest.tables["section_states"] = self.manifest.parts("section_states") + rels
        derived["start_parts"] = rels
        return rels

    def _head_order(self) -> list[tuple[int, Any]]:
        if self.line is not None:
            return self.results[0].heads

        # Several groups: the heads in the order a read of every file meets them.
        if self.head_order is not None:
            return self.head_order
        return heads_in(self.root, self.manifest, None)

    def abort(self) -> None:
        if self.line is not None:
            self.line.abort()
        ingested = list((self.ingested or {}).values())
        for rel in [rel for r in [*self.results, *ingested] for rel in r.written]:
            with contextlib.suppress(OSError):
                (self.root / rel).unlink()

    def _at_end(self, heads: list[tuple[int, Any]]) -> list[str]:
        """Health findings, crossing timelines and the sections of sensor frames: over the archive's tables."""

        warnings = EventStream(self.layout, DiagEventSettings()).warnings(heads)
        self.manifest.derived["warnings"] = warnings
        written: list[str] = []
        # Nothing for them to find (no layout, no health register, no other input): not read back, not imported.
        empty = at_end_is_empty(self.manifest, self.spec, self.registry)
        frames = {} if empty else at_end_tables(self.root, self.manifest, self.spec, warnings)
        for name in AT_END:
            self.manifest.tables[name] = []
        for name, df in frames.items():
            if df is None or df.empty:
                continue
            table = arrow_table(df)
            if name in ("section_states", "count_ledger"):  # the sections of sensor frames
                df = df.sort_values("time_ns", kind="stable")
                table = arrow_table(df).append_column("day", day_column(df["time_ns"].to_numpy(np.int64) // NS_PER_DAY))
            rel = write_small(self.root, name, self.generation, "e", table)
            if rel:
                written.append(rel)
                # Frame sections (no diagnostic log) are made again whole at each ingest.
                self.manifest.tables[name] = [rel]
        return written
