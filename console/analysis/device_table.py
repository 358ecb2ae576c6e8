"""The device inventory of a diagnostic read, held as columns; a device becomes an object only when read.

A log may name a million counting heads, or a device per record: an
inventory of :class:`DeviceInventory` objects, each with its list of head
names, would hold a Python object per head for as long as the analysis
lives.  :class:`DeviceTable` keeps the per-device facts as numpy columns
(names as codes into the registry's dictionaries, each device's diag ids,
channels and heads as a run of one flat array) and builds the objects as
they are read, a block at a time when iterated.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import overload

import numpy as np

from console.analysis.inventory import DeviceInventory, IdentityValue, apply_identity
from parsers.dictionary import StringDictionary

# Devices built per block when iterating: bounds the objects alive at once.
_BLOCK = 4096


@dataclass(frozen=True)
class Runs:
    """One run of values per device: device i's values are ``values[cuts[i]:cuts[i + 1]]``."""

    values: np.ndarray
    cuts: np.ndarray  # len(devices) + 1


@dataclass(frozen=True)
class DeviceNames:
    """The registry's dictionaries the codes point into."""

    devices: StringDictionary
    types: StringDictionary
    gs: StringDictionary
    heads: StringDictionary


class DeviceTable(Sequence[DeviceInventory]):
    """One :class:`DeviceInventory` per device with records, by device id, built on access."""

    def __init__(
        self,
        device_id: np.ndarray,
        codes: np.ndarray,  # (3, n): device, type and gs name codes
        records: np.ndarray,
        span_ns: np.ndarray,  # (2, n): first and last record time
        diag_ids: Runs,
        channels: Runs,
        head_name_codes: Runs,
        identity: dict[int, list[IdentityValue]],
        names: DeviceNames,
    ) -> None:
        self.device_id = device_id
        self._codes = codes
        self.records = records
        self._span_ns = span_ns
        self._diag_ids = diag_ids
        self._channels = channels
        self._heads = head_name_codes
        self._identity = identity
        self._names = names

    @classmethod
    def empty(cls) -> DeviceTable:
        none = Runs(np.zeros(0, np.int64), np.zeros(1, np.int64))
        blank = StringDictionary()
        return cls(
            np.zeros(0, np.int64),
            np.zeros((3, 0), np.int64),
            np.zeros(0, np.int64),
            np.zeros((2, 0), np.int64),
            none,
            none,
            none,
            {},
            DeviceNames(blank, blank, blank, blank),
        )

    def __len__(self) -> int:
        return len(self.device_id)

    @overload
    def __getitem__(self, index: int) -> DeviceInventory: ...
    @overload
    def __getitem__(self, index: slice) -> list[DeviceInventory]: ...
    def __getitem__(self, index: int | slice) -> DeviceInventory | list[DeviceInventory]:
        n = len(self)
        if isinstance(index, slice):
            start, stop, step = index.indices(n)
            if step == 1:
                return self._block(start, max(start, stop))
            return [self._block(i, i + 1)[0] for i in range(start, stop, step)]
        if not -n <= index < n:
            raise IndexError("device index out of range")
        i = index % n
        return self._block(i, i + 1)[0]

    def __iter__(self) -> Iterator[DeviceInventory]:
        for lo in range(0, len(self), _BLOCK):
            yield from self._block(lo, min(lo + _BLOCK, len(self)))

    def _block(self, lo: int, hi: int) -> list[DeviceInventory]:
        """Devices ``lo:hi`` as objects: one list per column, then list slices (no numpy call per device)."""
        if hi <= lo:
            return []
        names = self._names
        device = names.devices.take(self._codes[0, lo:hi])
        type_ = names.types.take(self._codes[1, lo:hi])
        gs = names.gs.take(self._codes[2, lo:hi])
        diag_ids, diag_at = _run_lists(self._diag_ids, lo, hi)
        channels, chan_at = _run_lists(self._channels, lo, hi)
        a, b = int(self._heads.cuts[lo]), int(self._heads.cuts[hi])
        heads = names.heads.take(self._heads.values[a:b])
        head_at = (self._heads.cuts[lo : hi + 1] - a).tolist()
        first, last = self._span_ns[0, lo:hi].tolist(), self._span_ns[1, lo:hi].tolist()
        out = []
        for k, (d, n) in enumerate(zip(self.device_id[lo:hi].tolist(), self.records[lo:hi].tolist(), strict=True)):
            inv = DeviceInventory(
                device_id=d,
                device=device[k],
                type=type_[k],
                gs=gs[k],
                diag_ids=diag_ids[diag_at[k] : diag_at[k + 1]],
                counting_heads=heads[head_at[k] : head_at[k + 1]],
                channels=channels[chan_at[k] : chan_at[k + 1]],
                records=n,
                first_ns=first[k],
                last_ns=last[k],
            )
            values = self._identity.get(d)
            if values:
                apply_identity(inv, values)
            out.append(inv)
        return out


def _run_lists(runs: Runs, lo: int, hi: int) -> tuple[list[int], list[int]]:
    """The values of devices ``lo:hi`` as one list, and each device's start in it (and the end)."""
    a, b = int(runs.cuts[lo]), int(runs.cuts[hi])
    return runs.values[a:b].tolist(), (runs.cuts[lo : hi + 1] - a).tolist()
