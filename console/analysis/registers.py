"""Per-register facts the analysis needs, as numpy tables over the registry.

A log of many boards has many registers (a million heads in the worst
logs we were sent), so nothing here loops over registers in Python: the
facts come from :meth:`DiagRegistry.arrays` and the interners' values,
which grow only at the end, and are extended as new registers appear.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from console.analysis.head_table import HeadTable
from console.analysis.inventory import IDENTITY_LABELS, DeviceInventory, IdentityValue, apply_identity
from console.analysis.wheels import WHEEL_SENSOR_ADDRESS
from parsers.diag import DATA_KINDS, DiagRegistry

_NONE = np.iinfo(np.int64).max


def _text_flags(values: list[str], wanted: frozenset[str]) -> np.ndarray:
    """Per interned string: is it one of ``wanted`` (once per distinct label, not per register)."""
    return np.fromiter((v in wanted for v in values), bool, len(values))


@dataclass
class RegisterTables:
    """Per register id: its counting-head key, channel, and whether it is a wheel sensor or identity register.

    Head keys number the (device id, counting head) pairs in the order their
    first register appeared, as the batch analysis always has.
    """

    registry: DiagRegistry
    head: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    channel: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    is_wheel: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    is_identity: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    head_device: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    head_name_code: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _sorted_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    _sorted_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def update(self) -> RegisterTables:
        """Extend the tables to registers added since the last call."""
        arr = self.registry.arrays()
        n, done = len(arr["device_id"]), len(self.head)
        if n == done:
            return self
        dev = arr["device_id"][done:].astype(np.int64)
        name = arr["counting_head"][done:].astype(np.int64)
        key = (dev << 32) | name
        # Keys already numbered, then new keys in order of first appearance.
        pos = np.searchsorted(self._sorted_keys, key)
        pos_ok = np.minimum(pos, max(len(self._sorted_keys) - 1, 0))
        known = (
            (pos < len(self._sorted_keys)) & (self._sorted_keys[pos_ok] == key)
            if len(self._sorted_keys)
            else (np.zeros(len(key), bool))
        )
        head = np.where(known, self._sorted_ids[pos_ok] if len(self._sorted_ids) else 0, -1)
        if not known.all():
            new_keys, first, inverse = np.unique(key[~known], return_index=True, return_inverse=True)
            rank = np.empty(len(new_keys), np.int64)
            rank[np.argsort(first, kind="stable")] = np.arange(len(new_keys))
            base = len(self.head_device)
            head[~known] = base + rank[inverse]
            by_rank = np.argsort(rank)
            self.head_device = np.concatenate([self.head_device, new_keys[by_rank] >> 32])
            self.head_name_code = np.concatenate([self.head_name_code, new_keys[by_rank] & 0xFFFFFFFF])
            all_keys = np.concatenate([self._sorted_keys, new_keys])
            all_ids = np.concatenate([self._sorted_ids, base + rank])
            order = np.argsort(all_keys, kind="stable")
            self._sorted_keys, self._sorted_ids = all_keys[order], all_ids[order]
        canon = arr["label_canonical"][done:]
        label = arr["label"][done:]
        canonicals, labels = self.registry.canonicals.values, self.registry.labels.values
        wheel_code = _text_flags(canonicals, frozenset({"wheel_sensor"}))
        ident_code = _text_flags(canonicals, frozenset(IDENTITY_LABELS))
        blank_label = _text_flags(labels, frozenset({""}))
        is_wheel = wheel_code[canon] | (blank_label[label] & (arr["address"][done:] == WHEEL_SENSOR_ADDRESS))
        self.head = np.concatenate([self.head, head])
        self.channel = np.concatenate([self.channel, arr["channel"][done:].astype(np.int64)])
        self.is_wheel = np.concatenate([self.is_wheel, is_wheel])
        self.is_identity = np.concatenate([self.is_identity, ident_code[canon]])
        return self

    @property
    def heads(self) -> HeadTable:
        """(device id, counting head name) per head key, as columns (nothing copied)."""
        return HeadTable(self.head_device, self.head_name_code, self.registry.heads)


def _unique_in_order(group: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (group, value) pairs, per group in order of first appearance."""
    if not len(group):
        return group, value
    key = np.stack([group, value])
    _, first = np.unique(key, axis=1, return_index=True)
    first = np.sort(first)
    order = np.lexsort((first, group[first]))
    return group[first][order], value[first][order]


def inventory(
    tables: RegisterTables,
    head_first_ns: np.ndarray,
    head_last_ns: np.ndarray,
    identity: dict[int, tuple[int, int, int, int]],
) -> list[DeviceInventory]:
    """One entry per device with records, grouped by device with numpy (not per register).

    ``head_first_ns``/``head_last_ns`` are per head key (int64 max/min: none);
    ``identity`` maps identity register ids to their latest (time, value, kind, data code).
    """
    reg = tables.registry
    arr = reg.arrays()
    counts = np.zeros(len(arr["device_id"]), np.int64)
    counts[: len(reg.record_counts)] = reg.record_counts[: len(counts)]
    rid = np.flatnonzero(counts)
    if not len(rid):
        return []
    dev = arr["device_id"][rid].astype(np.int64)
    devices, first_rid = np.unique(dev, return_index=True)
    records = np.bincount(np.searchsorted(devices, dev), weights=counts[rid], minlength=len(devices))
    d_diag, v_diag = _unique_in_order(dev, arr["diag_id"][rid].astype(np.int64))
    d_chan, v_chan = _unique_in_order(dev, arr["channel"][rid].astype(np.int64))
    d_head, v_head = _unique_in_order(dev, tables.head[rid])
    # Each device's span: over its heads' first and last record times.
    n_heads = len(tables.head_device)
    hf = np.full(n_heads, _NONE, np.int64)
    hl = np.full(n_heads, -_NONE, np.int64)
    hf[: len(head_first_ns)] = head_first_ns[:n_heads]
    hl[: len(head_last_ns)] = head_last_ns[:n_heads]
    ident: dict[int, list[IdentityValue]] = {}
    for r, (_, value, kind, data_code) in identity.items():  # a few dozen identity registers
        ident.setdefault(int(arr["device_id"][r]), []).append(
            IdentityValue(
                reg.canonicals.value(int(arr["label_canonical"][r])),
                int(arr["address"][r]),
                value,
                DATA_KINDS[kind],
                reg.data.value(data_code),
            )
        )
    # The pairs are sorted by device: each device's values are one run, cut once.
    at_diag = np.searchsorted(d_diag, devices)
    at_chan = np.searchsorted(d_chan, devices)
    at_head = np.searchsorted(d_head, devices)
    # Every device with records has a head (a register always names one, perhaps ""):
    # its span is over its heads' first and last record times.
    first = np.minimum.reduceat(hf[v_head], at_head)
    last = np.maximum.reduceat(hl[v_head], at_head)
    first[first == _NONE] = 0
    last[last == -_NONE] = 0
    # Lists, not arrays, per device: one tolist per column, then list slices.
    diag_ids = _runs(np.lexsort((v_diag, d_diag)), v_diag, at_diag)
    channels = _runs(np.lexsort((v_chan, d_chan)), v_chan, at_chan)
    head_names = reg.heads.take(tables.head_name_code[v_head])
    head_cuts = [*at_head.tolist(), len(v_head)]
    r0 = rid[first_rid]
    device_names = reg.devices.take(arr["device"][r0])
    type_names = reg.types.take(arr["type"][r0])
    gs_names = reg.gs.take(arr["gs"][r0])
    out = []
    for i, (d, n, f, la) in enumerate(
        zip(devices.tolist(), records.tolist(), first.tolist(), last.tolist(), strict=True)
    ):  # per device: only the object the faces read
        inv = DeviceInventory(
            device_id=d,
            device=device_names[i],
            type=type_names[i],
            gs=gs_names[i],
            diag_ids=diag_ids[i],
            counting_heads=head_names[head_cuts[i] : head_cuts[i + 1]],
            channels=channels[i],
            records=int(n),
            first_ns=f,
            last_ns=la,
        )
        values = ident.get(d)
        if values:
            apply_identity(inv, values)
        out.append(inv)
    return out


def _runs(order: np.ndarray, values: np.ndarray, at: np.ndarray) -> list[list[int]]:
    """Per group (starting at ``at`` in group-sorted pairs), its values in ascending order."""
    flat = values[order].tolist()
    cuts = [*at.tolist(), len(flat)]
    return [flat[cuts[i] : cuts[i + 1]] for i in range(len(at))]
