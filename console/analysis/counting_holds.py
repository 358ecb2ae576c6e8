"""Lone pulses and the holds they start, for :class:`~console.analysis.counting.CounterBank`.

Seed 002's soft timing, as :class:`~console.analysis.wheels.HeadCounter`
applies it: a damping of one system alone, with another onset at the head
within ``isolation_s`` before it, is a possibly missed axle
(SINGLE_CHANNEL); else it holds the section (INTERFERENCE) until either
the head's next onset (SINGLE_CHANNEL then: activity after an isolated
pulse) or ``isolation_s`` after the pulse, whichever a record of the head
reaches first (ACCIDENTAL).  Both are rare, so this is a loop per lone
pulse; each lookup is a binary search in the head's records.

Also the event collector the bank fills: events with the place HeadCounter
makes them (``gen``: the record whose feed makes it; ``sub``: the step
within that feed; ``tie``: the order within the step), sorted by it once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.event_block import KIND_CODE, Detail, EventBlock
from console.analysis.events import EventKind

if TYPE_CHECKING:
    from console.analysis.counting import CounterBank

NONE = np.iinfo(np.int64).min  # no time (HeadCounter's None)
_SINGLE_KIND, _INTERFERENCE_KIND, _ACCIDENTAL_KIND = (
    KIND_CODE[k] for k in (EventKind.SINGLE_CHANNEL, EventKind.INTERFERENCE, EventKind.ACCIDENTAL)
)
# Within one record, HeadCounter.feed makes its events in this order (an event's ``sub``): waiting
# onsets expired, holds confirmed accidental, holds ended by activity, the record's own, head free.
EXPIRED, ACCIDENTAL, ACTIVITY, OWN, FREE = range(5)

_COLS = ("gen", "sub", "tie", "time_ns", "kind", "head", "direction", "channel", "detail", "aux_ns")


class Collector:
    """Event columns as they are made, each with where HeadCounter makes it."""

    def __init__(self) -> None:
        self.parts: dict[str, list[np.ndarray]] = {c: [] for c in _COLS}

    def add(self, *values: np.ndarray | int) -> None:
        """Columns in the order of ``_COLS``; scalars stand for every row."""
        n = max((len(v) for v in values if isinstance(v, np.ndarray)), default=1)
        if n == 0:
            return
        for c, v in zip(_COLS, values, strict=True):
            self.parts[c].append(v if isinstance(v, np.ndarray) else np.full(n, v, np.int64))

    def block(self, bank: CounterBank) -> EventBlock:
        if not self.parts["gen"]:
            return EventBlock.empty(bank.names, bank.pool.strings)
        cols = {c: np.concatenate(v) if len(v) > 1 else v[0] for c, v in self.parts.items()}
        order = np.lexsort((cols["tie"], cols["sub"], cols["gen"]))
        cols = {c: v[order] for c, v in cols.items()}
        cols["source"] = np.full(len(order), bank.source, np.int32)
        return EventBlock.from_columns(cols, bank.names, bank.pool.strings)


@dataclass(frozen=True, slots=True)
class Lone:
    """A damping of one system alone, settled at a record of the block."""

    record: int  # position (in the mode's records) of the record whose feed settles it
    sub: int  # EXPIRED: that record's advance (point mode); OWN: it is the release
    tie: int
    t_on: int
    channel: int
    now: int  # the event's time
    before: int  # the head's previous onset when the pulse began (NONE: none)


def lone_event(
    bank: CounterBank, out: Collector, gen: int, sub: int, tie: int, key: int, t_on: int, ch: int, now: int, before: int
) -> int | None:
    """HeadCounter._lone: the event of a lone pulse; the new hold's id, or None."""
    if before != NONE and t_on - before <= bank.iso:
        out.add(gen, sub, tie, now, _SINGLE_KIND, key, 0, ch, Detail.TEXT, bank.texts[0])
        return None
    out.add(gen, sub, tie, now, _INTERFERENCE_KIND, key, 0, ch, Detail.TEXT, bank.texts[1])
    hid = bank.hold_ids
    bank.hold_ids += 1
    return hid


def settle(
    bank: CounterBank,
    out: Collector,
    idx: np.ndarray,
    h: np.ndarray,
    t: np.ndarray,
    onsets: np.ndarray,
    starts: np.ndarray,
    lones: list[Lone],
    held: list[int],
) -> None:
    """Lone pulses of one block (one mode's records) and the holds carried in for heads ``held``."""
    ends = np.r_[starts[1:], len(h)]
    heads = h[starts]

    def span(key: int) -> tuple[int, int]:
        g = int(np.searchsorted(heads, key))
        return int(starts[g]), int(ends[g])

    todo: list[tuple[int, int, int, int, int]] = []  # (head, onset, channel, hold id, first record after it)
    for key in held:
        first, _ = span(key)
        todo += [(key, t_on, c, hid, first) for t_on, c, hid in bank.holds.pop(key)]
    for x in sorted(lones, key=lambda x: (x.record, x.sub, x.tie)):  # per lone pulse: rare
        key = int(h[x.record])
        hid = lone_event(bank, out, int(idx[x.record]), x.sub, x.tie, key, x.t_on, x.channel, x.now, x.before)
        if hid is not None:
            # A hold begun at a release waits for the next record; one begun while time passed
            # (an onset expired) is checked in that same step, and that record's onset ends it.
            todo.append((key, x.t_on, x.channel, hid, x.record + (1 if x.sub == OWN else 0)))
    for key, t_on, c, hid, start in todo:  # per hold: rare
        _, end = span(key)
        due = t_on + bank.iso
        i = start + int(np.searchsorted(t[start:end], due, side="left"))
        k = int(np.searchsorted(onsets, start, side="left"))
        j = int(onsets[k]) if k < len(onsets) and onsets[k] < end else end
        if i < end and i <= j:
            out.add(int(idx[i]), ACCIDENTAL, hid, due, _ACCIDENTAL_KIND, key, 0, c, Detail.TEXT, bank.texts[2])
        elif j < end:
            out.add(int(idx[j]), ACTIVITY, hid, int(t[j]), _SINGLE_KIND, key, 0, c, Detail.ACTIVITY, t_on)
        else:
            bank.holds.setdefault(key, []).append((t_on, c, hid))
