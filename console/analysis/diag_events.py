"""A diagnostic log's wheel-sensor records → the section engine's event stream.

Per counting head of the layout: two-channel heads use the overlap rule
(:class:`console.analysis.counting.bank.CounterBank`, every head at once: the
events :class:`~console.analysis.counting.wheels.HeadCounter` gives), three-element
heads the majority rule (:func:`console.analysis.counting.majority.majority_events`).
A gap in a head's records longer than ``power_gap_s`` is a power or contact
loss: it only makes sense where the device writes records continuously
(a heartbeat), so it is off unless set.  A head silent at the end of the log
is lost too once the log ran on past its last record by more than the gap
and the order slack: a live console knows it then, without the head coming
back.

The events come in the order of a list built head by head (counting
events in time order, then power events) and sorted by time, stably.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np

from console.analysis.counting.majority import MajoritySettings, majority_events
from console.analysis.counting.wheels import CountingSettings
from console.analysis.events.block import KIND_CODE, NO_CHANNEL, Detail, EventBlock, StringPool
from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.passages.diag_analysis import DiagAnalysis
from console.analysis.passages.stream import ORDER_SLACK_S
from console.layout import Layout
from parsers.units import NS

NONE = np.iinfo(np.int64).min  # no time
_COUNTING, _POWER = 0, 1  # at equal times and heads, counting events first (the list's order)


@dataclass(frozen=True)
class DiagEventSettings:
    counting: CountingSettings = field(default_factory=CountingSettings)
    majority: MajoritySettings = field(default_factory=MajoritySettings)
    power_gap_s: float | None = None  # record gap that means power loss; None: off


def power_gap_columns(
    head: np.ndarray, first_ns: np.ndarray, last_ns: np.ndarray, before_ns: np.ndarray, power_gap_ns: int
) -> dict[str, np.ndarray]:
    """POWER_LOSS / POWER_RESTORED events of activity buckets sorted by head, then first record.

    ``before_ns``: per bucket, the head's last record before the first bucket
    of its head here (NONE: none; later buckets' values are not read).  A gap
    longer than ``power_gap_ns`` between a bucket's last record and the next
    one's first is a loss at ``last + power gap``, restored at the next
    record; per gap the loss, then the restoration.  The loss says what was
    known when it happened: no records for the power gap (a live console
    tells it then, before the head is heard again).  Columns of an
    :class:`EventBlock` without ``source``.
    """
    start = np.r_[True, head[1:] != head[:-1]] if len(head) else np.zeros(0, bool)
    prev_last = np.r_[NONE, last_ns[:-1]] if len(head) else last_ns
    prev_last[start] = before_ns[start]
    known = prev_last != NONE
    gap = first_ns - np.where(known, prev_last, first_ns)
    lost = np.flatnonzero(known & (gap > power_gap_ns))
    n = len(lost)
    return {
        "time_ns": np.c_[prev_last[lost] + power_gap_ns, first_ns[lost]].ravel(),
        "kind": np.tile([KIND_CODE[EventKind.POWER_LOSS], KIND_CODE[EventKind.POWER_RESTORED]], n),
        "head": np.repeat(head[lost], 2),
        "direction": np.zeros(2 * n, np.int64),
        "channel": np.full(2 * n, NO_CHANNEL),
        "detail": np.tile([Detail.NO_RECORDS, Detail.NONE], n),
        "aux_ns": np.tile([power_gap_ns, 0], n).astype(np.int64),
    }


def head_event_columns(
    kind: EventKind, head: np.ndarray, time_ns: np.ndarray, detail: Detail = Detail.NONE, aux_ns: int = 0
) -> dict[str, np.ndarray]:
    """One event of ``kind`` per head key, at its time (no direction, no channel).  Columns of an
    :class:`EventBlock` without ``source``."""
    n = len(head)
    return {
        "time_ns": np.asarray(time_ns, np.int64),
        "kind": np.full(n, KIND_CODE[kind]),
        "head": np.asarray(head, np.int64),
        "direction": np.zeros(n, np.int64),
        "channel": np.full(n, NO_CHANNEL),
        "detail": np.full(n, detail),
        "aux_ns": np.full(n, aux_ns, np.int64),
    }


def silent_loss_columns(head: np.ndarray, last_ns: np.ndarray, power_gap_ns: int) -> dict[str, np.ndarray]:
    """POWER_LOSS events of heads silent since ``last_ns`` while the log ran on (not heard again yet):
    each at ``last + power gap``.  Columns of an :class:`EventBlock` without ``source``."""
    time_ns = np.asarray(last_ns, np.int64) + power_gap_ns
    return head_event_columns(EventKind.POWER_LOSS, head, time_ns, Detail.NO_RECORDS, power_gap_ns)


def silent_heads(last_ns: np.ndarray, watermark_ns: int, power_gap_ns: int) -> np.ndarray:
    """Which heads, last heard at ``last_ns`` (NONE: never) and with nothing heard since, are known to have
    lost power: the watermark (the log's clock less the order slack: no record still to come is earlier)
    is more than the power gap past their last record."""
    return (last_ns != NONE) & (watermark_ns > last_ns + power_gap_ns)


HELD = "are held, never shown clear on their other heads' counts alone"  # in each warning of a head not heard


def _held(layout: Layout, heads: Sequence[str], what: str) -> list[str]:
    """A warning per head of the layout in ``heads`` (layout order) that bounds a section, saying ``what``."""
    out = []
    for head in layout.heads:
        secs = [s.id for s, _ in layout.sections_of(head.id)]
        if secs and head.id in heads:
            out.append(
                f"counting head {head.id} of the layout {what}: the sections it bounds ({', '.join(secs)}) {HELD}"
            )
    return out


def _counted(layout: Layout, log_heads: Sequence[tuple[int, str]]) -> set[str]:
    return {spec.id for device_id, name in log_heads if (spec := layout.counted_head(name, device_id)) is not None}


def absent_head_warnings(layout: Layout, log_heads: Sequence[tuple[int, str]]) -> list[str]:
    """The layout's heads bounding a section that no head of the log counts for (absent from the log, or there
    only under another device): their sections are held, never shown clear on their other heads' counts alone
    (:class:`~console.analysis.sections.engine.SectionEngine`), in layout order."""
    counted = _counted(layout, log_heads)
    return _held(layout, [h.id for h in layout.heads if h.id not in counted], "has no record in the log")


def shared_head_warnings(layout: Layout, log_heads: Sequence[tuple[int, str]]) -> list[str]:
    """The layout's heads with no device of their own that several devices of the log report (a Trackinfo
    set wrong on a board): their records are counted as one head's, which no layout can undo; in layout order."""
    devices: dict[str, list[int]] = {}
    for device_id, name in log_heads:
        devices.setdefault(name, []).append(int(device_id))
    out = []
    for head in layout.heads:
        ids = sorted(set(devices.get(head.id, [])))
        if head.device_id is None and len(ids) > 1:
            out.append(
                f"counting head {head.id} is in the log from devices {', '.join(map(str, ids))}, and the layout "
                "gives it no device: their records are counted as one head's (a board's Trackinfo set wrong?); "
                "give the head its device_id in the layout"
            )
    return out


def silent_head_warnings(layout: Layout, log_heads: Sequence[tuple[int, str]], unheard: Collection[str]) -> list[str]:
    """The layout's heads in the log (not told by :func:`absent_head_warnings`) that the section engine never
    heard of at the end (``unheard``: no wheel record of theirs, only status records)."""
    counted = _counted(layout, log_heads)
    return _held(layout, [h for h in unheard if h in counted], "has no wheel record in the log")


def diag_detection_events(
    analysis: DiagAnalysis, layout: Layout, settings: DiagEventSettings | None = None
) -> tuple[list[DetectionEvent], list[str]]:
    """(events in time order, warnings about log heads the layout does not know)."""
    from console.analysis.counting.bank import CounterBank
    from console.analysis.events.queue import EventQueue
    from parsers.units import ALL_TIME

    s = settings or DiagEventSettings()
    warnings: list[str] = []
    names = [name for _, name in analysis.heads]
    counted = np.zeros(len(names), bool)
    three: list[int] = []
    up = np.ones(len(names), bool)
    for key, (device_id, name) in enumerate(analysis.heads):  # per head: the layout's word on it
        if not layout.has_head(name):
            warnings.append(f"counting head {name} (device {device_id}) is in the log but not in the layout")
            continue
        head = layout.head(name)
        if head.device_id is not None and head.device_id != device_id:
            warnings.append(f"counting head {name}: the log's device {device_id} is not the layout's {head.device_id}")
            continue
        counted[key] = True
        up[key] = head.up_is_first_channel_first
        if head.channels == 3:
            three.append(key)
    warnings += shared_head_warnings(layout, analysis.heads) + absent_head_warnings(layout, analysis.heads)
    pool = StringPool()
    queue = EventQueue(names, pool.strings)
    wr = analysis.wheel_records
    if len(wr):
        hk = wr["head"].to_numpy(np.int64)
        ch = wr["channel"].to_numpy(np.int64)
        t = wr["time_ns"].to_numpy(np.int64)
        v = wr["value"].to_numpy(np.int64)
        sub = wr["subsecond"].to_numpy(bool) if "subsecond" in wr else np.ones(len(hk), bool)
        is_two = counted.copy()
        is_two[three] = False
        order = np.lexsort((t, hk))  # per head by time; ties keep the log's order
        order = order[is_two[hk[order]]]
        if len(order):
            keys = hk[order]
            starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
            heads = keys[starts]
            bank = CounterBank(s.counting, names=names, pool=pool)
            point_mode = ~np.logical_or.reduceat(v[order] == 0, starts)
            whole_second = ~np.logical_and.reduceat(sub[order], starts)
            bank.configure(heads, up[heads], point_mode, whole_second)
            counting = bank.feed(keys, ch[order], t[order], v[order])
            flushed = bank.flush()
            # Per head in time order, stably: the generation order breaks ties.
            for block in (counting, flushed):
                queue.push(block, block.head, _COUNTING)
        for key in three:  # per three-element head
            rows = hk == key
            on = v[rows] == 1
            spec = layout.head(names[key])
            evs = majority_events(
                names[key],
                ch[rows][on],
                t[rows][on],
                up_is_s1_to_s3=spec.up_is_first_channel_first,
                settings=s.majority,
            )
            queue.push(EventBlock.from_events(evs, names, pool), np.full(len(evs), key, np.int64), _COUNTING)
    if s.power_gap_s is not None and len(analysis.activity):
        act = analysis.activity
        ak = act["head"].to_numpy(np.int64)
        first = act["t_first_ns"].to_numpy(np.int64)
        last = act["t_last_ns"].to_numpy(np.int64)
        order = np.lexsort((first, ak))
        order = order[counted[ak[order]]]
        gap_ns = int(s.power_gap_s * NS)
        cols = power_gap_columns(ak[order], first[order], last[order], np.full(len(order), NONE), gap_ns)
        # A head silent at the end while the log ran on: lost, not heard again.
        ends = np.r_[np.flatnonzero(ak[order][1:] != ak[order][:-1]), len(order) - 1] if len(order) else order
        tail_head, tail_last = ak[order][ends], last[order][ends]
        silent = silent_heads(tail_last, int(last.max()) - int(ORDER_SLACK_S * NS), gap_ns)
        tail = silent_loss_columns(tail_head[silent], tail_last[silent], gap_ns)
        cols = {c: np.concatenate([cols[c], tail[c]]) for c in cols}
        cols["source"] = np.full(len(cols["time_ns"]), pool.code("diag"))
        block = EventBlock.from_columns(cols, names, pool.strings)
        queue.push(block, block.head, _POWER)
    return queue.pop_below(int(ALL_TIME)).events(), warnings
