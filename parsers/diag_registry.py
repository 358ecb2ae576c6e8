"""The dimension tables of one diagnostic read: registers, interned strings, per-span caches."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from parsers.diag_fields import (
    DATA_KINDS,
    FieldError,
    RegisterKey,
    _split_fields,
    decode_data,
    decode_date,
    parse_register_span,
)

_ERROR_CACHE_MAX = 20_000
_VALUE_CACHE_MAX = 200_000


class _Interner:
    """Strings → dense codes, for categorical columns shared across chunks."""

    def __init__(self) -> None:
        self.values: list[str] = []
        self._codes: dict[str, int] = {}

    def code(self, value: str) -> int:
        found = self._codes.get(value)
        if found is None:
            found = self._codes[value] = len(self.values)
            self.values.append(value)
        return found


@dataclass
class DiagRegistry:
    """Dimension tables shared by all chunks of one read.

    Records carry a ``register_id`` into :attr:`registers`; categorical string
    columns carry codes into the interners.  Both only ever grow, so codes in
    an early chunk stay valid for the final table.
    """

    registers: list[RegisterKey] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    devices: _Interner = field(default_factory=_Interner)
    types: _Interner = field(default_factory=_Interner)
    gs: _Interner = field(default_factory=_Interner)
    heads: _Interner = field(default_factory=_Interner)
    labels: _Interner = field(default_factory=_Interner)
    canonicals: _Interner = field(default_factory=_Interner)
    data: _Interner = field(default_factory=_Interner)
    _register_ids: dict[bytes, int] = field(default_factory=dict)
    _register_errors: dict[bytes, FieldError] = field(default_factory=dict)
    _values: dict[bytes, tuple[int, int, int, int] | FieldError] = field(default_factory=dict)
    _data: dict[bytes, tuple[int, int, int] | FieldError] = field(default_factory=dict)
    _days: dict[bytes, int | FieldError] = field(default_factory=dict)
    _arrays: dict[str, np.ndarray] = field(default_factory=dict)
    _arrays_len: int = -1
    record_counts: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def count_records(self, register_id: np.ndarray) -> None:
        """Add parsed records to the per-register totals."""
        counts = np.bincount(register_id, minlength=len(self.registers))
        if len(self.record_counts) < len(counts):
            grown = np.zeros(len(counts), np.int64)
            grown[: len(self.record_counts)] = self.record_counts
            self.record_counts = grown
        self.record_counts[: len(counts)] += counts

    def unknown_labels(self) -> dict[str, int]:
        """Records per label that maps to no known register (kept verbatim)."""
        out: dict[str, int] = {}
        for rid, r in enumerate(self.registers):
            if r.label and r.label_canonical is None and rid < len(self.record_counts):
                out[r.label] = out.get(r.label, 0) + int(self.record_counts[rid])
        return {k: v for k, v in out.items() if v}

    def register_id(self, span: bytes) -> int | FieldError:
        found = self._register_ids.get(span)
        if found is not None:
            return found
        err = self._register_errors.get(span)
        if err is not None:
            return err
        try:
            key = parse_register_span(span)
        except FieldError as exc:
            if len(self._register_errors) < _ERROR_CACHE_MAX:
                self._register_errors[span] = exc
            return exc
        except ValueError:  # wrong number of parts: only for malformed spans
            return FieldError("fields", "expected 12 tab-separated Key:Value fields")
        rid = self._register_ids[span] = self.add_register(key)
        return rid

    def add_register(self, key: RegisterKey) -> int:
        """Append a register and intern its strings; its id.  (Also used by readers
        that rebuild a registry from stored records, such as the archive.)"""
        rid = len(self.registers)
        self.registers.append(key)
        for interner, value in (
            (self.devices, key.device),
            (self.types, key.type),
            (self.gs, key.gs),
            (self.heads, key.counting_head),
            (self.labels, key.label),
            (self.canonicals, key.label_canonical or key.label),
        ):
            interner.code(value)
        return rid

    def value(self, span: bytes) -> tuple[int, int, int, int] | FieldError:
        """(data code, value, kind code, day ns) for a value span ``Data:…\tDate:…``.

        The data and date halves have caches of their own: a long log meets
        every (value, day) pair anew, but few values and few days.
        """
        found = self._values.get(span)
        if found is not None:
            return found
        parts = span.split(b"\t")
        result: tuple[int, int, int, int] | FieldError
        if len(parts) != 2:
            result = FieldError("fields", "expected 12 tab-separated Key:Value fields")
        else:
            data = self._data.get(parts[0])
            if data is None:
                data = self._data[parts[0]] = self._parse_data(parts[0])
            day = self._days.get(parts[1])
            if day is None:
                day = self._days[parts[1]] = self._parse_day(parts[1])
            if isinstance(data, FieldError):
                result = data
            elif isinstance(day, FieldError):
                result = day
            else:
                result = (*data, day)
        if len(self._values) >= _VALUE_CACHE_MAX:
            self._values.clear()  # bounded: a cache, not a store
            self._data.clear()
            self._days.clear()
        self._values[span] = result
        return result

    def _parse_data(self, field_bytes: bytes) -> tuple[int, int, int] | FieldError:
        try:
            (raw,) = _split_fields(field_bytes, ("Data",), 10)
            text, value, kind = decode_data(raw)
        except FieldError as exc:
            return exc
        return self.data.code(text), value, DATA_KINDS.index(kind)

    @staticmethod
    def _parse_day(field_bytes: bytes) -> int | FieldError:
        try:
            (raw,) = _split_fields(field_bytes, ("Date",), 11)
            return decode_date(raw)
        except FieldError as exc:
            return exc

    def arrays(self) -> dict[str, np.ndarray]:
        """Per-register lookup arrays (indexed by register_id), extended for new registers only."""
        done = max(self._arrays_len, 0)
        if done != len(self.registers) or not self._arrays:  # not self._arrays: none built yet (no register)
            regs = self.registers[done:]
            new: dict[str, np.ndarray] = {
                "diag_id": np.array([r.diag_id for r in regs], dtype=np.int32),
                "device_id": np.array([r.device_id for r in regs], dtype=np.int32),
                "device": np.array([self.devices.code(r.device) for r in regs], dtype=np.int32),
                "type": np.array([self.types.code(r.type) for r in regs], dtype=np.int32),
                "gs": np.array([self.gs.code(r.gs) for r in regs], dtype=np.int32),
                "counting_head": np.array([self.heads.code(r.counting_head) for r in regs], dtype=np.int32),
                "channel": np.array([r.channel for r in regs], dtype=np.int8),
                "address": np.array([r.address for r in regs], dtype=np.int32),
                "label": np.array([self.labels.code(r.label) for r in regs], dtype=np.int32),
                "label_canonical": np.array(
                    [self.canonicals.code(r.label_canonical or r.label) for r in regs], dtype=np.int32
                ),
            }
            # A log of a million heads adds registers in every chunk: never rebuild the old ones.
            self._arrays = {k: np.concatenate([self._arrays[k], v]) for k, v in new.items()} if done else new
            self._arrays_len = len(self.registers)
        return self._arrays
