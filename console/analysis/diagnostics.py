"""One pass over a diagnostic log: inventory, passages, axles and speeds.

:class:`DiagAccumulator` takes parsed chunks one at a time and keeps only
reductions (activity buckets, wheel detections, the latest identity values,
record counts), so a multi-GB log is analysed in bounded memory.
:meth:`DiagAccumulator.result` turns them into a :class:`DiagAnalysis`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import pandas as pd

from console.analysis.inventory import IDENTITY_LABELS, DeviceInventory, IdentityValue, apply_identity
from console.analysis.passages import NS, chunk_buckets, merge_buckets, split_passages
from console.analysis.speed import MPS_TO_KMH
from console.analysis.wheels import (
    DIRECTION_12,
    DIRECTION_21,
    SYS1,
    SYS2,
    WHEEL_SENSOR_ADDRESS,
    PairingSettings,
    pair_axles,
)
from parsers.diag import DATA_KINDS, DiagChunk, DiagRegistry


@dataclass(frozen=True)
class SpeedSettings:
    """Line facts and analysis settings (defaults: the Osong tram test line, seed 003)."""

    spacing_m: float = 0.13
    train_length_m: float = 28.6
    # Longer than the 6 s a tram takes over WS4 in the paper, shorter than
    # any headway between two trams.
    idle_gap_s: float = 10.0
    pair_window_s: float = PairingSettings.pair_window_s


@dataclass
class _Luts:
    head: np.ndarray
    channel: np.ndarray
    is_wheel: np.ndarray
    is_identity: np.ndarray


@dataclass
class DiagAnalysis:
    """Everything `trackside analyze` reports about a diagnostic log."""

    settings: SpeedSettings
    devices: list[DeviceInventory]
    passages: pd.DataFrame
    axles: pd.DataFrame
    overlap_records: int
    unpaired_detections: int
    head_names: list[str]

    def passages_json(self) -> list[dict[str, Any]]:
        return passages_to_json(self.passages)

    def to_dict(self) -> dict[str, Any]:
        s = self.settings
        return {
            "settings": {
                "spacing_m": s.spacing_m,
                "train_length_m": s.train_length_m,
                "idle_gap_s": s.idle_gap_s,
                "pair_window_s": s.pair_window_s,
            },
            "devices": [d.to_dict() for d in self.devices],
            "passages": self.passages_json(),
            "overlap_records": self.overlap_records,
            "unpaired_detections": self.unpaired_detections,
        }


@dataclass
class DiagAccumulator:
    """Reduce parsed chunks to what the analysis needs, chunk by chunk."""

    registry: DiagRegistry
    _buckets: list[pd.DataFrame] = field(default_factory=list)
    _detections: list[pd.DataFrame] = field(default_factory=list)
    _identity: dict[int, tuple[int, int, int, int]] = field(default_factory=dict)
    _head_keys: dict[tuple[int, str], int] = field(default_factory=dict)
    _head_list: list[tuple[int, str]] = field(default_factory=list)
    _luts: _Luts | None = None
    _luts_len: int = -1

    def _lookup(self) -> _Luts:
        regs = self.registry.registers
        if self._luts is None or self._luts_len != len(regs):
            head = np.empty(len(regs), np.int64)
            for i, r in enumerate(regs):
                key = (r.device_id, r.counting_head)
                if key not in self._head_keys:
                    self._head_keys[key] = len(self._head_list)
                    self._head_list.append(key)
                head[i] = self._head_keys[key]
            self._luts = _Luts(
                head=head,
                channel=np.array([r.channel for r in regs], np.int64),
                is_wheel=np.array(
                    [
                        r.label_canonical == "wheel_sensor" or (not r.label and r.address == WHEEL_SENSOR_ADDRESS)
                        for r in regs
                    ],
                    bool,
                ),
                is_identity=np.array([r.label_canonical in IDENTITY_LABELS for r in regs], bool),
            )
            self._luts_len = len(regs)
        return self._luts

    def add(self, chunk: DiagChunk) -> None:
        if len(chunk) == 0:
            return
        luts = self._lookup()
        rid = chunk.register_id
        head = luts.head[rid]
        channel = luts.channel[rid]
        self._buckets.append(chunk_buckets(head, channel, chunk.time_ns, chunk.file_id))

        wheel = luts.is_wheel[rid] & ((chunk.value == 0) | (chunk.value == 1))
        if wheel.any():
            self._detections.append(
                pd.DataFrame(
                    {
                        "head": head[wheel],
                        "channel": channel[wheel],
                        "time_ns": chunk.time_ns[wheel],
                        "value": chunk.value[wheel].astype(np.int8),
                        "subsecond": chunk.subsecond[wheel],
                        "file": np.full(int(wheel.sum()), chunk.file_id, np.int64),
                    }
                )
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

    def result(self, settings: SpeedSettings) -> DiagAnalysis:
        self._lookup()
        buckets, overlap = merge_buckets(self._buckets)
        buckets = split_passages(buckets, settings.idle_gap_s)
        detections = _chosen_file_only(self._detections, buckets)
        onsets = detections[detections["value"] == 1]
        axles, unpaired = pair_axles(onsets, PairingSettings(settings.spacing_m, settings.pair_window_s))
        head_names = [name for _, name in self._head_list]
        passages = _passages(buckets, onsets, axles, settings, self._head_list)
        return DiagAnalysis(
            settings=settings,
            devices=self._inventory(buckets),
            passages=passages,
            axles=axles,
            overlap_records=overlap,
            unpaired_detections=len(unpaired),
            head_names=head_names,
        )

    def _inventory(self, buckets: pd.DataFrame) -> list[DeviceInventory]:
        reg = self.registry
        devices: dict[int, DeviceInventory] = {}
        for rid, r in enumerate(reg.registers):
            counts = reg.record_counts
            n = int(counts[rid]) if rid < len(counts) else 0
            if n == 0:
                continue
            inv = devices.get(r.device_id)
            if inv is None:
                inv = devices[r.device_id] = DeviceInventory(
                    device_id=r.device_id,
                    device=r.device,
                    type=r.type,
                    gs=r.gs,
                    diag_ids=[],
                    counting_heads=[],
                    channels=[],
                    records=0,
                    first_ns=0,
                    last_ns=0,
                )
            inv.records += n
            if r.diag_id not in inv.diag_ids:
                inv.diag_ids.append(r.diag_id)
            if r.counting_head not in inv.counting_heads:
                inv.counting_heads.append(r.counting_head)
            if r.channel not in inv.channels:
                inv.channels.append(r.channel)
        span = buckets.groupby("head").agg(first=("t_first_ns", "min"), last=("t_last_ns", "max"))
        identity: dict[int, list[IdentityValue]] = {}
        for rid, (_, value, kind, data_code) in self._identity.items():
            r = reg.registers[rid]
            identity.setdefault(r.device_id, []).append(
                IdentityValue(r.label_canonical or "", r.address, value, DATA_KINDS[kind], reg.data.values[data_code])
            )
        for dev_id, inv in devices.items():
            keys = [self._head_keys[(dev_id, h)] for h in inv.counting_heads]
            rows = span.loc[span.index.intersection(keys)]
            inv.first_ns = int(rows["first"].min()) if len(rows) else 0
            inv.last_ns = int(rows["last"].max()) if len(rows) else 0
            inv.diag_ids.sort()
            inv.channels.sort()
            apply_identity(inv, identity.get(dev_id, []))
        return [devices[k] for k in sorted(devices)]


def _chosen_file_only(parts: list[pd.DataFrame], buckets: pd.DataFrame) -> pd.DataFrame:
    """Detections from the file chosen for their bucket (see passages: overlap)."""
    cols = {
        "head": np.int64,
        "channel": np.int64,
        "time_ns": np.int64,
        "value": np.int8,
        "subsecond": bool,
        "file": np.int64,
    }
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=t) for c, t in cols.items()}).assign(passage=pd.Series(dtype=np.int64))
    det = pd.concat(parts, ignore_index=True)
    det["second"] = det["time_ns"] // NS
    keyed = det.merge(
        buckets[["head", "channel", "second", "file", "passage"]],
        on=["head", "channel", "second", "file"],
        how="inner",
    )
    return keyed.drop(columns="second")


def _passages(
    buckets: pd.DataFrame,
    onsets: pd.DataFrame,
    axles: pd.DataFrame,
    s: SpeedSettings,
    heads: list[tuple[int, str]],
) -> pd.DataFrame:
    """One row per passage, every figure vectorized over passages."""
    if buckets.empty:
        return pd.DataFrame(columns=list(PASSAGE_COLUMNS))
    g = buckets.groupby("passage", sort=True)
    p = g.agg(
        head=("head", "first"),
        start_ns=("t_first_ns", "min"),
        end_ns=("t_last_ns", "max"),
        records=("records", "sum"),
    )
    ch = buckets.groupby(["passage", "channel"]).agg(first=("t_first_ns", "min"), last=("t_last_ns", "max"))
    rec_first = ch["first"].unstack()
    rec_last = ch["last"].unstack()

    # Detections (Radsensor onsets) per passage and channel.
    on = onsets.groupby(["passage", "channel"]).agg(
        n=("time_ns", "size"), first=("time_ns", "min"), last=("time_ns", "max"), sub=("subsecond", "all")
    )
    det_n = on["n"].unstack()
    det_first = on["first"].unstack()
    det_last = on["last"].unstack()

    def col(frame: pd.DataFrame, c: int) -> pd.Series:
        return frame[c].reindex(p.index) if c in frame.columns else pd.Series(np.nan, index=p.index)

    p["detections_sys1"] = col(det_n, SYS1).fillna(0).astype(np.int64)
    p["detections_sys2"] = col(det_n, SYS2).fillna(0).astype(np.int64)
    p["subsecond"] = onsets.groupby("passage")["subsecond"].all().reindex(p.index).fillna(False).astype(bool)

    # Axles: assign by (head, second) of the earlier onset.
    ax = axles.assign(second=axles["time_ns"] // NS).merge(
        buckets[["head", "second", "passage"]].drop_duplicates(["head", "second"]),
        on=["head", "second"],
        how="inner",
    )
    ag = ax.groupby("passage")
    p["axles"] = ag.size().reindex(p.index).fillna(0).astype(np.int64)
    n12 = (ax["direction"] == DIRECTION_12).groupby(ax["passage"]).sum().reindex(p.index).fillna(0)
    n21 = (ax["direction"] == DIRECTION_21).groupby(ax["passage"]).sum().reindex(p.index).fillna(0)
    direction = np.full(len(p), None, dtype=object)
    direction[(n12 > n21).to_numpy()] = DIRECTION_12
    direction[(n21 > n12).to_numpy()] = DIRECTION_21
    direction[((n12 > 0) & (n12 == n21)).to_numpy()] = "mixed"
    p["direction"] = direction
    speeds = ax.dropna(subset=["speed_kmh"]).groupby("passage")["speed_kmh"]
    p["speed_kmh_per_axle"] = speeds.agg(list).reindex(p.index)
    p["speed_kmh_per_axle_mean"] = speeds.mean().reindex(p.index)

    # Paper's per-second method: records at the head in the first detection second.
    first_onset = onsets.groupby("passage")["time_ns"].min().reindex(p.index)
    p["detection_second_ns"] = (first_onset // NS) * NS
    per_sec = buckets.groupby(["passage", "second"])["records"].sum()
    key = pd.MultiIndex.from_arrays([p.index, (first_onset // NS).fillna(-1).astype(np.int64)])
    p["records_in_detection_second"] = per_sec.reindex(key).to_numpy()
    p["speed_kmh_per_second_method"] = s.spacing_m * p["records_in_detection_second"] * MPS_TO_KMH

    # Whole-train: entering system's first record → leaving system's last.
    reverse = (p["direction"] == DIRECTION_21).to_numpy()
    both_det = (p["detections_sys1"] > 0) & (p["detections_sys2"] > 0)
    enter_first = np.where(
        both_det,
        np.where(reverse, col(det_first, SYS2), col(det_first, SYS1)),
        np.where(reverse, col(rec_first, SYS2), col(rec_first, SYS1)),
    )
    leave_last = np.where(
        both_det,
        np.where(reverse, col(det_last, SYS1), col(det_last, SYS2)),
        np.where(reverse, col(rec_last, SYS1), col(rec_last, SYS2)),
    )
    duration = (leave_last - enter_first) / NS
    p["whole_train_duration_s"] = duration
    with np.errstate(invalid="ignore", divide="ignore"):
        p["speed_kmh_whole_train"] = np.where(
            duration > 0, (s.train_length_m + s.spacing_m) / duration * MPS_TO_KMH, np.nan
        )
    basis = np.where(both_det, "detections", "records").astype(object)
    basis[np.isnan(duration) | (duration <= 0)] = None
    p["whole_train_basis"] = basis
    p["device_id"] = [heads[h][0] for h in p["head"]]
    p["counting_head"] = [heads[h][1] for h in p["head"]]
    p["duration_s"] = (p["end_ns"] - p["start_ns"]) / NS
    return p.reset_index(drop=True)[list(PASSAGE_COLUMNS)]


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
    "whole_train_basis",
    "whole_train_duration_s",
    "speed_kmh_per_axle",
    "speed_kmh_per_axle_mean",
    "subsecond",
)


def _iso_array(ns: pd.Series) -> list[str | None]:
    from console.analysis.timefmt import iso

    return [None if pd.isna(v) else iso(int(v)) for v in ns]


def passages_to_json(p: pd.DataFrame) -> list[dict[str, Any]]:
    """The documented JSON form of the passages table (null where unknown)."""
    if p.empty:
        return []
    out = pd.DataFrame(
        {
            "device_id": p["device_id"].astype(int),
            "counting_head": p["counting_head"],
            "start": _iso_array(p["start_ns"]),
            "end": _iso_array(p["end_ns"]),
            "duration_s": p["duration_s"].round(6),
            "records": p["records"].astype(int),
            "axles": p["axles"].astype(int),
            "detections": [
                {"sys1": int(a), "sys2": int(b)}
                for a, b in zip(p["detections_sys1"], p["detections_sys2"], strict=True)
            ],
            "direction": p["direction"],
            "detection_second": _iso_array(p["detection_second_ns"]),
            "records_in_detection_second": p["records_in_detection_second"],
            "speed_kmh_per_second_method": p["speed_kmh_per_second_method"].round(3),
            "speed_kmh_whole_train": p["speed_kmh_whole_train"].round(3),
            "whole_train_basis": p["whole_train_basis"],
            "speed_kmh_per_axle": [
                [round(float(x), 3) for x in v] if isinstance(v, list) else None for v in p["speed_kmh_per_axle"]
            ],
            "speed_kmh_per_axle_mean": p["speed_kmh_per_axle_mean"].round(3),
            "subsecond": p["subsecond"].astype(bool),
        }
    )
    records = cast(list[dict[str, Any]], out.astype(object).where(out.notna(), None).to_dict("records"))
    for r in records:
        if r["records_in_detection_second"] is not None:
            r["records_in_detection_second"] = int(r["records_in_detection_second"])
    return records
