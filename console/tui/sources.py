"""What every station-view source shows alike: a train as its units' last fixes place it, an integrity change."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from console.analysis.crossing.values import ControllerSettings, Fix
from console.analysis.integrity.values import PARTED
from console.tui.model import LogEntry, TrainView
from parsers.units import NS

if TYPE_CHECKING:
    from console.live.engine import LiveEngine

INTEGRITY_SEVERITY = {"whole": "info", "doubtful": "warning", PARTED: "critical"}


def integrity_entry(t_ns: int, train: str, state: str, evidence: Sequence[str]) -> LogEntry:
    """A train's integrity change as the event log shows it, with its evidence."""
    return LogEntry(t_ns, INTEGRITY_SEVERITY.get(state, "warning"), f"train {train} {state}: {'; '.join(evidence)}")


STALE_S = ControllerSettings().stale_after_s  # the crossing units' own rule for a silent unit


def reported_train(
    train: str,
    length_m: float,
    head: Fix | None,
    eot: Fix | None,
    now_ns: int,
    next_stop: str = "–",
    controller: str = "–",
    true_head_m: float | None = None,
    integrity: str | None = None,
) -> TrainView | None:
    """A train as the console knows it: from the last head and EOT fixes that reached it.

    A missing end is placed a train length from the other, so the diagram still
    shows the train; the ages tell the panel which end is only inferred."""
    ref = head or eot
    if ref is None:
        return None
    d = ref.direction_hint or (head.direction_hint if head else 0) or 1

    def now_at(f: Fix) -> float:
        # Dead reckoning from a fresh fix, so the diagram moves between reports;
        # a stale unit's train stays where it was last heard.
        age_s = (now_ns - f.t_fix_ns) / NS
        v = f.speed_mps if f.speed_mps == f.speed_mps else 0.0
        return f.chainage_m + (d * v * age_s if 0 < age_s <= STALE_S else 0.0)

    head_m = now_at(head) if head else now_at(ref) + d * length_m
    tail_m = now_at(eot) if eot else head_m - d * length_m
    v = ref.speed_mps if ref.speed_mps == ref.speed_mps else 0.0
    return TrainView(
        train,
        head_m,
        tail_m,
        d,
        v * 3.6,
        next_stop,
        controller,
        head_age_s=(now_ns - head.t_fix_ns) / NS if head else None,
        eot_age_s=(now_ns - eot.t_fix_ns) / NS if eot else None,
        true_head_m=true_head_m,
        integrity=integrity,
    )


def engine_trains(live: LiveEngine, now_ns: int, gone_s: float) -> list[TrainView]:
    """The trains a live engine's units place (from their last fixes), each with its integrity; a train whose
    head unit (or, without one, EOT unit) has not been heard for ``gone_s`` has left the line."""
    cf = live.crossings
    if cf is None:
        return []
    out = []
    for train in sorted({t for t, _ in cf.last}):
        head, eot = cf.last.get((train, "head")), cf.last.get((train, "eot"))
        ref = head or eot
        if ref is None or now_ns - ref.t_fix_ns > gone_s * NS:
            continue
        integrity = live.integrity.monitor.state(train) if live.integrity is not None else None
        view = reported_train(train, cf.default_length_m, head, eot, now_ns, integrity=integrity)
        if view is not None:
            out.append(view)
    return out
