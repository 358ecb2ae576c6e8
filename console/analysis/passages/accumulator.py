"""One pass over a diagnostic log: inventory, passages, axles and speeds.

:class:`DiagAccumulator` takes parsed chunks one at a time and keeps only
reductions (activity buckets, wheel detections, the latest identity values,
record counts), so a multi-GB log is analysed in bounded memory.
:meth:`DiagAccumulator.result` turns them into a :class:`~console.analysis.passages.diag_analysis.DiagAnalysis`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from console.analysis.device_table import DeviceTable
from console.analysis.passages.buckets import INT64_MAX, INT64_MIN, Columns, merge_buckets, record_runs, remove_records
from console.analysis.passages.diag_analysis import DiagAnalysis
from console.analysis.passages.overlap import fingerprints, overlap_mask
from console.analysis.passages.part_analysis import analyse_parts
from console.analysis.passages.registers import RegisterTables, inventory
from console.analysis.passages.speed_settings import SpeedSettings
from parsers.diag.records import DiagChunk
from parsers.diag.registry import DiagRegistry


@dataclass
class DiagAccumulator:
    """Reduce parsed chunks to what the analysis needs, chunk by chunk."""

    registry: DiagRegistry
    # Releases (Radsensor 0) are only needed by the section engine's overlap rule.
    keep_releases: bool = False
    # Overlap between files is found record by record: a fingerprint, register
    # and time per record (20 bytes) are kept.  A caller reading one file
    # turns it off (nothing can overlap), so memory stays bounded there.
    track_overlap: bool = True
    _prints: list[dict[str, np.ndarray]] = field(default_factory=list)
    _n_records: int = 0
    _buckets: list[dict[str, np.ndarray]] = field(default_factory=list)
    _detections: list[dict[str, np.ndarray]] = field(default_factory=list)
    _identity: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)
    _tables: RegisterTables | None = None
    # Per head key: first and last record time (int64 max/min: none yet), for the inventory.
    head_first_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    head_last_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def _lookup(self) -> RegisterTables:
        if self._tables is None:
            self._tables = RegisterTables(self.registry)
        return self._tables.update()

    def _track_spans(self, buckets: Columns) -> None:
        n = len(self._lookup().head_device)
        if len(self.head_first_ns) < n:
            # Room for half as many heads again: a log adding heads in every chunk copies them rarely.
            size = max(n, len(self.head_first_ns) * 3 // 2)
            self.head_first_ns = np.r_[self.head_first_ns, np.full(size - len(self.head_first_ns), INT64_MAX, np.int64)]
            self.head_last_ns = np.r_[self.head_last_ns, np.full(size - len(self.head_last_ns), INT64_MIN, np.int64)]
        np.minimum.at(self.head_first_ns, buckets["head"], buckets["t_first_ns"])
        np.maximum.at(self.head_last_ns, buckets["head"], buckets["t_last_ns"])

    def add(self, chunk: DiagChunk) -> np.ndarray:
        """Take in a chunk; its records' head keys (int64)."""
        if len(chunk) == 0:
            return np.zeros(0, np.int64)
        luts = self._lookup()
        rid = chunk.register_id
        # Releases (Radsensor 0) only for the section engine's overlap rule.
        head, buckets, wheel = record_runs(chunk, luts, keep_releases=self.keep_releases)
        self._buckets.append(buckets)
        self._track_spans(buckets)
        first_record = self._n_records
        self._n_records += len(chunk)
        if self.track_overlap:
            self._prints.append(
                {
                    "fp": fingerprints(chunk.time_ns, rid, chunk.value),
                    "rid": rid.astype(np.int32, copy=False),
                    "time_ns": chunk.time_ns,
                    "file": np.full(len(chunk), chunk.file_id, np.int16),
                }
            )

        # Wheel sensor records: onsets for speeds (and releases, when kept).
        if len(wheel):
            self._detections.append(
                {
                    "head": head[wheel],
                    "channel": luts.channel_of(rid[wheel]),
                    "time_ns": chunk.time_ns[wheel],
                    "value": chunk.value[wheel].astype(np.int8),
                    "subsecond": chunk.subsecond[wheel],
                    "file": np.full(len(wheel), chunk.file_id, np.int64),
                    "record": first_record + wheel,
                }
            )

        ident = luts.is_identity[rid]
        if ident.any():
            r, t = rid[ident], chunk.time_ns[ident]
            v, k, d = chunk.value[ident], chunk.data_kind[ident], chunk.data_code[ident]
            order = np.lexsort((t, r))
            r, t, v, k, d = r[order], t[order], v[order], k[order], d[order]
            last = np.flatnonzero(np.append(r[1:] != r[:-1], True))
            for i in last:  # one per identity register: a few dozen per chunk
                prev = self._identity.get(int(r[i]))
                if prev is None or t[i] >= prev[0]:
                    self._identity[int(r[i])] = (int(t[i]), int(v[i]), int(k[i]), int(d[i]))
        return head

    def result(self, settings: SpeedSettings) -> DiagAnalysis:
        luts = self._lookup()
        buckets = merge_buckets(self._buckets)
        self._buckets = []  # reduced: free the per-chunk runs
        repeated, overlap_by_file, overlap_times = self._overlap(luts, buckets)
        detections, self._detections = self._detections, []
        spacing = settings.spacing_by_head(luts.heads)
        part = analyse_parts(buckets, detections, settings, self.keep_releases, repeated, head_spacing_m=spacing)
        return DiagAnalysis(
            settings=settings,
            devices=self.devices(),
            passage_columns=part.passages,
            axle_columns=part.axles,
            overlap_records=sum(overlap_by_file),
            unpaired_detections=part.unpaired,
            overlap_by_file=overlap_by_file,
            heads=luts.heads,
            # Only the section engine reads these: not kept for speeds alone.
            wheel_columns=part.wheel if self.keep_releases else None,
            activity_columns=part.activity if self.keep_releases else None,
            overlap_times_ns=overlap_times,
        )

    def devices(self) -> DeviceTable:
        return inventory(self._lookup(), self.head_first_ns, self.head_last_ns, self._identity)

    def first_record_ns(self) -> int | None:
        """The time of the earliest timed record read so far (None: none yet)."""
        first = int(self.head_first_ns.min()) if len(self.head_first_ns) else INT64_MAX
        return None if first == INT64_MAX else first

    def _overlap(self, luts: RegisterTables, buckets: Columns) -> tuple[np.ndarray | None, list[int], np.ndarray]:
        """Records repeated from another file (a mask over all records, None: none), their count per file
        and their times."""
        n_files = len(self.registry.files)
        prints, self._prints = self._prints, []
        none = np.zeros(0, np.int64)
        if not prints or n_files < 2:
            return None, [0] * n_files, none
        cols = {c: np.concatenate([p[c] for p in prints]) for c in ("fp", "rid", "time_ns", "file")}
        del prints
        head = luts.head_of(cols["rid"])
        mask = overlap_mask(cols["file"], head, cols["fp"], cols["time_ns"])
        if not mask.any():
            return None, [0] * n_files, none
        remove_records(buckets, head[mask], luts.channel_of(cols["rid"][mask]), cols["time_ns"][mask])
        per_file = np.bincount(cols["file"][mask].astype(np.int64), minlength=n_files)
        return mask, [int(x) for x in per_file], cols["time_ns"][mask].astype(np.int64)


def wheel_columns(luts: RegisterTables, chunk: DiagChunk) -> dict[str, np.ndarray] | None:
    """A chunk's wheel-sensor records (onsets and releases) as the counting reads them, in read order."""
    rid = chunk.register_id
    wheel = luts.is_wheel[rid] & ((chunk.value == 1) | (chunk.value == 0))
    if not wheel.any():
        return None
    r = rid[wheel]
    return {
        "head": luts.head_of(r),
        "channel": luts.channel_of(r),
        "time_ns": chunk.time_ns[wheel],
        "value": chunk.value[wheel].astype(np.int8),
        "subsecond": chunk.subsecond[wheel],
    }
