"""Per-register facts the analysis needs, as numpy tables over the registry.

A log of many boards has many registers (a million heads in the worst
logs we were sent), so nothing here loops over registers in Python: the
facts come from :meth:`DiagRegistry.arrays` and the interners' values,
which grow only at the end, and are extended as new registers appear.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

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
    def heads(self) -> list[tuple[int, str]]:
        names = self.registry.heads.values
        return [(int(d), names[int(c)]) for d, c in zip(self.head_device, self.head_name_code, strict=True)]


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
                reg.canonicals.values[arr["label_canonical"][r]],
                int(arr["address"][r]),
                value,
                DATA_KINDS[kind],
                reg.data.values[data_code],
            )
        )
    names = reg.heads.values
    # The pairs are sorted by device: each device's values are one slice.
    at_diag = [*np.searchsorted(d_diag, devices).tolist(), len(d_diag)]
    at_chan = [*np.searchsorted(d_chan, devices).tolist(), len(d_chan)]
    at_head = [*np.searchsorted(d_head, devices).tolist(), len(d_head)]
    out = []
    for i, d in enumerate(devices.tolist()):  # per device
        r0 = int(rid[first_rid[i]])
        heads = v_head[at_head[i] : at_head[i + 1]]
        first = hf[heads][hf[heads] != _NONE]
        last = hl[heads][hl[heads] != -_NONE]
        inv = DeviceInventory(
            device_id=d,
            device=reg.devices.values[arr["device"][r0]],
            type=reg.types.values[arr["type"][r0]],
            gs=reg.gs.values[arr["gs"][r0]],
            diag_ids=sorted(v_diag[at_diag[i] : at_diag[i + 1]].tolist()),
            counting_heads=[names[int(tables.head_name_code[h])] for h in heads.tolist()],
            channels=sorted(v_chan[at_chan[i] : at_chan[i + 1]].tolist()),
            records=int(records[i]),
            first_ns=int(first.min()) if len(first) else 0,
            last_ns=int(last.max()) if len(last) else 0,
        )
        apply_identity(inv, ident.get(d, []))
        out.append(inv)
    return out
