"""The dimension tables of one diagnostic read: registers, interned strings, per-span caches.

Held flat, whatever the number of registers: a log where every record names
its own counting head has as many registers as lines, so a register is a
row of numpy columns (ids, channel, address, and codes into string
dictionaries), not a Python object, and the register span that keys it is a
128-bit digest in a :class:`~parsers.dictionary.DigestIndex`, not a bytes
object in a ``dict`` (``benchmarks/bench_many_devices.py``).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import overload

import numpy as np

from parsers.diag.fields import (
    DATA_KINDS,
    FieldError,
    RegisterKey,
    decode_data,
    decode_date,
    parse_register_span,
    split_fields,
)
from parsers.dictionary import FRONT_CACHE_MAX, DigestIndex, Growable, StringDictionary, digests

_ERROR_CACHE_MAX = 20_000
_VALUE_CACHE_MAX = 200_000
_NO_ROW = (0, 0, 0, 0)  # an invalid value span's columns

# Per-register columns and their types; the string ones are codes into the registry's dictionaries.
_COLUMNS: dict[str, type] = {
    "diag_id": np.int32,
    "device_id": np.int32,
    "device": np.int32,
    "type": np.int32,
    "gs": np.int32,
    "counting_head": np.int32,
    "channel": np.int8,
    "address": np.int32,
    "label": np.int32,
    "label_canonical": np.int32,  # code into ``canonicals``: the canonical name, else the label
    "label_known": np.bool_,  # the label maps to a known register (label_canonical is not None)
    "label_encoding": np.int32,
}
_BAD_SHAPE = "expected 12 tab-separated Key:Value fields"


class RegisterList(Sequence[RegisterKey]):
    """The registers as :class:`RegisterKey` objects, each built when asked for (none is stored)."""

    def __init__(self, registry: DiagRegistry) -> None:
        self._registry = registry

    def __len__(self) -> int:
        return self._registry.n_registers

    @overload
    def __getitem__(self, index: int) -> RegisterKey: ...
    @overload
    def __getitem__(self, index: slice) -> list[RegisterKey]: ...
    def __getitem__(self, index: int | slice) -> RegisterKey | list[RegisterKey]:
        n = len(self)
        if isinstance(index, slice):
            return [self._registry.register(i) for i in range(*index.indices(n))]
        if not -n <= index < n:
            raise IndexError("register id out of range")
        return self._registry.register(index % n)


class DiagRegistry:
    """Dimension tables shared by all chunks of one read.

    Records carry a ``register_id`` into the per-register columns
    (:meth:`arrays`); categorical string columns carry codes into the
    dictionaries (``devices``, ``heads``, …, ``data``).  All only ever grow,
    so codes in an early chunk stay valid for the final table.
    """

    def __init__(self) -> None:
        self.files: list[str] = []
        self.devices = StringDictionary()
        self.types = StringDictionary()
        self.gs = StringDictionary()
        self.heads = StringDictionary()
        self.labels = StringDictionary()
        self.canonicals = StringDictionary()
        self.encodings = StringDictionary()
        self.data = StringDictionary()
        self.record_counts = np.zeros(0, np.int64)
        self._columns = {name: Growable(dtype) for name, dtype in _COLUMNS.items()}
        self._spans = DigestIndex()  # register span → register id
        self._span_front: dict[bytes, int] = {}  # the spans met lately, before the index
        self._register_errors: dict[bytes, FieldError] = {}
        self._values: dict[bytes, tuple[tuple[str, int, int] | FieldError, int | FieldError]] = {}
        self._data: dict[bytes, tuple[str, int, int] | FieldError] = {}
        self._days: dict[bytes, int | FieldError] = {}
        # A valid value span's whole row (data code, value, kind code, day ns): the usual chunk's spans were all
        # met before, and their rows then come in one C-level pass of lookups.
        self._value_rows: dict[bytes, tuple[int, int, int, int]] = {}

    @property
    def n_registers(self) -> int:
        return self._columns["diag_id"].n

    @property
    def registers(self) -> RegisterList:
        """The registers by id, as :class:`RegisterKey` objects built on access (for the few
        callers that want one; the columns are :meth:`arrays`)."""
        return RegisterList(self)

    def register(self, rid: int) -> RegisterKey:
        """Register ``rid`` as a :class:`RegisterKey`."""
        c = {name: col.data[rid] for name, col in self._columns.items()}
        return RegisterKey(
            diag_id=int(c["diag_id"]),
            device_id=int(c["device_id"]),
            device=self.devices.value(int(c["device"])),
            type=self.types.value(int(c["type"])),
            gs=self.gs.value(int(c["gs"])),
            counting_head=self.heads.value(int(c["counting_head"])),
            channel=int(c["channel"]),
            address=int(c["address"]),
            label=self.labels.value(int(c["label"])),
            label_canonical=self.canonicals.value(int(c["label_canonical"])) if c["label_known"] else None,
            label_encoding=self.encodings.value(int(c["label_encoding"])),
        )

    def count_records(self, register_id: np.ndarray) -> None:
        """Add parsed records to the per-register totals (kept for every register, perhaps with room beyond)."""
        if len(self.record_counts) < self.n_registers:
            # Room for half as many again: a log adding registers in every chunk copies the totals rarely.
            grown = np.zeros(max(self.n_registers, len(self.record_counts) * 3 // 2), np.int64)
            grown[: len(self.record_counts)] = self.record_counts
            self.record_counts = grown
        if not len(register_id):
            return
        # Counted over the chunk's span of ids only: a chunk of new registers is no pass over all of them.
        lo, hi = int(register_id.min()), int(register_id.max())
        if hi - lo <= 4 * len(register_id) + 4096:
            self.record_counts[lo : hi + 1] += np.bincount(register_id - lo, minlength=hi - lo + 1)
        else:
            np.add.at(self.record_counts, register_id, 1)

    def unknown_labels(self) -> dict[str, int]:
        """Records per label that maps to no known register (kept verbatim), labels in register order."""
        n = min(self.n_registers, len(self.record_counts))
        a = self.arrays()
        label = a["label"][:n]
        blank = np.fromiter((not v for v in self.labels.values), bool, len(self.labels))
        pick = np.flatnonzero(~a["label_known"][:n] & ~blank[label])
        if not len(pick):
            return {}
        codes, first = np.unique(label[pick], return_index=True)
        totals = np.zeros(len(self.labels), np.int64)
        np.add.at(totals, label[pick], self.record_counts[pick])
        order = codes[np.argsort(first, kind="stable")]
        return {self.labels.value(c): int(totals[c]) for c in order.tolist() if totals[c]}

    def canonical_in(self, names: Collection[str]) -> np.ndarray:
        """Per register: is its canonical label one of ``names`` (once per distinct name, not per register)."""
        wanted = np.fromiter((v in names for v in self.canonicals.values), bool, len(self.canonicals))
        a = self.arrays()
        return wanted[a["label_canonical"]] & a["label_known"]

    def register_ids(self, spans: Sequence[bytes]) -> tuple[np.ndarray, dict[int, FieldError]]:
        """Register ids of distinct register spans (-1 where a span is invalid) and the errors by position.

        New spans are parsed and become registers, numbered in the order given.
        """
        front = self._span_front
        # The usual chunk names only registers met before: one C-level pass of lookups, no loop here.
        known = list(map(front.get, spans))
        if None not in known:
            return np.array(known, np.int32), {}
        out = np.array([-1 if k is None else k for k in known], np.int32)
        errors: dict[int, FieldError] = {}
        todo: list[int] = []
        for i, (span, k) in enumerate(zip(spans, known, strict=True)):
            if k is not None:
                continue
            err = self._register_errors.get(span)
            if err is not None:
                errors[i] = err
            else:
                todo.append(i)
        if not todo:
            return out, errors
        keys = [spans[i] for i in todo]
        hi, lo = digests(keys)
        found_ids = self._spans.get(hi, lo)
        new_at: list[int] = []
        new_keys: list[RegisterKey] = []
        for k in np.flatnonzero(found_ids < 0).tolist():
            try:
                new_keys.append(parse_register_span(keys[k]))
                new_at.append(k)
            except FieldError as exc:
                if len(self._register_errors) < _ERROR_CACHE_MAX:
                    self._register_errors[keys[k]] = exc
                errors[todo[k]] = exc
            except ValueError:  # wrong number of parts: only for malformed spans
                errors[todo[k]] = FieldError("fields", _BAD_SHAPE)
        if new_keys:
            rids = self.add_registers(new_keys)
            found_ids[new_at] = rids
            self._spans.add(hi[new_at], lo[new_at], rids)
        ok = np.flatnonzero(found_ids >= 0)
        out[np.asarray(todo, np.int64)[ok]] = found_ids[ok]
        if len(front) + len(ok) > FRONT_CACHE_MAX:
            front.clear()  # bounded: a cache in front of the index
        front.update(zip([keys[k] for k in ok.tolist()], found_ids[ok].tolist(), strict=True))
        return out, errors

    def register_id(self, span: bytes) -> int | FieldError:
        """The register id of one register span, or why it is invalid."""
        ids, errors = self.register_ids([span])
        return errors[0] if 0 in errors else int(ids[0])

    def add_registers(self, keys: Sequence[RegisterKey]) -> np.ndarray:
        """Append registers and intern their strings; their ids (int32)."""
        base, m = self.n_registers, len(keys)
        col = self._columns
        for name in ("diag_id", "device_id", "channel", "address"):
            col[name].extend(np.fromiter((getattr(k, name) for k in keys), _COLUMNS[name], m))
        col["device"].extend(self.devices.codes([k.device for k in keys]))
        col["type"].extend(self.types.codes([k.type for k in keys]))
        col["gs"].extend(self.gs.codes([k.gs for k in keys]))
        col["counting_head"].extend(self.heads.codes([k.counting_head for k in keys]))
        col["label"].extend(self.labels.codes([k.label for k in keys]))
        col["label_canonical"].extend(self.canonicals.codes([k.label_canonical or k.label for k in keys]))
        col["label_known"].extend(np.fromiter((k.label_canonical is not None for k in keys), bool, m))
        col["label_encoding"].extend(self.encodings.codes([k.label_encoding for k in keys]))
        return np.arange(base, base + m, dtype=np.int32)

    def add_register(self, key: RegisterKey) -> int:
        """Append a register and intern its strings; its id.  (Also used by readers
        that rebuild a registry from stored records, such as the archive.)"""
        return int(self.add_registers([key])[0])

    def values(self, spans: Sequence[bytes]) -> tuple[np.ndarray, dict[int, FieldError]]:
        """(data code, value, kind code, day ns) of value spans ``Data:…\tDate:…`` as four int64 rows,
        and the errors by position (their columns hold 0)."""
        found: list[tuple[int, int, int, int] | None] = list(map(self._value_rows.get, spans))
        # Only spans not met before are decoded here (a chunk brings a few new values among hundreds).
        miss = [i for i, row in enumerate(found) if row is None]
        errors: dict[int, FieldError] = {}
        if miss:
            if len(self._value_rows) + len(miss) > _VALUE_CACHE_MAX:
                self._value_rows.clear()  # bounded: a cache, not a store
            texts: list[str] = []
            text_at: list[int] = []
            for i in miss:
                data, day = self._decoded(spans[i])
                found[i] = _NO_ROW
                if isinstance(data, FieldError):
                    errors[i] = data
                    continue
                # Every data text read is interned (also beside a bad date), in the order read.
                texts.append(data[0])
                text_at.append(i)
                if isinstance(day, FieldError):
                    errors[i] = day
                else:
                    found[i] = (0, data[1], data[2], day)
            codes = self.data.codes(texts).tolist() if texts else []
            for i, code in zip(text_at, codes, strict=True):
                if i not in errors:
                    row = found[i]
                    assert row is not None
                    found[i] = self._value_rows[spans[i]] = (code, row[1], row[2], row[3])
        return np.array(found, np.int64).reshape(len(spans), 4).T, errors

    def value(self, span: bytes) -> tuple[int, int, int, int] | FieldError:
        """(data code, value, kind code, day ns) for one value span, or why it is invalid."""
        cols, errors = self.values([span])
        if 0 in errors:
            return errors[0]
        code, value, kind, day = cols[:, 0].tolist()
        return code, value, kind, day

    def _decoded(self, span: bytes) -> tuple[tuple[str, int, int] | FieldError, int | FieldError]:
        """(data text, value, kind code) and day ns of a value span, each or why it is invalid.

        The data and date halves have caches of their own: a long log meets
        every (value, day) pair anew, but few values and few days.
        """
        found = self._values.get(span)
        if found is not None:
            return found
        parts = span.split(b"\t")
        result: tuple[tuple[str, int, int] | FieldError, int | FieldError]
        if len(parts) != 2:
            result = (FieldError("fields", _BAD_SHAPE), 0)
        else:
            data = self._data.get(parts[0])
            if data is None:
                data = self._data[parts[0]] = self._parse_data(parts[0])
            day = self._days.get(parts[1])
            if day is None:
                day = self._days[parts[1]] = self._parse_day(parts[1])
            result = (data, day)
        if len(self._values) >= _VALUE_CACHE_MAX:
            self._values.clear()  # bounded: a cache, not a store
            self._data.clear()
            self._days.clear()
        self._values[span] = result
        return result

    @staticmethod
    def _parse_data(field_bytes: bytes) -> tuple[str, int, int] | FieldError:
        try:
            (raw,) = split_fields(field_bytes, ("Data",), 10)
            text, value, kind = decode_data(raw)
        except FieldError as exc:
            return exc
        return text, value, DATA_KINDS.index(kind)

    @staticmethod
    def _parse_day(field_bytes: bytes) -> int | FieldError:
        try:
            (raw,) = split_fields(field_bytes, ("Date",), 11)
            return decode_date(raw)
        except FieldError as exc:
            return exc

    def arrays(self) -> dict[str, np.ndarray]:
        """Per-register columns, indexed by register_id: views, valid as long as held (appends never
        change a register already there)."""
        return {name: col.view() for name, col in self._columns.items()}
