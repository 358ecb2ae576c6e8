"""One group's pipeline through one ingest: restored from the last ingest's state or made again from every
archived record, fed the new records, its state and tail saved as parts (:mod:`console.archive.derive`)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import itertools
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from console.archive import arrow_np
from console.archive.derive_groups import LINE, group_tag, group_where
from console.archive.derive_settings import fingerprint_of
from console.archive.derive_sink import ArchiveSink
from console.archive.group_records import head_facts, older_records, repeated_records, repeats_per_day
from console.archive.parts import write_part
from console.archive.reader import record_batches
from console.archive.records import ChunkRebuilder
from console.archive.store import DATA, Manifest
from console.engine.pipeline import Pipeline, PipelineSettings
from console.engine.sinks import Sink
from parsers.diag.registry import DiagRegistry

if TYPE_CHECKING:
    from parsers.diag.records import DiagChunk

STATE_TABLE = "pipeline_state"


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
    heads no section uses (:func:`~console.archive.derive_groups.plan_groups`), each fed its new records back
    from their parts.
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
        self.tag = "" if key == LINE else f"-{group_tag(key)}{salt}"
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
            for batch in record_batches(self.root, self.manifest, where=group_where(self.heads, seqs)):
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
        where = group_where(self.heads, None)
        repeated = repeated_records(self.root, self.manifest, where)
        self.overlap_by_day = repeats_per_day(repeated)
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
