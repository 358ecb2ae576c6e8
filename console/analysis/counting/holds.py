"""Lone pulses, the holds they start and the onsets still waiting, for
:class:`~console.analysis.counting.bank.CounterBank`: all heads at once.

Seed 002's soft timing, as :class:`~console.analysis.counting.wheels.HeadCounter`
applies it: a damping of one system alone, with another onset at the head
within ``isolation_s`` before it, is a possibly missed axle
(SINGLE_CHANNEL); else it holds the section (INTERFERENCE) until either
the head's next onset (SINGLE_CHANNEL then: activity after an isolated
pulse) or ``isolation_s`` after the pulse, whichever a record of the head
reaches first (ACCIDENTAL).  Each lookup is one search in the block's
records for all pulses.

What is carried from one block to the next, point mode's onsets waiting
for a partner and the holds, is kept as flat tables with a row each
(:class:`Rows`), and time passing (:func:`pass_time`) settles them with
array operations too.

Also the event collector the bank fills: events with the place HeadCounter
makes them (``gen``: the record whose feed makes it; ``sub``: the step
within that feed; ``tie``: the order within the step), sorted by it once.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator, Sequence
from typing import Protocol

import numpy as np

from console.analysis.events.block import COLUMN_DTYPES, COLUMNS, KIND_CODE, Detail, EventBlock, StringPool
from console.analysis.events.detection import EventKind

NONE = np.iinfo(np.int64).min  # no time (HeadCounter's None)
_SINGLE_KIND, _INTERFERENCE_KIND, _ACCIDENTAL_KIND = (
    KIND_CODE[k] for k in (EventKind.SINGLE_CHANNEL, EventKind.INTERFERENCE, EventKind.ACCIDENTAL)
)


class HoldingBank(Protocol):
    """What the holds' rules read and keep of :class:`~console.analysis.counting.bank.CounterBank`."""

    iso: int  # the isolation time, ns
    names: Sequence[str]
    pool: StringPool
    source: int
    texts: tuple[int, int, int]  # the pool's codes of the three hold notes
    tol: np.ndarray  # per head: the pair window, ns
    pending: Rows
    holds: Rows
    hold_ids: int


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

    def block(self, bank: HoldingBank) -> EventBlock:
        if not self.parts["gen"]:
            return EventBlock.empty(bank.names, bank.pool.strings)
        # One column at a time, the pieces let go as they are joined: at the end of a log with a million
        # heads this block holds every head's last events, and whole copies of all columns at once would
        # set the read's peak.
        parts, self.parts = self.parts, {c: [] for c in _COLS}

        def joined(c: str) -> np.ndarray:
            v = parts.pop(c)
            return np.concatenate(v) if len(v) > 1 else v[0]

        order = np.lexsort((joined("tie"), joined("sub"), joined("gen")))
        cols = {c: np.asarray(joined(c)[order], COLUMN_DTYPES[c]) for c in COLUMNS if c != "source"}
        cols["source"] = np.full(len(order), bank.source, np.int32)
        return EventBlock.from_columns(cols, bank.names, bank.pool.strings)


class Rows:
    """A table of per-head rows (``head`` first), sorted by head, then by ``order`` (else as added)."""

    def __init__(self, columns: tuple[str, ...], order: str | None = None) -> None:
        self.columns, self.order = columns, order
        self.cols = {c: np.zeros(0, np.int64) for c in columns}

    def __len__(self) -> int:
        return len(self.cols["head"])

    def heads(self) -> np.ndarray:
        return self.cols["head"]

    def take(self, mask: np.ndarray) -> dict[str, np.ndarray]:
        """Remove the rows of ``mask`` and return them (in the table's order)."""
        out = {c: v[mask] for c, v in self.cols.items()}
        self.cols = {c: v[~mask] for c, v in self.cols.items()}
        return out

    def between(self, lo: int, hi: int) -> Rows:
        """A table of the rows of heads ``lo`` … ``hi - 1`` (views of this one's columns)."""
        heads = self.cols["head"]
        a, b = np.searchsorted(heads, (lo, hi))
        part = Rows(self.columns, self.order)
        part.cols = {c: v[a:b] for c, v in self.cols.items()}
        return part

    @classmethod
    def joined(cls, parts: Sequence[Rows]) -> Rows:
        """Tables of ascending, disjoint head ranges as one."""
        out = cls(parts[0].columns, parts[0].order)
        out.cols = {c: np.concatenate([p.cols[c] for p in parts]) for c in out.columns}
        return out

    def add(self, rows: dict[str, np.ndarray]) -> None:
        if not len(rows["head"]):
            return
        cols = {c: np.r_[self.cols[c], np.asarray(rows[c], np.int64)] for c in self.columns}
        keys = (cols[self.order], cols["head"]) if self.order else (cols["head"],)
        order = np.lexsort(keys)
        self.cols = {c: v[order] for c, v in cols.items()}


def first_record(h: np.ndarray, t: np.ndarray, qh: np.ndarray, qt: np.ndarray, after: bool) -> np.ndarray:
    """Per query (head, time): the position of that head's first record at (``after``: after) that
    time, in records sorted by (head, time); the head's end when none.  One sort of the queried
    heads' records for all queries."""
    if not len(qh):
        return np.zeros(0, np.int64)
    mine = np.flatnonzero(np.isin(h, qh))
    n = len(mine)
    is_query = np.r_[np.zeros(n, bool), np.ones(len(qh), bool)]
    # At equal times a query sorts after the records when they are not after it, else before them.
    order = np.lexsort((is_query if after else ~is_query, np.r_[t[mine], qt], np.r_[h[mine], qh]))
    record = ~is_query[order]
    records_before = np.cumsum(record) - record
    pos = np.empty(len(qh), np.int64)
    pos[order[~record] - n] = records_before[~record]
    found = pos < n
    found[found] = h[mine[pos[found]]] == qh[found]
    head_end = np.searchsorted(h, qh, side="right")  # h is sorted by head
    return np.where(found, mine[np.minimum(pos, max(n - 1, 0))], head_end)


def lone_events(
    bank: HoldingBank,
    out: Collector,
    gen: np.ndarray,
    sub: np.ndarray,
    tie: np.ndarray,
    key: np.ndarray,
    t_on: np.ndarray,
    ch: np.ndarray,
    now: np.ndarray,
    before: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """HeadCounter._lone for many pulses: their events; (which start a hold, the holds' ids)."""
    single = (before != NONE) & (t_on - np.where(before == NONE, 0, before) <= bank.iso)
    s, i = np.flatnonzero(single), np.flatnonzero(~single)
    out.add(gen[s], sub[s], tie[s], now[s], _SINGLE_KIND, key[s], 0, ch[s], Detail.TEXT, bank.texts[0])
    out.add(gen[i], sub[i], tie[i], now[i], _INTERFERENCE_KIND, key[i], 0, ch[i], Detail.TEXT, bank.texts[1])
    hid = bank.hold_ids + np.arange(len(i), dtype=np.int64)
    bank.hold_ids += len(i)
    return i, hid


def settle(
    bank: HoldingBank,
    out: Collector,
    idx: np.ndarray,
    h: np.ndarray,
    t: np.ndarray,
    onsets: np.ndarray,
    starts: np.ndarray,
    lones: dict[str, np.ndarray],
) -> None:
    """The lone pulses of one block (one mode's records, ``lones``: a column each) and the holds
    carried in for its heads: their events, and the holds left for the next block."""
    ends = np.r_[starts[1:], len(h)]
    heads = h[starts]
    old = bank.holds.take(np.isin(bank.holds.heads(), heads))  # carried in
    rec, sub = lones["record"], lones["sub"]
    if not len(rec) and not len(old["head"]):
        return
    key = h[rec]
    i, hid = lone_events(
        bank, out, idx[rec], sub, lones["tie"], key, lones["t_on"], lones["channel"], lones["now"], lones["before"]
    )
    # Holds to settle: those carried in (from their head's first record), then the new ones.  A hold
    # begun at a release waits for the next record; one begun while time passed (an onset expired)
    # is checked in that same step, and that record's onset ends it.
    hk = np.r_[old["head"], key[i]]
    ht = np.r_[old["t_on"], lones["t_on"][i]]
    hc = np.r_[old["channel"], lones["channel"][i]]
    hid = np.r_[old["hold"], hid]
    group = np.asarray(np.searchsorted(heads, hk), np.int64)
    start = np.r_[starts[group[: len(old["head"])]], rec[i] + (sub[i] == OWN)]
    end = ends[group]
    due = ht + bank.iso
    first = np.maximum(start, first_record(h, t, hk, due, after=False))
    next_onset = np.r_[onsets, np.iinfo(np.int64).max][np.searchsorted(onsets, start)]  # none: past the end
    j = np.minimum(next_onset, end)
    acc = (first < end) & (first <= j)
    act = ~acc & (j < end)
    a, b = np.flatnonzero(acc), np.flatnonzero(act)
    out.add(idx[first[a]], ACCIDENTAL, hid[a], due[a], _ACCIDENTAL_KIND, hk[a], 0, hc[a], Detail.TEXT, bank.texts[2])
    out.add(idx[j[b]], ACTIVITY, hid[b], t[j[b]], _SINGLE_KIND, hk[b], 0, hc[b], Detail.ACTIVITY, ht[b])
    stay = ~acc & ~act
    bank.holds.add({"head": hk[stay], "t_on": ht[stay], "channel": hc[stay], "hold": hid[stay]})


def pass_time(bank: HoldingBank, until: Callable[[np.ndarray], np.ndarray], strict: bool) -> EventBlock:
    """HeadCounter.advance at every head with something waiting or held, to ``until(heads)`` each
    (NONE: not this head):
    waiting onsets more than a window old expire, holds due by then are confirmed accidental.
    ``strict``: holds due at that very time stay (they are made with the records then)."""
    out = Collector()
    waiting = bank.pending
    if len(waiting):
        p = waiting.cols
        expires = p["t_on"] + bank.tol[p["head"]]
        late = expires < until(p["head"])  # a prefix of each head's queue
        gone = np.flatnonzero(late)
        if len(gone):
            expires = expires[gone]
            rows = waiting.take(late)
            key = rows["head"]
            sub = np.full(len(key), EXPIRED, np.int64)
            i, hid = lone_events(bank, out, key, sub, gone, key, rows["t_on"], rows["channel"], expires, rows["before"])
            bank.holds.add({"head": key[i], "t_on": rows["t_on"][i], "channel": rows["channel"][i], "hold": hid})
    if len(bank.holds):
        q = bank.holds.cols
        due = q["t_on"] + bank.iso
        last = until(q["head"])
        if strict:
            last = np.where(last == NONE, NONE, last - 1)
        ripe = due <= last
        if ripe.any():
            rows = bank.holds.take(ripe)
            key = rows["head"]
            due = rows["t_on"] + bank.iso
            text = bank.texts[2]
            out.add(key, ACCIDENTAL, rows["hold"], due, _ACCIDENTAL_KIND, key, 0, rows["channel"], Detail.TEXT, text)
    return out.block(bank)


def pass_time_slices(
    bank: HoldingBank, until: Callable[[np.ndarray], np.ndarray], strict: bool, size: int
) -> Iterator[EventBlock]:
    """:func:`pass_time` a slice of whole heads at a time (about ``size`` rows waiting or held each):
    the same events, in the same order over the blocks, each block a slice's.

    A head's events depend on its own rows only, and the hold ids are handed out in the same order, so
    only the temporaries shrink: at the end of a log of a million heads, half a million onsets may
    expire at once.  Iterate to the end: the bank's tables are whole again only then."""
    pending, holds = bank.pending, bank.holds
    if len(pending) + len(holds) <= size:
        yield pass_time(bank, until, strict)
        return
    heads = np.unique(np.r_[pending.heads(), holds.heads()])
    # Rows of the heads up to each; a slice ends with the head that reaches the next multiple of size.
    rows_to = np.searchsorted(pending.heads(), heads, side="right") + np.searchsorted(holds.heads(), heads, "right")
    cut = np.searchsorted(rows_to, np.arange(size, rows_to[-1], size), side="left") + 1
    bounds = np.r_[heads[0], heads[np.minimum(cut, len(heads) - 1)], heads[-1] + 1]
    left: tuple[list[Rows], list[Rows]] = ([], [])
    for lo, hi in itertools.pairwise(bounds):
        if lo >= hi:
            continue
        bank.pending, bank.holds = pending.between(int(lo), int(hi)), holds.between(int(lo), int(hi))
        yield pass_time(bank, until, strict)
        left[0].append(bank.pending)
        left[1].append(bank.holds)
    bank.pending, bank.holds = Rows.joined(left[0]), Rows.joined(left[1])
