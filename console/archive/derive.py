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
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import itertools
import os
import pickle
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from console.analysis.counting.wheels import SYS1, SYS2, WHEEL_SENSOR_ADDRESS
from console.analysis.diag_events import DiagEventSettings
from console.analysis.passages.overlap import overlap_mask
from console.analysis.passages.registers import RegisterTables
from console.analysis.passages.speed_settings import SpeedSettings
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.stream import EventStream, HeadFacts
from console.archive import arrow_np
from console.archive.at_end_empty import at_end_is_empty
from console.archive.day_rows import DayRows
from console.archive.derive_sink import DERIVE_VERSION, ArchiveSink, arrow_table, day_column
from console.archive.head_days import days_of_parts, derive_days
from console.archive.history import at_end_tables
from console.archive.parts import write_part, write_small
from console.archive.reader import heads_in, layout_of, record_batches, speed_settings
from console.archive.records import ChunkRebuilder
from console.archive.store import DATA, Manifest
from console.archive.views import connect
from console.engine.pipeline import Pipeline, PipelineSettings
from console.engine.sinks import Sink
from console.memory import trim_heap
from parsers.diag.registry import DiagRegistry
from parsers.units import NS_PER_DAY

if TYPE_CHECKING:
    from console.layout import Layout
    from parsers.diag.read import DiagChunk

# Written by the pipeline as records are fed (committed, or the tail of the last ingest).
STREAMED = ("passages", "axles", "section_states", "count_ledger", "channel_events")
# Computed over the archive's tables at the end of each ingest.
AT_END = ("health_findings", "crossing_timelines")
DERIVED = (*STREAMED, *AT_END)
STATE_TABLE = "pipeline_state"


def derive_settings(manifest: Manifest, layout: Layout | None) -> PipelineSettings:
    """What the archive's pipeline computes: passages and axles; events and sections on the layout."""

    speed: SpeedSettings = speed_settings(manifest, layout)
    return PipelineSettings(
        speed=speed,
        events=DiagEventSettings(),
        layout=layout,
        sections=layout if layout is not None and layout.sections else None,
        axles=True,
    )


def fingerprint(settings: PipelineSettings, layout_spec: str | None) -> dict[str, Any]:
    """What the derived rows were made with, as the manifest keeps it (JSON): another one, and the next
    ingest makes them again from the records."""
    speed = dataclasses.asdict(settings.speed)
    # Heads' own spacings only where a layout gives some: an archive made before they existed (one spacing
    # for every head) keeps its fingerprint, and resumes.
    own = speed.pop("head_spacing_m")
    if own:
        speed["head_spacing_m"] = [[head, m] for head, m in own]
    return {"version": DERIVE_VERSION, "settings": speed, "layout": layout_spec}


# -- one ingest's derivation ------------------------------------------------------------------------------


@dataclass
class GroupResult:
    """What one group's derivation wrote and knows at the end of an ingest."""

    key: str
    state: str
    committed: dict[str, list[str]]
    tail: dict[str, list[str]]
    final: dict[str, tuple[str, int, int, int, str]]
    heads: list[tuple[int, Any]]
    overlap_by_day: dict[str, int]
    written: list[str]
    rebuilt: bool  # made again from every record: the group's rows of earlier ingests are gone
    first_event_ns: int | None  # the group's first detection event (a line's sections start at the earliest)


@dataclass
class _State:
    """What is pickled between ingests: the pipeline, and the rebuilder that numbers its registers when
    records come back from the archive (the Dask engine's groups)."""

    pipeline: Pipeline
    rebuilder: Any = None


class GroupRun:
    """One group's pipeline through one ingest: restored from the last ingest's state, or started afresh.

    ``key`` names the group: ``*`` is the whole line (the local engine, fed as the files are parsed);
    the Dask engine runs one group per set of sections that share heads, and one per device for the
    heads no section uses (:func:`plan_groups`), each fed its new records back from their parts.
    """

    def __init__(
        self,
        root: Path,
        manifest: Manifest,
        settings: PipelineSettings,
        key: str,
        heads: frozenset[tuple[int, Any]] | None = None,
        salt: str = "",
    ) -> None:
        self.root, self.manifest, self.settings, self.key, self.heads = root, manifest, settings, key, heads
        self.generation = manifest.generation
        # ``salt``: the ingest task that runs the group, in its parts' names (two tasks that both met the group
        # never write the same file; the ingest keeps neither's rows then, see Derivation.take_ingested).
        self.tag = "" if key == LINE else f"-{_tag(key)}{salt}"
        self.sink = ArchiveSink(root, self.generation, "d" + self.tag)
        self.written: list[str] = []  # every part written, removed if the ingest fails
        self.tail_sink: ArchiveSink | None = None
        old = manifest.derived
        state = old.get("states", {}).get(key) if old.get("fingerprint") == fingerprint_of(settings, old) else None
        self.resumed = state is not None
        if state is not None:
            import pyarrow.parquet as pq

            payload = pq.read_table(root / state).column("pipeline")[0].as_py()
            self.state: _State = pickle.loads(payload)  # the archive's own state, written by us
            self.state.pipeline.sink = self.sink
        else:
            self.state = _State(Pipeline(DiagRegistry(), settings, self.sink))
        self.late_before = self.pipeline.late_records
        self._before = np.zeros(0, np.int64)
        self.overlap_by_day: dict[str, int] = dict(old.get("overlap_by_day", {}).get(key, {})) if self.resumed else {}
        # No state to continue (a new archive, another layout or version): the records already archived are
        # read back with the new ones (the caller says which records are new: see older_records).
        self.rebuild = not self.resumed and bool(manifest.parts("records"))
        self.rebuilt = False

    @property
    def pipeline(self) -> Pipeline:
        return self.state.pipeline

    @property
    def registry(self) -> DiagRegistry:
        return self.pipeline.registry

    def begin_file(self) -> None:
        """A new file's records come next: its heads' latest times so far are what it must not go back to."""
        self._before = self.pipeline.acc.head_last_ns.copy()

    def feed(self, chunk: DiagChunk) -> None:
        if self.rebuild or not len(chunk):
            return
        # A file going back into the time an earlier file covered for a head may repeat its records (an
        # overlapping export) or interleave with them: the history is then made again from every record.
        heads = self.pipeline.acc._lookup().head_of(chunk.register_id)
        seen = heads < len(self._before)
        if seen.any() and bool((chunk.time_ns[seen] <= self._before[heads[seen]]).any()):
            self.rebuild = True
            return
        self.pipeline.feed(chunk)

    def feed_archived(self, file_seqs: list[int]) -> None:
        """This ingest's new records of the group's heads, read back from their parts (file by file)."""

        if self.rebuild:
            return
        if self.state.rebuilder is None:
            self.state.rebuilder = ChunkRebuilder(self.registry)
        rebuild = self.state.rebuilder
        # One read of all the files (in file, line order), not one per file: each read opens the archive's
        # views and scans its parts, so per file it cost groups × files scans (minutes for 320 files on Dask).
        # A file of none of the group's records changes nothing here (begin_file twice is begin_file once).
        runs = [file_seqs] if file_seqs == sorted(file_seqs) else [[seq] for seq in file_seqs]
        for seqs in runs:
            last_file = None
            for batch in record_batches(self.root, self.manifest, where=_group_where(self.heads, seqs)):
                for chunk in rebuild.chunks(batch):
                    if chunk.file_id != last_file:
                        self.begin_file()
                        last_file = chunk.file_id
                    self.feed(chunk)

    def must_rebuild(self) -> None:
        """The new records do not continue the history (a file replaced or dropped): made again from all."""
        self.rebuild = True

    def finish(self) -> GroupResult:
        """After the records are written: rebuild if needed, save the state, write the tail."""
        if self.pipeline.late_records > self.late_before or self.pipeline.facts_wrong:
            self.rebuild = True  # records older than the state had closed, or a head's facts guessed wrong
        if self.rebuild:
            self._rebuild()
        state_rel = f"{DATA}/{STATE_TABLE}/g{self.generation:06d}-s{self.tag}.parquet"
        payload = self._snapshot()
        (self.root / state_rel).parent.mkdir(parents=True, exist_ok=True)
        self.written.append(state_rel)
        # A part like any other (a fresh name, published with the manifest): one row, the pickled pipeline.
        write_part(self.root, state_rel, pa.table({"pipeline": arrow_np.binaries([payload], pa.large_binary())}))
        committed = self.sink.close()
        self.written += [rel for rels in committed.values() for rel in rels]
        self.tail_sink = tail_sink = ArchiveSink(self.root, self.generation, "t" + self.tag)
        tail: _State = pickle.loads(payload)  # just made
        tail.pipeline.sink = tail_sink
        outcome = tail.pipeline.finish()
        tail_parts = tail_sink.close()
        self.written += [rel for rels in tail_parts.values() for rel in rels]
        final = outcome.sections.final_states() if outcome.sections is not None else {}
        heads = [(int(d), n) for d, n in tail.pipeline.heads]
        return GroupResult(
            self.key,
            state_rel,
            committed,
            tail_parts,
            final,
            heads,
            self.overlap_by_day,
            list(self.written),
            self.rebuilt,
            tail.pipeline.first_event_ns,
        )

    def abort(self) -> None:
        """A failed ingest: every part this group wrote is removed (no manifest names them)."""
        self.sink.abort()
        if self.tail_sink is not None:
            self.tail_sink.abort()
        for rel in self.written:
            with contextlib.suppress(OSError):
                (self.root / rel).unlink()

    def _snapshot(self) -> bytes:
        pipeline = self.pipeline
        sink, pipeline.sink = pipeline.sink, Sink()
        try:
            buf = io.BytesIO()
            pickle.dump(self.state, buf, protocol=pickle.HIGHEST_PROTOCOL)
            return buf.getvalue()
        finally:
            pipeline.sink = sink

    def _rebuild(self) -> None:
        """Every derived row of the group made again from its archived records, merged as a read of all the
        files together orders them (files whose times interleave give each head's records in time order);
        records a file repeats from another at their seam (overlapping exports) are set aside, as a batch
        read of all the files does (:mod:`console.analysis.passages.overlap`)."""

        self.sink.abort()
        self.sink = ArchiveSink(self.root, self.generation, "d" + self.tag)
        where = _group_where(self.heads, None)
        repeated = repeated_records(self.root, self.manifest, where)
        self.overlap_by_day = _per_day(repeated)
        rebuild = ChunkRebuilder()
        batches = record_batches(self.root, self.manifest, merged=True, on_registers=rebuild.seed, where=where)
        first = next(batches, None)  # the registers are numbered (seeded) before the first batch comes
        facts, steps = head_facts(self.root, self.manifest, rebuild.registry, where)
        pipeline = Pipeline(rebuild.registry, self.settings, self.sink, facts=facts, head_step_s=steps)
        self.state = _State(pipeline, rebuild if self.key != LINE else None)
        for batch in itertools.chain([first] if first is not None else [], batches):
            for chunk in rebuild.chunks(batch):
                if len(repeated["key"]):
                    seq = rebuild.file_seq_of(chunk.file_id)
                    keep = ~np.isin((np.int64(seq) << 32) | chunk.line, repeated["key"])
                    if not keep.all():
                        chunk = chunk.take(keep)
                pipeline.feed(chunk)
        self.rebuild = False
        self.rebuilt = True


LINE = "*"  # the local engine's one group: the whole line
# A head as one text in SQL (device id and counting head), and the same made here.
HEAD_KEY = "concat(device_id, '/', coalesce(counting_head, ''))"


def head_key(device_id: int, name: Any) -> str:
    return f"{int(device_id)}/{name if isinstance(name, str) else ''}"


def _tag(key: str) -> str:
    """A group's key as a short file-name tag."""
    import hashlib

    return hashlib.sha1(key.encode()).hexdigest()[:8]


def _group_where(heads: frozenset[tuple[int, Any]] | None, file_seqs: list[int] | None) -> tuple[str, list[Any]]:
    """A WHERE over ``records`` for a group's heads (None: every head) and some files (None: every file)."""
    conds: list[str] = []
    params: list[Any] = []
    if heads is not None:
        # The devices as constants too: DuckDB then reads only their partitions (device_id is a partition key),
        # not every part of the archive once per group.
        devices = ", ".join(str(d) for d in sorted({int(d) for d, _ in heads})) or "NULL"
        conds.append(f"device_id IN ({devices}) AND {HEAD_KEY} IN (SELECT unnest(?))")
        params.append(sorted({head_key(d, h) for d, h in heads}))
    if file_seqs is not None:
        conds.append("file_seq IN (SELECT unnest(?))")
        params.append(list(file_seqs))
    return " AND ".join(conds), params


def fingerprint_of(settings: PipelineSettings, derived: dict[str, Any]) -> dict[str, Any]:
    return fingerprint(settings, derived.get("layout"))


def group_key_of(layout: Layout | None) -> Callable[[int, Any], str]:
    """The group a head (device id, name) belongs to: the sections sharing heads it bounds (one section engine
    each), else its device (the heads no section uses).  A head's group depends on the head and the layout
    alone, so whoever meets the head first names its group the same."""
    component: dict[str, str] = {}
    if layout is not None:
        parent: dict[str, str] = {}

        def find(x: str) -> str:
            while parent.setdefault(x, x) != x:
                x = parent[x]
            return x

        for sec in layout.sections:
            names = [b.head for b in sec.bounds]
            for other in names[1:]:
                parent[find(other)] = find(names[0])
            find(names[0])
        members: dict[str, list[str]] = {}
        for name in parent:
            members.setdefault(find(name), []).append(name)
        for names in members.values():
            key = "sections:" + "+".join(sorted(names))
            component.update(dict.fromkeys(names, key))

    def key_of(dev: int, name: Any) -> str:
        group = component.get(name) if isinstance(name, str) else None
        return group or f"device:{int(dev)}"

    return key_of


def plan_groups(layout: Layout | None, heads: Iterable[tuple[int, Any]]) -> dict[str, frozenset[tuple[int, Any]]]:
    """The independent groups of heads: the heads of sections that share heads (one section engine each),
    and per device the heads no section uses.  Each runs a pipeline of its own, in parallel."""
    key_of = group_key_of(layout)
    groups: dict[str, set[tuple[int, Any]]] = {}
    for dev, name in heads:
        groups.setdefault(key_of(dev, name), set()).add((int(dev), name))
    return {k: frozenset(v) for k, v in groups.items()}


class Derivation:
    """One ingest's derivation: the pipelines of its groups, and what is computed over the archive at the end.

    Local (the default): one group, the whole line, fed as the files are parsed.  Dask (``mapper``): after
    the records are written, one task per group of heads (:func:`plan_groups`), each reading its new records
    back and carrying its own state; the results come back in group order, so the archive does not depend
    on the engine or the number of workers.
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
                mine = f"-{_tag(r.key)}" if r.key != LINE else ""
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


def derive_group(
    root: Path,
    manifest: Manifest,
    settings: PipelineSettings,
    key: str,
    heads: frozenset[tuple[int, Any]],
    new_seqs: list[int],
    rebuild: bool,
) -> GroupResult:
    """One group's derivation (a Dask task): its new records read back and fed, the state saved.

    Its section engine holds the sections its heads bound, and gives no start rows (the caller writes them,
    at the line's first event)."""
    lay = settings.sections
    if lay is not None:
        names = {name for _, name in heads}
        mine = tuple(sec for sec in lay.sections if all(b.head in names for b in sec.bounds))
        settings = dataclasses.replace(
            settings, sections=dataclasses.replace(lay, sections=mine) if mine else None, start_rows=False
        )
    run = GroupRun(root, manifest, settings, key, heads)
    try:
        if rebuild or (not run.resumed and older_records(root, manifest, heads, new_seqs)):
            run.must_rebuild()
        elif not run.resumed:
            run.rebuild = False  # a group seen first now: its new records are all it has, read as they came
        run.feed_archived(new_seqs)
        return run.finish()
    except BaseException:
        run.abort()
        raise


def older_records(root: Path, manifest: Manifest, heads: frozenset[tuple[int, Any]], new_seqs: list[int]) -> bool:
    """Whether the group's heads have records in files other than this ingest's new ones."""

    cond, params = _group_where(heads, None)
    con, _ = connect(root, manifest, tables=("records",))
    try:
        rows = con.sql(
            f"SELECT count(*) FROM records WHERE {cond} AND file_seq NOT IN (SELECT unnest(?))",
            params=[*params, list(new_seqs)],
        ).fetchall()
    finally:
        con.close()
    return bool(rows and rows[0][0])


_RECORD_PRINT = "hash(time, diag_id, device_id, counting_head, channel, address, label, value)"


def repeated_records(root: Path, manifest: Manifest, where: tuple[str, list[Any]]) -> dict[str, np.ndarray]:
    """The archived records that repeat another file's at a seam: ``key`` (file_seq << 32 | line), sorted,
    and their ``time_ns``.  Only heads whose files' time ranges intersect are compared record by record."""

    none = {"key": np.zeros(0, np.int64), "time_ns": np.zeros(0, np.int64)}
    con, _ = connect(root, manifest, tables=("records",))
    try:
        cond, params = where
        w = f" WHERE {cond}" if cond else ""
        spans = con.sql(
            f"SELECT device_id, counting_head, file_seq, min(time) AS lo, max(time) AS hi FROM records{w} "
            "GROUP BY ALL ORDER BY device_id, counting_head, file_seq",
            params=params,
        ).fetchall()
        suspects: set[tuple[int, str]] = set()
        latest: dict[tuple[int, str], Any] = {}
        for dev, head, _seq, lo, hi in spans:  # per head and file: a few hundred rows
            k = (dev, head)
            if k in latest and lo <= latest[k]:
                suspects.add(k)
            latest[k] = max(latest.get(k, hi), hi)
        if not suspects:
            return none
        rows = con.sql(
            "SELECT file_seq, line, device_id, counting_head, epoch_ns(time) AS t, "
            f"{_RECORD_PRINT} AS fp "
            f"FROM records WHERE {HEAD_KEY} IN (SELECT unnest(?)) ORDER BY file_seq, line",
            params=[sorted(head_key(d, h) for d, h in suspects)],
        ).fetchnumpy()

        def whole_files(fa: int, fb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            # Every record of the two files (all heads, all boards), as the batch read compares them.
            got = []
            for seq in (fa, fb):
                r = con.sql(
                    f"SELECT line, {_RECORD_PRINT} AS fp FROM records WHERE file_seq = ? ORDER BY line",
                    params=[seq],
                ).fetchnumpy()
                got += [(np.int64(seq) << 32) | r["line"].astype(np.int64), r["fp"].astype(np.uint64)]
            return got[0], got[1], got[2], got[3]

        import pandas as pd

        head = pd.factorize(pd.MultiIndex.from_arrays([rows["device_id"], rows["counting_head"]]))[0]
        mask = overlap_mask(
            rows["file_seq"].astype(np.int64),
            head.astype(np.int64),
            rows["fp"].astype(np.uint64),
            rows["t"].astype(np.int64),
            key=(rows["file_seq"].astype(np.int64) << 32) | rows["line"].astype(np.int64),
            whole_files=whole_files,
        )
    finally:
        con.close()
    key = (rows["file_seq"].astype(np.int64)[mask] << 32) | rows["line"].astype(np.int64)[mask]
    order = np.argsort(key)
    return {"key": key[order], "time_ns": rows["t"].astype(np.int64)[mask][order]}


def head_facts(
    root: Path, manifest: Manifest, registry: DiagRegistry, where: tuple[str, list[Any]]
) -> tuple[dict[int, Any], np.ndarray]:
    """Per head key of ``registry`` (its registers numbered), what a read of every record knows of it: the
    facts detection events count by, and its stamps' resolution (axles pair by it)."""

    con, _ = connect(root, manifest, tables=("records",))
    try:
        rows = con.sql(
            "SELECT device_id, counting_head, bool_or(value = 0) AS releases, "
            "bool_and(subsecond) FILTER (WHERE value = 1) AS fine, "
            "bool_and(epoch_ns(time) % 1000000 = 0) FILTER (WHERE value = 1) AS ms, "
            "bool_and(epoch_ns(time) % 1000 = 0) FILTER (WHERE value = 1) AS us, "
            "bool_or(NOT subsecond) AS whole FROM records "
            "WHERE (label_canonical = 'wheel_sensor' OR (label = '' AND address = ?)) AND channel IN (?, ?) "
            + (f"AND {where[0]} " if where[0] else "")
            + "GROUP BY ALL",
            params=[WHEEL_SENSOR_ADDRESS, SYS1, SYS2, *where[1]],
        ).fetchall()
    finally:
        con.close()
    heads = RegisterTables(registry).update().heads
    key_of = {(int(d), n): k for k, (d, n) in enumerate(heads)}
    steps = np.full(len(heads), np.nan)
    facts: dict[int, Any] = {}
    for dev, name, releases, fine, ms, us, whole in rows:  # per head
        k = key_of.get((int(dev), name))
        if k is None:
            continue
        facts[k] = HeadFacts(point_mode=not releases, whole_second=bool(whole))
        if fine is not None:
            steps[k] = (1e-3 if ms else 1e-6 if us else 1e-9) if fine else 1.0
    return facts, steps


def _per_day(repeated: dict[str, np.ndarray]) -> dict[str, int]:
    days, counts = np.unique(repeated["time_ns"] // NS_PER_DAY, return_counts=True)
    return {str(np.datetime64(int(d), "D")): int(n) for d, n in zip(days.tolist(), counts.tolist(), strict=True)}


def _head_list(heads: Any) -> list[tuple[int, Any]]:
    return [(int(d), n) for d, n in heads]
