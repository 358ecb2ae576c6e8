"""One pass over a diagnostic log: inventory, passages, axles and speeds.

:class:`DiagAccumulator` takes parsed chunks one at a time and keeps only
reductions (activity buckets, wheel detections, the latest identity values,
record counts), so a multi-GB log is analysed in bounded memory.
:meth:`DiagAccumulator.result` turns them into a :class:`DiagAnalysis`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.counting.speed import MPS_TO_KMH
from console.analysis.counting.wheels import (
    DIRECTION_12,
    DIRECTION_21,
    SYS1,
    SYS2,
    PairingSettings,
    axles_frame,
    pair_onsets,
)
from console.analysis.device_table import DeviceTable
from console.analysis.head_table import Heads, head_names, heads_at
from console.analysis.inventory import DeviceInventory
from console.analysis.passages.buckets import (
    AXLES_UNKNOWN_REASONS,
    Columns,
    axles_unknown_codes,
    bucket_index,
    group_extremes,
    merge_buckets,
    record_runs,
    remove_records,
    split_passages,
)
from console.analysis.passages.overlap import fingerprints, overlap_mask
from console.analysis.passages.registers import RegisterTables, inventory
from console.analysis.timefmt import exact_ns, iso_array
from parsers.diag.read import DiagChunk
from parsers.diag.registry import DiagRegistry
from parsers.units import NS

if TYPE_CHECKING:
    import pandas as pd

    from console.layout import Layout


@dataclass(frozen=True)
class SpeedSettings:
    """Line facts and analysis settings (defaults: the Osong tram test line, seed 003)."""

    spacing_m: float = 0.13
    train_length_m: float = 28.6
    # Longer than the 6 s a tram takes over WS4 in the paper, shorter than
    # any headway between two trams.
    idle_gap_s: float = 10.0
    pair_window_s: float = PairingSettings.pair_window_s
    # Above this, a "whole-train speed" is an artefact, not a train.
    max_speed_kmh: float = 400.0
    # Heads (by their Trackinfo name) whose Sys1–Sys2 spacing is not ``spacing_m``: a line of WS4 heads at
    # 0.13 m and a newer type at 0.15 m reads 15 % fast at the one or slow at the other with one spacing.
    head_spacing_m: tuple[tuple[str, float], ...] = ()

    @classmethod
    def of_layout(
        cls,
        layout: Layout | None,
        spacing_m: float | None = None,
        train_length_m: float | None = None,
        idle_gap_s: float = 10.0,
    ) -> SpeedSettings:
        """The line's facts from its layout unless given: each head's spacing (``spacing_m`` given sets one
        for every head), the first consist's length."""
        consist = layout.consist() if layout is not None else None
        per_head: tuple[tuple[str, float], ...] = ()
        if spacing_m is None and layout is not None:
            spacing_m = layout.spacing_m()
            per_head = tuple((h.id, h.spacing_m) for h in layout.heads if h.spacing_m != spacing_m)
        return cls(
            spacing_m=spacing_m if spacing_m is not None else cls.spacing_m,
            train_length_m=train_length_m
            if train_length_m is not None
            else (consist.length_m if consist is not None else cls.train_length_m),
            idle_gap_s=idle_gap_s,
            head_spacing_m=per_head,
        )

    def to_json(self) -> dict[str, Any]:
        """The settings as every JSON document gives them (``head_spacing_m``: the heads not at ``spacing_m``)."""
        return {
            "spacing_m": self.spacing_m,
            "head_spacing_m": dict(self.head_spacing_m),
            "train_length_m": self.train_length_m,
            "idle_gap_s": self.idle_gap_s,
            "pair_window_s": round(self.pair_window_s, 6),
        }

    def spacing_by_head(self, heads: Heads) -> np.ndarray | None:
        """Per head key, the head's spacing in metres; None: ``spacing_m`` for every head."""
        if not self.head_spacing_m:
            return None
        own = dict(self.head_spacing_m)
        return np.array([own.get(n, self.spacing_m) for n in head_names(heads)], np.float64)


@dataclass
class DiagAnalysis:
    """Everything `trackside analyze` reports about a diagnostic log.

    The tables are held as numpy columns; the DataFrames (:attr:`passages`,
    :attr:`axles`, :attr:`wheel_records`, :attr:`activity`) are built on first
    use, so a face that only writes JSON never needs pandas.
    """

    settings: SpeedSettings
    devices: Sequence[DeviceInventory]
    passage_columns: Columns | None  # see _passages; None: no passages
    axle_columns: Columns
    overlap_records: int
    unpaired_detections: int
    # Per input file (in read order): its records set aside as another file's overlap.
    overlap_by_file: list[int] = field(default_factory=list)
    # For the section engine: heads as (device id, name), every wheel-sensor
    # record (head key, channel, time, 1/0), and per head the seconds with records.
    heads: Heads = field(default_factory=list)
    wheel_columns: Columns | None = None
    activity_columns: Columns | None = None
    # The times of the records set aside as overlap (the archive counts them per day).
    overlap_times_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def head_names(self) -> list[str]:
        """Every head's name, by head key."""
        return head_names(self.heads)

    @cached_property
    def passages(self) -> pd.DataFrame:
        return passages_frame(self.passage_columns, self.heads)

    @cached_property
    def axles(self) -> pd.DataFrame:
        return axles_frame(self.axle_columns)

    @cached_property
    def wheel_records(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.wheel_columns) if self.wheel_columns is not None else pd.DataFrame()

    @cached_property
    def activity(self) -> pd.DataFrame:
        import pandas as pd

        return pd.DataFrame(self.activity_columns) if self.activity_columns is not None else pd.DataFrame()

    def passages_json_text(self) -> str:
        """The passages as a JSON array, without pandas where the values allow."""
        from console.analysis.passages.json_text import encode_passages

        if self.passage_columns is None:
            return "[]"
        text = encode_passages(self.passage_columns, self.heads)
        return text if text is not None else passages_json_text(self.passages)

    def passages_json(self) -> list[dict[str, Any]]:
        import json

        return list(json.loads(self.passages_json_text()))

    def to_dict(self, passages: Any = None, devices: Any = None) -> dict[str, Any]:
        """The JSON document's analysis part; ``passages`` and ``devices`` may be pre-encoded text."""
        s = self.settings
        return {
            "settings": s.to_json(),
            "devices": [d.to_dict() for d in self.devices] if devices is None else devices,
            "passages": self.passages_json() if passages is None else passages,
            "overlap_records": self.overlap_records,
            "unpaired_detections": self.unpaired_detections,
        }


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
            self.head_first_ns = np.r_[self.head_first_ns, np.full(size - len(self.head_first_ns), _BIG, np.int64)]
            self.head_last_ns = np.r_[self.head_last_ns, np.full(size - len(self.head_last_ns), _SMALL, np.int64)]
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
        first = int(self.head_first_ns.min()) if len(self.head_first_ns) else _BIG
        return None if first == _BIG else first

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


@dataclass
class PartAnalysis:
    """Passages, axles and unpaired onsets of a set of whole passages' reductions."""

    passages: Columns | None
    axles: Columns
    unpaired: int
    wheel: Columns | None = None
    activity: Columns | None = None


def analyse_parts(
    buckets: Columns,
    detections: list[dict[str, np.ndarray]],
    settings: SpeedSettings,
    keep_releases: bool = False,
    repeated: np.ndarray | None = None,
    head_step_s: np.ndarray | None = None,
    head_spacing_m: np.ndarray | None = None,
) -> PartAnalysis:
    """Merged buckets and wheel detections of whole passages → their passages and axles.

    The batch analysis calls it once for the whole log; the streaming one
    (:mod:`console.analysis.passages.stream`) once per batch of closed passages.
    """
    buckets = split_passages(buckets, settings.idle_gap_s)
    wheel = _wheel_records(detections, buckets, repeated)
    # Without releases every wheel record is an onset: no copy needed.
    onsets = {c: v[wheel["value"] == 1] for c, v in wheel.items()} if keep_releases else wheel
    pairing = PairingSettings(settings.spacing_m, settings.pair_window_s)
    axles, n_unpaired, first_onset = pair_onsets(onsets, pairing, head_step_s, head_spacing_m)
    return PartAnalysis(
        passages=_passages(buckets, onsets, axles, onsets["bucket"][first_onset], settings, head_spacing_m),
        axles=axles,
        unpaired=n_unpaired,
        wheel={c: wheel[c] for c in ("head", "channel", "time_ns", "value", "subsecond")} if keep_releases else None,
        activity={c: buckets[c] for c in ("head", "t_first_ns", "t_last_ns")} if keep_releases else None,
    )


Arrays = dict[str, np.ndarray]
_BIG = np.iinfo(np.int64).max
_SMALL = np.iinfo(np.int64).min
# The time resolution assumed for stamps with a fraction (the speed bounds).
SUBSECOND_RESOLUTION_S = 0.001


def _wheel_records(parts: list[Arrays], buckets: Columns, repeated: np.ndarray | None) -> Arrays:
    """Wheel-sensor records in read order, less those repeated from another file,
    with their bucket row and passage."""
    names = ("head", "channel", "time_ns", "value", "subsecond", "file")
    if not parts:
        empty = {c: np.zeros(0, bool if c == "subsecond" else np.int64) for c in names}
        empty["value"] = np.zeros(0, np.int8)
        return {**empty, "bucket": np.zeros(0, np.int64), "passage": np.zeros(0, np.int64)}
    cols = {c: np.concatenate([part[c] for part in parts]) for c in names}
    row = bucket_index(buckets, cols["head"], cols["time_ns"])
    keep = row >= 0
    if repeated is not None:
        keep &= ~repeated[np.concatenate([part["record"] for part in parts])]
    if keep.all():  # nothing to drop: no copy
        cols["bucket"] = row
    else:
        cols = {c: v[keep] for c, v in cols.items()}
        cols["bucket"] = row[keep]
    if len(parts) > 1 and (cols["file"] != cols["file"][0]).any():
        order = _merged_order(cols["head"], cols["file"], cols["time_ns"])
        cols = {c: v[order] for c, v in cols.items()}
    cols["passage"] = buckets["passage"][cols["bucket"]]
    return cols


def _merged_order(head: np.ndarray, file: np.ndarray, time_ns: np.ndarray) -> np.ndarray:
    """Read order → one log's order: by time; equal times by file, each file in its own order.

    Equal whole-second stamps from two files meet at a seam (a pull that
    ends mid-second, the next that begins there): per head, the file whose
    records begin earlier holds the earlier part of that second, whatever
    order the files were given in; where both begin in the same second (the
    head's first passage at the seam), the one that ends earlier (the earlier
    pull, its copy of the seam set aside as overlap).
    """
    key = head * (int(file.max()) + 1) + file
    groups, inverse = np.unique(key, return_inverse=True)
    first = np.full(len(groups), _BIG, np.int64)
    np.minimum.at(first, inverse, time_ns)
    last = np.full(len(groups), -_BIG, np.int64)
    np.maximum.at(last, inverse, time_ns)
    g_head = groups // (int(file.max()) + 1)
    g_order = np.lexsort((groups, last, first, g_head))  # per head: by first time, last time, then file
    rank = np.empty(len(groups), np.int64)
    rank[g_order] = np.arange(len(groups))
    return np.lexsort((np.arange(len(time_ns)), rank[inverse], time_ns))


def _group_min(n: int, group: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = np.full(n, _BIG, np.int64)
    np.minimum.at(out, group, values)
    return out


def _group_max(n: int, group: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = np.full(n, _SMALL, np.int64)
    np.maximum.at(out, group, values)
    return out


def _or_nan(values: np.ndarray, sentinel: int) -> np.ndarray:
    return np.where(values == sentinel, np.nan, values.astype(np.float64))


PASSAGE_BASES = (None, "detections", "records")
PASSAGE_DIRECTIONS = (None, DIRECTION_12, DIRECTION_21, "mixed")  # the direction codes 0, 1, 2, 3
PASSAGE_KINDS = ("train", "damping", "status")


def _passages(
    buckets: Columns,
    onsets: Arrays,
    axles: Arrays,
    axle_bucket: np.ndarray,
    s: SpeedSettings,
    head_spacing_m: np.ndarray | None = None,
) -> Columns | None:
    """One row per passage, every figure vectorized over passages (no groupby per record).

    The columns of :data:`PASSAGE_COLUMNS`, except that the text columns are
    codes: ``head`` (into the head list), ``direction`` (into
    ``wheels.DIRECTIONS``, 3: mixed), ``whole_train_basis`` (into ``PASSAGE_BASES``)
    and ``kind`` (into ``PASSAGE_KINDS``); ``axle_speeds_kmh`` holds the per-axle
    speeds that ``axle_speeds_start``/``stop`` index.
    """
    if len(buckets["head"]) == 0:
        return None
    # Buckets are sorted by head and second, so a passage is a run of rows.
    passage = buckets["passage"]
    at = np.flatnonzero(np.r_[True, passage[1:] != passage[:-1]])
    n = len(at)

    def col(name: str) -> np.ndarray:
        return buckets[name]

    head = col("head")[at]
    spacing_m = head_spacing_m[head] if head_spacing_m is not None else s.spacing_m
    start_ns = np.minimum.reduceat(col("t_first_ns"), at)
    end_ns = np.maximum.reduceat(col("t_last_ns"), at)
    records = np.add.reduceat(col("records"), at)
    rec_first = {c: _or_nan(np.minimum.reduceat(col(f"t_first_sys{c}_ns"), at), _BIG) for c in (SYS1, SYS2)}
    rec_last = {c: _or_nan(np.maximum.reduceat(col(f"t_last_sys{c}_ns"), at), _SMALL) for c in (SYS1, SYS2)}

    # Wheel onsets per passage and system.
    op, och, ot = onsets["passage"], onsets["channel"], onsets["time_ns"]
    det_n, det_first, det_last = {}, {}, {}
    for c in (SYS1, SYS2):
        det_n[c], least, greatest = group_extremes(n, op, ot, och, c)
        det_first[c] = _or_nan(least, _BIG)
        det_last[c] = _or_nan(greatest, _SMALL)
    n_onsets = np.bincount(op, minlength=n)
    subsecond = (n_onsets > 0) & (np.bincount(op[~onsets["subsecond"]], minlength=n) == 0)

    # Axles belong to the passage of the bucket holding their earlier onset (``axle_bucket``: that row).
    ax_ok = axle_bucket >= 0
    ax_p = passage[axle_bucket[ax_ok]]
    ax_dir = axles["direction"][ax_ok]
    n_axles = np.bincount(ax_p, minlength=n)
    n12 = np.bincount(ax_p[ax_dir == 1], minlength=n)
    n21 = np.bincount(ax_p[ax_dir == 2], minlength=n)
    direction = np.zeros(n, np.int8)  # codes: see passages_frame
    direction[n12 > n21] = 1
    direction[n21 > n12] = 2
    direction[(n12 > 0) & (n12 == n21)] = 3
    # Per-axle speeds stay one array sorted by passage and time; each passage
    # holds [start, stop) into it.
    speed = axles["speed_kmh"][ax_ok]
    timed = ~np.isnan(speed)
    timed_p, timed_t, timed_v = ax_p[timed], axles["time_ns"][ax_ok][timed], speed[timed]
    # Axles come by head, each head's in time: the sort is mostly not needed (stable: the same order either way).
    if not bool(np.all((timed_p[1:] > timed_p[:-1]) | ((timed_p[1:] == timed_p[:-1]) & (timed_t[1:] >= timed_t[:-1])))):
        order = np.lexsort((timed_t, timed_p))
        timed_p, timed_v = timed_p[order], timed_v[order]
    n_timed = np.bincount(timed_p, minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        axle_mean = np.bincount(timed_p, weights=timed_v, minlength=n) / n_timed

    # Paper's per-second method: records at the head in the first detection second.
    first_bucket = _group_min(n, op, onsets["bucket"])
    has = first_bucket != _BIG
    fb = np.where(has, first_bucket, 0)
    detection_second_ns = np.where(has, col("second")[fb] * NS, np.nan)
    records_in_second = np.where(has, col("records")[fb], np.nan)

    # Whole-train: entering system's first record → leaving system's last.
    reverse = direction == 2
    both = (det_n[SYS1] > 0) & (det_n[SYS2] > 0)
    enter = np.where(reverse, 2, 1)
    leave = 3 - enter
    enter_first = np.where(
        both,
        np.where(enter == 1, det_first[SYS1], det_first[SYS2]),
        np.where(enter == 1, rec_first[SYS1], rec_first[SYS2]),
    )
    leave_last = np.where(
        both,
        np.where(leave == 2, det_last[SYS2], det_last[SYS1]),
        np.where(leave == 2, rec_last[SYS2], rec_last[SYS1]),
    )
    duration = (leave_last - enter_first) / NS
    with np.errstate(invalid="ignore", divide="ignore"):
        whole = np.where(duration > 0, (s.train_length_m + spacing_m) / duration * MPS_TO_KMH, np.nan)
    # A status dump with no wheel in it spans milliseconds: as a "train" it
    # would run at thousands of km/h.  No train is faster than max_speed_kmh.
    implausible = whole > s.max_speed_kmh
    whole = np.where(implausible, np.nan, whole)
    basis = np.where(both, 1, 2).astype(np.int8)
    basis[np.isnan(duration) | (duration <= 0) | implausible] = 0
    # Resolution: each stamp is the true time cut down to its resolution r, so
    # the true duration lies within (d - r, d + r) and the speed between
    # these bounds.  Sub-second stamps are taken as millisecond-exact (at
    # worst; microsecond logs are better).  No upper bound within one step.
    whole_second = (np.add.reduceat(col("records_whole_second"), at) > 0) | ((n_onsets > 0) & ~subsecond)
    resolution_s = np.where(whole_second, 1.0, SUBSECOND_RESOLUTION_S)
    measured = basis > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        length_m = s.train_length_m + spacing_m
        whole_min = np.where(measured, length_m / (duration + resolution_s) * MPS_TO_KMH, np.nan)
        whole_max = np.where(
            measured & (duration > resolution_s), length_m / (duration - resolution_s) * MPS_TO_KMH, np.nan
        )
    stop = np.cumsum(n_timed)
    return {
        "head": head,
        "start_ns": start_ns,
        "end_ns": end_ns,
        "duration_s": (end_ns - start_ns) / NS,
        "records": records,
        "detections_sys1": det_n[SYS1],
        "detections_sys2": det_n[SYS2],
        "axles": n_axles,
        "direction": direction,
        "detection_second_ns": detection_second_ns,
        "records_in_detection_second": records_in_second,
        "speed_kmh_per_second_method": spacing_m * records_in_second * MPS_TO_KMH,
        "speed_kmh_whole_train": whole,
        "speed_kmh_whole_train_min": whole_min,
        "speed_kmh_whole_train_max": whole_max,
        "whole_train_basis": basis,
        "whole_train_duration_s": duration,
        "axle_speeds_start": stop - n_timed,
        "axle_speeds_stop": stop,
        "speed_kmh_per_axle_mean": axle_mean,
        "subsecond": subsecond,
        "time_resolution_s": resolution_s,
        # A train: axles counted, or (the paper's whole-second excerpts) a
        # plausible Sys1→Sys2 span.  A damping: wheel-sensor onsets but no
        # axle (one system only: a trolley, metal).  Else a status dump.
        "kind": np.select([(n_axles > 0) | ~np.isnan(whole), n_onsets > 0], [0, 1], default=2).astype(np.int8),
        "axle_speeds_kmh": timed_v,
    }


def passages_frame(cols: Columns | None, heads: Heads) -> pd.DataFrame:
    """The passages table (:data:`PASSAGE_COLUMNS`) from :func:`_passages`' columns."""
    import pandas as pd

    if cols is None:
        return pd.DataFrame(columns=list(PASSAGE_COLUMNS))
    # Only the heads of these passages are looked up: a log may have a million heads.
    used, inverse = np.unique(cols["head"], return_inverse=True)
    used_dev, used_names = heads_at(heads, used)
    head_name = np.empty(len(used), dtype=object)
    head_name[:] = used_names
    text = {
        "counting_head": head_name[inverse.reshape(-1)],
        "direction": np.array(PASSAGE_DIRECTIONS, dtype=object)[cols["direction"]],
        "whole_train_basis": np.array(PASSAGE_BASES, dtype=object)[cols["whole_train_basis"]],
        "kind": np.array(PASSAGE_KINDS, dtype=object)[cols["kind"]],
    }
    data = {"device_id": used_dev[inverse.reshape(-1)], **{c: text.get(c, cols.get(c)) for c in PASSAGE_COLUMNS[1:]}}
    out = pd.DataFrame(data)
    out.attrs["axle_speeds_kmh"] = cols["axle_speeds_kmh"]
    return out


PASSAGE_COLUMNS = (
    "device_id",
    "counting_head",
    "start_ns",
    "end_ns",
    "duration_s",
    "records",
    "detections_sys1",
    "detections_sys2",
    "axles",
    "direction",
    "detection_second_ns",
    "records_in_detection_second",
    "speed_kmh_per_second_method",
    "speed_kmh_whole_train",
    "speed_kmh_whole_train_min",
    "speed_kmh_whole_train_max",
    "whole_train_basis",
    "whole_train_duration_s",
    "axle_speeds_start",
    "axle_speeds_stop",
    "speed_kmh_per_axle_mean",
    "subsecond",
    "time_resolution_s",
    "kind",
)


def frame_columns(p: pd.DataFrame) -> tuple[Columns, list[tuple[int, str]]] | None:
    """The columns and heads :func:`passages_frame` makes ``p`` of (its rows in its order), for the
    byte encoders; None where a value has no such form (a null head, count or flag, a text with no code)."""
    import pandas as pd

    ints = ("start_ns", "end_ns", "records", "detections_sys1", "detections_sys2", "axles")
    if any(p[c].dtype.kind not in "iu" for c in (*ints, "device_id", "axle_speeds_start", "axle_speeds_stop")):
        return None
    if p["subsecond"].dtype.kind != "b" or p["counting_head"].isna().any():
        return None
    dev_code, devs = pd.factorize(p["device_id"].to_numpy(np.int64))
    name_code, names = pd.factorize(p["counting_head"])
    if not all(isinstance(n, str) for n in names):
        return None
    head, pairs = pd.factorize(dev_code.astype(np.int64) * max(len(names), 1) + name_code)
    heads = [(int(devs[k // len(names)]), str(names[k % len(names)])) for k in pairs.tolist()]
    cols: Columns = {"head": head.astype(np.int64)}
    for c in PASSAGE_COLUMNS[2:]:
        if c in ("direction", "whole_train_basis", "kind"):
            values = {"direction": PASSAGE_DIRECTIONS, "whole_train_basis": PASSAGE_BASES, "kind": PASSAGE_KINDS}[c]
            known = [v for v in values if v is not None]
            code = pd.Index(known).get_indexer(pd.Index(p[c].to_numpy(object))).astype(np.int8)  # -1: null, unknown
            if values[0] is None:
                if ((code < 0) != p[c].isna().to_numpy()).any():
                    return None
                code = code + 1
            elif (code < 0).any():
                return None
            cols[c] = code
        else:
            cols[c] = p[c].to_numpy()
    cols["axle_speeds_kmh"] = np.asarray(p.attrs.get("axle_speeds_kmh", np.zeros(0)), np.float64)
    return cols, heads


def iso_strings(ns: pd.Series | np.ndarray) -> np.ndarray:
    """ISO 8601 strings in UTC with Z (:func:`timefmt.iso_array`: milliseconds at least), vectorized; None for NaN."""
    ints, ok = exact_ns(ns)
    out = iso_array(ints)
    out[~ok] = None
    return out


def axle_speed_lists(p: pd.DataFrame) -> list[list[float] | None]:
    """Per passage, its per-axle speeds (km/h, 3 decimals), or None without timing."""
    speeds = np.round(np.asarray(p.attrs.get("axle_speeds_kmh", np.zeros(0)), dtype=float), 3).tolist()
    starts = p["axle_speeds_start"].tolist()
    stops = p["axle_speeds_stop"].tolist()
    return [speeds[a:b] if b > a else None for a, b in zip(starts, stops, strict=True)]


def passages_json_text(p: pd.DataFrame) -> str:
    """The passages as a JSON array (C encoder: fast on 10⁵ passages)."""
    import pandas as pd

    if p.empty:
        return "[]"
    n_det = p["records_in_detection_second"].to_numpy(dtype=float)
    unknown = axles_unknown_codes(p["detections_sys1"], p["detections_sys2"])
    frame = pd.DataFrame(
        {
            "device_id": p["device_id"].to_numpy(np.int64),
            "counting_head": p["counting_head"].astype(object).to_numpy(),
            "start": iso_strings(p["start_ns"]),
            "end": iso_strings(p["end_ns"]),
            "duration_s": p["duration_s"].to_numpy(dtype=float).round(6),
            "records": p["records"].to_numpy(np.int64),
            "axles": p["axles"].to_numpy(np.int64),
            "axles_unknown_reason": np.array(AXLES_UNKNOWN_REASONS, dtype=object)[unknown],
            "detections_sys1": p["detections_sys1"].to_numpy(np.int64),
            "detections_sys2": p["detections_sys2"].to_numpy(np.int64),
            "direction": _objects(p["direction"]),
            "detection_second": iso_strings(p["detection_second_ns"]),
            "records_in_detection_second": pd.arrays.IntegerArray(
                np.nan_to_num(n_det).astype(np.int64), np.isnan(n_det)
            ),
            "speed_kmh_per_second_method": p["speed_kmh_per_second_method"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train": p["speed_kmh_whole_train"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train_min": p["speed_kmh_whole_train_min"].to_numpy(dtype=float).round(3),
            "speed_kmh_whole_train_max": p["speed_kmh_whole_train_max"].to_numpy(dtype=float).round(3),
            "whole_train_basis": _objects(p["whole_train_basis"]),
            "whole_train_duration_s": p["whole_train_duration_s"].to_numpy(dtype=float).round(6),
            "speed_kmh_per_axle": axle_speed_lists(p),
            "speed_kmh_per_axle_mean": p["speed_kmh_per_axle_mean"].to_numpy(dtype=float).round(3),
            "subsecond": p["subsecond"].to_numpy(bool),
            "time_resolution_s": p["time_resolution_s"].to_numpy(dtype=float),
            "kind": _objects(p["kind"]),
        }
    )
    return frame.to_json(orient="records", force_ascii=True, double_precision=10)


def _objects(values: pd.Series) -> np.ndarray:
    # pandas 3 stores these as its string dtype, where missing reads as NaN.
    import pandas as pd

    out = values.astype(object).to_numpy().copy()
    out[pd.isna(values).to_numpy()] = None
    return out


def passages_to_json(p: pd.DataFrame) -> list[dict[str, Any]]:
    """The documented JSON form of the passages table (null where unknown)."""
    import json

    return list(json.loads(passages_json_text(p)))
