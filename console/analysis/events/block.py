"""Detection events as columns: a block of events without an object per event.

The counting path makes about one event per wheel record (an axle, a head
damped, a head free).  Held as :class:`~console.analysis.events.detection.DetectionEvent`
objects they cost more than the rules that make them; an :class:`EventBlock`
keeps them as arrays (time, kind code, head key, direction, channel) and
makes the objects, and their ``detail`` text, only for the events a consumer
renders or steps one by one (:meth:`EventBlock.events`).

Heads are keys into ``names`` (the stream's head list); a negative key
``-1 - i`` names ``pool[i]`` (an operator reset's section).  Sources and
fixed detail texts are pool entries too; the details that carry numbers
(an axle's two onset times, a gap) are formatted from ``aux_ns`` when made.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from console.analysis.events.detection import DetectionEvent, EventKind
from parsers.units import NS

KINDS: tuple[EventKind, ...] = tuple(EventKind)
KIND_CODE: dict[EventKind, int] = {k: i for i, k in enumerate(KINDS)}
NO_CHANNEL = -1  # an event without a channel (None)


class Detail(IntEnum):
    """How an event's ``detail`` text is made from its columns."""

    NONE = 0
    TEXT = 1  # pool[aux_ns]
    AXLE_SYS1_FIRST = 2  # "Sys1 {aux_ns} Sys2 {time_ns}"
    AXLE_SYS2_FIRST = 3  # "Sys1 {time_ns} Sys2 {aux_ns}"
    ACTIVITY = 4  # "activity {(time_ns - aux_ns) / NS:.1f} s after an isolated pulse"
    NO_RECORDS = 5  # "no records for {aux_ns / NS:.0f} s" (aux_ns: the gap)


class StringPool:
    """Append-only strings with their index: the texts an event block's codes point at."""

    def __init__(self) -> None:
        self.strings: list[str] = []
        self._index: dict[str, int] = {}

    def code(self, text: str) -> int:
        i = self._index.get(text)
        if i is None:
            i = self._index[text] = len(self.strings)
            self.strings.append(text)
        return i


_TEXT, _SYS1_FIRST, _SYS2_FIRST, _ACTIVITY = (
    int(Detail.TEXT),
    int(Detail.AXLE_SYS1_FIRST),
    int(Detail.AXLE_SYS2_FIRST),
    int(Detail.ACTIVITY),
)


def _detail(code: int, t: int, aux: int, pool: Sequence[str]) -> str:
    # Plain ints, not the enum: this runs once per event made into an object.
    if code == 0:
        return ""
    if code == _TEXT:
        return pool[aux]
    if code == _SYS1_FIRST:
        return f"Sys1 {aux} Sys2 {t}"
    if code == _SYS2_FIRST:
        return f"Sys1 {t} Sys2 {aux}"
    if code == _ACTIVITY:
        return f"activity {(t - aux) / NS:.1f} s after an isolated pulse"
    return f"no records for {np.int64(aux) / NS:.0f} s"  # as numpy divides the gap


COLUMNS = ("time_ns", "kind", "head", "direction", "channel", "source", "detail", "aux_ns")
COLUMN_DTYPES = {
    "time_ns": np.int64,
    "kind": np.int8,
    "head": np.int64,
    "direction": np.int8,
    "channel": np.int16,
    "source": np.int32,
    "detail": np.int8,
    "aux_ns": np.int64,
}


@dataclass
class EventBlock:
    """Events as columns, in the order given (the producer's order)."""

    time_ns: np.ndarray  # int64
    kind: np.ndarray  # int8, into KINDS
    head: np.ndarray  # int64: >= 0 a key into names, < 0 pool[-1 - key]
    direction: np.ndarray  # int8
    channel: np.ndarray  # int16, NO_CHANNEL: none
    source: np.ndarray  # int32, into pool
    detail: np.ndarray  # int8, a Detail
    aux_ns: np.ndarray  # int64, what the detail is made from
    names: Sequence[str]
    pool: Sequence[str]

    def __len__(self) -> int:
        return len(self.time_ns)

    @classmethod
    def empty(cls, names: Sequence[str], pool: Sequence[str]) -> EventBlock:
        return cls.from_columns({c: np.zeros(0, COLUMN_DTYPES[c]) for c in COLUMNS}, names, pool)

    @classmethod
    def from_columns(cls, cols: dict[str, np.ndarray], names: Sequence[str], pool: Sequence[str]) -> EventBlock:
        c = {name: np.asarray(cols[name], COLUMN_DTYPES[name]) for name in COLUMNS}
        return cls(
            time_ns=c["time_ns"],
            kind=c["kind"],
            head=c["head"],
            direction=c["direction"],
            channel=c["channel"],
            source=c["source"],
            detail=c["detail"],
            aux_ns=c["aux_ns"],
            names=names,
            pool=pool,
        )

    @classmethod
    def from_events(cls, events: Sequence[DetectionEvent], names: Sequence[str], pool: StringPool) -> EventBlock:
        """Events given as objects (operator resets, events of other sources): heads and texts pooled."""
        cols: dict[str, list[int]] = {c: [] for c in COLUMNS}
        for e in events:
            cols["time_ns"].append(e.time_ns)
            cols["kind"].append(KIND_CODE[e.kind])
            cols["head"].append(-1 - pool.code(e.head))
            cols["direction"].append(e.direction)
            cols["channel"].append(NO_CHANNEL if e.channel is None else e.channel)
            cols["source"].append(pool.code(e.source))
            cols["detail"].append(Detail.TEXT if e.detail else Detail.NONE)
            cols["aux_ns"].append(pool.code(e.detail) if e.detail else 0)
        return cls.from_columns({c: np.array(v, COLUMN_DTYPES[c]) for c, v in cols.items()}, names, pool.strings)

    def column(self, name: str) -> np.ndarray:
        value: np.ndarray = getattr(self, name)
        return value

    def take(self, index: np.ndarray) -> EventBlock:
        """The events at ``index`` (positions or a mask), in that order."""
        return EventBlock.from_columns({c: self.column(c)[index] for c in COLUMNS}, self.names, self.pool)

    @staticmethod
    def concat(blocks: Iterable[EventBlock], names: Sequence[str], pool: Sequence[str]) -> EventBlock:
        parts = [b for b in blocks if len(b)]
        if not parts:
            return EventBlock.empty(names, pool)
        if len(parts) == 1:
            return parts[0]
        return EventBlock.from_columns({c: np.concatenate([b.column(c) for b in parts]) for c in COLUMNS}, names, pool)

    def head_name(self, key: int) -> str:
        return self.names[key] if key >= 0 else self.pool[-1 - key]

    def event(self, i: int) -> DetectionEvent:
        """The event at position ``i`` as an object."""
        ch = int(self.channel[i])
        t = int(self.time_ns[i])
        return DetectionEvent(
            t,
            KINDS[self.kind[i]],
            self.head_name(int(self.head[i])),
            int(self.direction[i]),
            None if ch == NO_CHANNEL else ch,
            self.pool[self.source[i]],
            _detail(int(self.detail[i]), t, int(self.aux_ns[i]), self.pool),
        )

    def events(self) -> list[DetectionEvent]:
        """Every event as an object, in order (a loop per event: for consumers that need objects)."""
        names: Sequence[str] | dict[int, str] = self.names
        pool = self.pool
        take = getattr(names, "take", None)
        if take is not None:  # names read from columns: this block's heads looked up once each
            keys = np.unique(self.head[self.head >= 0])
            names = dict(zip(keys.tolist(), take(keys), strict=True))
        out = []
        cols = zip(
            self.time_ns.tolist(),
            self.kind.tolist(),
            self.head.tolist(),
            self.direction.tolist(),
            self.channel.tolist(),
            self.source.tolist(),
            self.detail.tolist(),
            self.aux_ns.tolist(),
            strict=True,
        )
        for t, k, h, d, ch, s, dc, aux in cols:
            out.append(
                DetectionEvent(
                    t,
                    KINDS[k],
                    names[h] if h >= 0 else pool[-1 - h],
                    d,
                    None if ch == NO_CHANNEL else ch,
                    pool[s],
                    _detail(dc, t, aux, pool) if dc else "",
                )
            )
        return out

    def of_kinds(self, kinds: Iterable[EventKind]) -> EventBlock:
        """Only the events of these kinds."""
        codes = np.array([KIND_CODE[k] for k in kinds], np.int8)
        return self.take(np.isin(self.kind, codes))
