"""A followed train's state in the integrity monitor: each unit's accepted fixes (:class:`Unit`), the
EOT fixes judged against the head (:class:`Judged`), and the train's witnesses' opinions, its checks
and its events (:class:`Train`); and which other followed train was at a place (:func:`other_train_in`).
"""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Iterable
from dataclasses import dataclass, field

from console.analysis.crossing.evidence import DeviceEvidence
from console.analysis.integrity.brake_pipe import BrakePipeWitness
from console.analysis.integrity.counts import NONE, HeadCheck, Opinion
from console.analysis.integrity.gnss import Point, Verdict
from console.analysis.integrity.values import AROUND, ConsistSpec, IntegrityEvent
from console.analysis.window import Window


@dataclass
class Unit:
    """One GNSS unit's accepted fixes (chainage), in fix-time order."""

    ev: DeviceEvidence
    times: list[int] = field(default_factory=list)
    chainage: list[float] = field(default_factory=list)
    speed: list[float] = field(default_factory=list)
    speed_hi: list[float] = field(default_factory=list)
    last_fix_ns: int | None = None
    first_rx_ns: int | None = None

    def point(self, i: int, d: int) -> Point:
        return Point(self.times[i], d * self.chainage[i], self.speed[i], self.speed_hi[i])

    def around(self, t_ns: int, d: int, n: int = AROUND) -> list[Point]:
        """The ``n`` fixes before ``t_ns`` and the ``n`` after it (fewer where there are none)."""
        i = bisect_left(self.times, t_ns)
        return [self.point(k, d) for k in range(max(0, i - n), min(len(self.times), i + n))]

    def prune(self, before_ns: int) -> None:
        k = bisect_left(self.times, before_ns)
        if k > 0 and k < len(self.times):
            del self.times[:k], self.chainage[:k], self.speed[:k], self.speed_hi[:k]


@dataclass
class Judged:
    t_fix_ns: int
    s_m: float
    speed_mps: float
    speed_hi_mps: float
    verdict: Verdict | None  # None: no head fix to judge it by yet
    bracket: tuple[int, int] | None = None  # the head fixes' times just before and just after it, once bracketed


LEARN_SAMPLES = 5  # head–EOT distances that make a learnt length (their median)


@dataclass
class Train:
    spec: ConsistSpec
    head: Unit
    eot: Unit
    length_m: float | None = None  # as given, or learnt; None: still being learnt
    samples: list[float] = field(default_factory=list)
    direction: int = 0
    state: str | None = None
    judged: Window[Judged] = field(default_factory=lambda: Window(4))
    gnss: Opinion = NONE
    counters: Opinion = NONE
    checks: dict[str, HeadCheck] = field(default_factory=dict)
    parted_by: Opinion | None = None
    rear_m: float | None = None
    events: list[IntegrityEvent] = field(default_factory=list)
    brake: BrakePipeWitness = field(default_factory=BrakePipeWitness)
    brake_opinion: Opinion = NONE
    seq: int = 0  # the order it was first followed in (the order trains are evaluated in)
    due_ns: int | None = None  # the next instant time alone may change its verdict (None: none pending)


def other_train_in(trains: Iterable[Train], tr: Train, lo: float, hi: float, t_ns: int, pos_allow_m: float) -> bool:
    """Another followed train had a unit in (or a body across) ``lo``–``hi`` around ``t_ns``."""
    lo, hi = lo - pos_allow_m, hi + pos_allow_m
    for other in trains:
        if other is tr:
            continue
        ends = []
        for unit in (other.head, other.eot):
            i = bisect_left(unit.times, t_ns)
            near = [unit.chainage[k] for k in (i - 1, i) if 0 <= k < len(unit.times)]
            ends += near
        if not ends:
            continue
        if other.head.times and not other.eot.times:  # no EOT: the body a train length behind
            d = other.direction or 1
            ends += [x - d * (other.length_m or other.spec.length_m) for x in ends]
        if max(ends) >= lo and min(ends) <= hi:
            return True
    return False
