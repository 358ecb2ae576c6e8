"""Per-register facts the analysis needs, as numpy tables over the registry.

A log of many boards has many registers (a million heads in the worst
logs we were sent), so nothing here loops over registers in Python: the
facts come from :meth:`DiagRegistry.arrays` and the interners' values,
which grow only at the end, and are extended as new registers appear.
"""

from __future__ import annotations

import numpy as np

from console.analysis.counting.wheels import WHEEL_SENSOR_ADDRESS
from console.analysis.device_table import DeviceNames, DeviceTable, Runs
from console.analysis.head_table import HeadTable
from console.analysis.inventory import IDENTITY_LABELS, IdentityValue
from parsers.diag.fields import DATA_KINDS
from parsers.diag.registry import DiagRegistry
from parsers.dictionary import DigestIndex, Growable

_NONE = np.iinfo(np.int64).max


def _text_flags(values: list[str], wanted: frozenset[str]) -> np.ndarray:
    """Per interned string: is it one of ``wanted`` (once per distinct label, not per register)."""
    return np.fromiter((v in wanted for v in values), bool, len(values))


class RegisterTables:
    """Per register id: its counting-head key, channel, and whether it is a wheel sensor or identity register.

    Head keys number the (device id, counting head) pairs in the order their
    first register appeared, as the batch analysis always has.  Columns grow
    in place (:class:`~parsers.dictionary.Growable`), in the narrowest type
    that holds them; the lookups (:meth:`head_of`, :meth:`channel_of`) give
    int64, as the analysis has always computed with.
    """

    def __init__(self, registry: DiagRegistry) -> None:
        self.registry = registry
        self._head = Growable(np.int32)
        self._channel = Growable(np.int8)
        self._is_wheel = Growable(np.bool_)
        self._is_identity = Growable(np.bool_)
        self._head_device = Growable(np.int32)
        self._head_name_code = Growable(np.int32)
        self._head_keys = DigestIndex()  # (device id << 32 | name code) → head key

    @property
    def head(self) -> np.ndarray:
        return self._head.view()

    @property
    def channel(self) -> np.ndarray:
        return self._channel.view()

    @property
    def is_wheel(self) -> np.ndarray:
        return self._is_wheel.view()

    @property
    def is_identity(self) -> np.ndarray:
        return self._is_identity.view()

    @property
    def head_device(self) -> np.ndarray:
        return self._head_device.view()

    @property
    def head_name_code(self) -> np.ndarray:
        return self._head_name_code.view()

    def head_of(self, register_id: np.ndarray) -> np.ndarray:
        """Head keys (int64) of registers."""
        return self._head.view()[register_id].astype(np.int64)

    def channel_of(self, register_id: np.ndarray) -> np.ndarray:
        """Channels (int64) of registers."""
        return self._channel.view()[register_id].astype(np.int64)

    def update(self) -> RegisterTables:
        """Extend the tables to registers added since the last call."""
        arr = self.registry.arrays()
        n, done = len(arr["device_id"]), self._head.n
        if n == done:
            return self
        key = (arr["device_id"][done:].astype(np.uint64) << np.uint64(32)) | arr["counting_head"][done:].astype(
            np.uint64
        )
        # Keys already numbered, then new keys in order of first appearance.
        zero = np.zeros(len(key), np.uint64)
        head = self._head_keys.get(key, zero)
        new = head < 0
        if new.any():
            new_keys, first, inverse = np.unique(key[new], return_index=True, return_inverse=True)
            rank = np.empty(len(new_keys), np.int32)
            rank[np.argsort(first, kind="stable")] = np.arange(len(new_keys), dtype=np.int32)
            base = self._head_device.n
            head[new] = base + rank[inverse.reshape(-1)]
            self._head_keys.add(new_keys, zero[: len(new_keys)], base + rank)
            by_rank = new_keys[np.argsort(rank)]
            self._head_device.extend((by_rank >> np.uint64(32)).astype(np.int32))
            self._head_name_code.extend((by_rank & np.uint64(0xFFFFFFFF)).astype(np.int32))
        canon = arr["label_canonical"][done:]
        label = arr["label"][done:]
        canonicals, labels = self.registry.canonicals.values, self.registry.labels.values
        wheel_code = _text_flags(canonicals, frozenset({"wheel_sensor"}))
        ident_code = _text_flags(canonicals, frozenset(IDENTITY_LABELS))
        blank_label = _text_flags(labels, frozenset({""}))
        self._head.extend(head)
        self._channel.extend(arr["channel"][done:])
        self._is_wheel.extend(
            wheel_code[canon] | (blank_label[label] & (arr["address"][done:] == WHEEL_SENSOR_ADDRESS))
        )
        self._is_identity.extend(ident_code[canon])
        return self

    @property
    def heads(self) -> HeadTable:
        """(device id, counting head name) per head key, as columns (nothing copied)."""
        return HeadTable(self.head_device, self.head_name_code, self.registry.heads)


def _unique_in_order(group: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (group, value) pairs, per group in order of first appearance (int64)."""
    if not len(group):
        return group.astype(np.int64), value.astype(np.int64)
    g64, v64 = group.astype(np.int64), value.astype(np.int64)
    if g64.min() >= 0 and v64.min() >= 0 and g64.max() < 2**31 and v64.max() < 2**32:
        # One int64 key per pair (ids, channels and head keys are small and not negative): one sort,
        # stable, so each pair's run starts at its first appearance.
        key = (g64 << 32) | v64
        del g64, v64
        _, first = np.unique(key, return_index=True)
        del key
    else:
        order = np.lexsort((v64, g64))
        g, v = g64[order], v64[order]
        first = order[np.flatnonzero(np.r_[True, (g[1:] != g[:-1]) | (v[1:] != v[:-1])])]
        del g, v, order
    first = np.sort(first)
    by_group = first[np.lexsort((first, group[first]))]
    return group[by_group].astype(np.int64), value[by_group].astype(np.int64)


def inventory(
    tables: RegisterTables,
    head_first_ns: np.ndarray,
    head_last_ns: np.ndarray,
    identity: dict[int, tuple[int, int, int, int]],
) -> DeviceTable:
    """One entry per device with records, grouped by device with numpy (not per register).

    ``head_first_ns``/``head_last_ns`` are per head key (int64 max/min: none);
    ``identity`` maps identity register ids to their latest (time, value, kind, data code).
    """
    reg = tables.registry
    arr = reg.arrays()
    counts = reg.record_counts[: reg.n_registers]
    if len(counts) < reg.n_registers:  # registers of no record yet
        counts = np.r_[counts, np.zeros(reg.n_registers - len(counts), np.int64)]
    rid = np.flatnonzero(counts)
    if not len(rid):
        return DeviceTable.empty()
    dev = arr["device_id"][rid]
    devices, first_rid, dev_index = np.unique(dev, return_index=True, return_inverse=True)
    devices = devices.astype(np.int64)
    records = np.zeros(len(devices), np.int64)
    np.add.at(records, dev_index.reshape(-1), counts[rid])
    del dev_index
    d_diag, v_diag = _unique_in_order(dev, arr["diag_id"][rid])
    d_chan, v_chan = _unique_in_order(dev, arr["channel"][rid])
    d_head, v_head = _unique_in_order(dev, tables.head_of(rid))
    # Each device's span: over its heads' first and last record times.
    n_heads = len(tables.head_device)
    hf, hl = head_first_ns[:n_heads], head_last_ns[:n_heads]
    if len(hf) < n_heads:  # heads without records yet
        hf = np.r_[hf, np.full(n_heads - len(hf), _NONE, np.int64)]
        hl = np.r_[hl, np.full(n_heads - len(hl), -_NONE, np.int64)]
    ident: dict[int, list[IdentityValue]] = {}
    # Most recently read first: where a device's heads give one register different values (two serial
    # numbers), the latest reading is the device's, as the archive's report takes it (ties: the register
    # seen first).  A few dozen identity registers.
    for r, (_, value, kind, data_code) in sorted(identity.items(), key=lambda kv: (-kv[1][0], kv[0])):
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
    r0 = rid[first_rid]
    return DeviceTable(
        device_id=devices,
        codes=np.stack([arr["device"][r0], arr["type"][r0], arr["gs"][r0]]),
        records=records,
        span_ns=np.stack([first, last]),
        # Diag ids and channels ascending per device; heads in order of first appearance.
        diag_ids=Runs(v_diag[np.lexsort((v_diag, d_diag))], np.r_[at_diag, len(v_diag)]),
        channels=Runs(v_chan[np.lexsort((v_chan, d_chan))], np.r_[at_chan, len(v_chan)]),
        head_name_codes=Runs(tables.head_name_code[v_head], np.r_[at_head, len(v_head)]),
        identity=ident,
        names=DeviceNames(reg.devices, reg.types, reg.gs, reg.heads),
    )
