"""Train integrity: is each train whole, in doubt, or parted?  Three witnesses, one verdict.

The level-crossing paper (Co Nhu Van, TCSJ 2026, §2.2) gives the cab unit
the EOT unit's status "to ensure the integrity of the train"; here the
console checks it from what reaches it:

* **GNSS** (:mod:`console.analysis.integrity.gnss`): each EOT fix against
  the head's bounds at its time, a train length behind and at the head's
  speed.  A fix both behind *and* slower is a rear part falling behind
  (``parted`` at once); two fixes in a row behind or slower, one of them
  slower, likewise; three in a row only behind (a standing head shows no
  speed difference) likewise.  One such fix alone, a fix ahead or faster
  than a whole train allows, or a stale unit is **doubt**.
* **Axle counters**: once two head fixes place the head a train length
  (and every allowance) past a counting head, the axles counted there in
  the train's direction since it arrived must be the consist's.  Fewer,
  with the counter's own doubt (a single system, a count error, a fault,
  a power loss) quiet, is a rear part that never passed.
* **Sections**: the section the train left at that head must not stay
  occupied behind it (unless another followed train is in it).
* **Brake pipe** (:mod:`console.analysis.integrity.brake_pipe`), where the units
  report it: the rear pipe vented while the front stayed charged is
  ``parted``; both vented (an emergency of the whole train) or the front's
  status unknown is doubt.

Fusion: ``parted`` on the GNSS or the brake-pipe witness alone, or on the counters' short
count and the section left occupied together, or on a GNSS separation
doubt and a counters' separation doubt together; a short count with a
consistent EOT fix measured after it is doubt, not parted (the counters
disagree with the unit riding on the last vehicle).  ``parted`` is
latched: only :meth:`IntegrityMonitor.reset` (the rear part recovered)
leaves it.  An EOT unit that goes silent is doubt, never parted: nothing
but positive evidence of a separation parts a train.

The monitor is pure (no I/O): feed it with :meth:`~IntegrityMonitor.fix`,
:meth:`~IntegrityMonitor.detection` (axles and the counters' doubt),
:meth:`~IntegrityMonitor.passage` (a head's axle count at once),
:meth:`~IntegrityMonitor.transition` (section states) and
:meth:`~IntegrityMonitor.tick`; each returns the state changes it caused,
each carrying its evidence.  The counters' evidence is weighed at the next
fix or tick: by then the section changes that go with a block of axles have
arrived too (the pipeline hands the axles first, then the changes).
"""

from __future__ import annotations

import heapq
import math
import statistics
from bisect import bisect_left
from dataclasses import dataclass, field
from typing import Any

from console.analysis.crossing.evidence import DeviceEvidence, EvidenceLimits
from console.analysis.events.detection import DetectionEvent
from console.analysis.integrity.brake_pipe import BRAKE_PIPE as BRAKE_PIPE  # the witnesses' names, re-exported
from console.analysis.integrity.brake_pipe import BrakePipeWitness, BrakeSettings
from console.analysis.integrity.counts import AXLES as AXLES
from console.analysis.integrity.counts import NONE, CountsWitness, HeadCheck, Opinion
from console.analysis.integrity.counts import SECTIONS as SECTIONS
from console.analysis.integrity.gnss import (
    BEHIND,
    CONSISTENT,
    INCONSISTENT,
    SLOWER,
    STRONG,
    GnssLimits,
    Point,
    Verdict,
    head_bounds,
    judge_eot,
)
from console.analysis.sections.state import Transition
from console.analysis.timefmt import iso
from console.analysis.window import Window
from console.layout import Layout
from parsers.units import NS

WHOLE, DOUBTFUL, PARTED = "whole", "doubtful", "parted"
HEAD, EOT = "head", "eot"
GNSS = "gnss"
SEPARATION = (BEHIND, SLOWER, STRONG)
AROUND = 2  # head fixes each side of an EOT fix's time that bound the head there


@dataclass(frozen=True)
class IntegritySettings:
    noise_m: float = 5.0  # σ of a fix along the track (the receivers' figure)
    speed_noise_mps: float = 0.2  # σ of a reported (Doppler) speed
    k_sigma: float = 3.5  # allowances are this many σ (each fix: a difference of two gets twice)
    max_accel_mps2: float = 1.5  # no train changes speed faster, emergency braking included
    max_speed_mps: float = 45.0
    clock_offset_s: float = 0.2  # each unit's clock may be this far off
    coupling_slack_m: float = 5.0  # EOT mount beyond the last wheel, couplers' play
    report_period_s: float = 10.0  # the units' report period
    latency_s: float = 2.0  # radio and processing delay allowance
    stale_after_s: float = 30.0  # at least this long without a fix: the unit is stale
    counter_lag_s: float = 5.0  # axle events and section changes reach the monitor within this
    history_s: float = 240.0  # fixes and axle events kept
    emergency_hold_s: float = 30.0  # an emergency brake application is held at least this long

    @property
    def stale_s(self) -> float:
        """A unit is stale after several missed reports (never after one lost packet) and the latency."""
        return max(self.stale_after_s, 4 * self.report_period_s) + self.latency_s

    def gnss_limits(self) -> GnssLimits:
        return GnssLimits(
            self.noise_m,
            self.speed_noise_mps,
            self.k_sigma,
            self.max_accel_mps2,
            self.max_speed_mps,
            self.clock_offset_s,
            self.coupling_slack_m,
        )


@dataclass(frozen=True)
class ConsistSpec:
    """What the console knows of a train: its length and, where the layout or the simulator
    knows it, its axle count."""

    train: str
    length_m: float  # first to last wheel; the EOT rides on the last vehicle
    axles: int | None = None
    # False: the length is only the layout's guess; the monitor learns it from the first fixes
    # (head–EOT distance while running whole) and judges by speed alone until then.
    length_known: bool = True


@dataclass(frozen=True)
class IntegrityEvent:
    """A change of a train's integrity state, with the evidence for it."""

    t_ns: int
    train: str
    state: str  # whole | doubtful | parted
    previous: str | None  # None: the first state known
    witnesses: tuple[str, ...]  # gnss | axles | sections: who gave the evidence
    evidence: tuple[str, ...]
    rear_m: float | None = None  # the rear part's (EOT's) last chainage, when parted

    def to_dict(self) -> dict[str, Any]:
        return {
            "train": self.train,
            "state": self.state,
            "previous": self.previous,
            "witnesses": list(self.witnesses),
            "evidence": list(self.evidence),
            "rear_m": None if self.rear_m is None else round(self.rear_m, 1),
            "time_ns": self.t_ns,
            "time": iso(self.t_ns),
        }


@dataclass
class _Unit:
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
class _Judged:
    t_fix_ns: int
    s_m: float
    speed_mps: float
    speed_hi_mps: float
    verdict: Verdict | None  # None: no head fix to judge it by yet
    bracket: tuple[int, int] | None = None  # the head fixes' times just before and just after it, once bracketed


LEARN_SAMPLES = 5  # head–EOT distances that make a learnt length (their median)


@dataclass
class _Train:
    spec: ConsistSpec
    head: _Unit
    eot: _Unit
    length_m: float | None = None  # as given, or learnt; None: still being learnt
    samples: list[float] = field(default_factory=list)
    direction: int = 0
    state: str | None = None
    judged: Window[_Judged] = field(default_factory=lambda: Window(4))
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


# A train to evaluate at the next fix or tick whatever the time (its evidence changed).
_AT_ONCE = -(2**63)


class IntegrityMonitor:
    """Integrity states of the trains the console follows.  Pure: feed it, read the events."""

    def __init__(self, settings: IntegritySettings | None = None, layout: Layout | None = None) -> None:
        self.s = settings or IntegritySettings()
        self.lim = self.s.gnss_limits()
        self.layout = layout
        self.trains: dict[str, _Train] = {}
        self.now_ns: int | None = None  # the units' clock: the latest fix reception or tick
        self.counts = CountsWitness(
            layout, self.lim.pos_allow_m, self.lim.coupling_slack_m, self.s.counter_lag_s, self.s.history_s
        )
        self.late_fixes = 0  # fixes older than their unit's last one: set aside
        # The agenda: a fix or a tick evaluates the trains whose verdict it can change, not every train
        # followed.  A train's verdict changes with its own evidence (its fixes, brake reports, the
        # operator's reset: it is evaluated at once), with the counters' evidence (a train with a
        # counters' check still open is evaluated every time, as before), and with time alone only
        # as a unit goes stale (the instants _stale and _silent turn at: its due instant).  Between
        # them evaluating it finds the same verdict and changes nothing, so it is left out; doubt is
        # never late: a train is evaluated at the first fix or tick at or after each of its instants.
        self._seq = 0
        self._due: list[tuple[int, int, str]] = []  # (due_ns, seq, train), stale entries skipped
        self._open: dict[int, str] = {}  # seq → train: trains with a counters' check still open

    # -- trains ------------------------------------------------------------
    def _unit(self) -> _Unit:
        s = self.s
        noise = s.k_sigma * s.noise_m
        lim = EvidenceLimits(noise, s.max_accel_mps2, s.max_accel_mps2, s.max_speed_mps, speed_error_mps=0.5)
        return _Unit(DeviceEvidence(lim))

    def add_train(self, spec: ConsistSpec) -> None:
        """Follow a train (again: its consist is updated, its history kept)."""
        tr = self.trains.get(spec.train)
        if tr is None:
            self._seq += 1
            tr = self.trains[spec.train] = _Train(spec, self._unit(), self._unit(), seq=self._seq)
            s = self.s
            tr.brake = BrakePipeWitness(BrakeSettings(s.clock_offset_s, s.emergency_hold_s, s.history_s))
        else:
            self._at_once(tr)  # its consist changed: its checks are judged by it
        tr.spec = spec
        if spec.length_known:
            tr.length_m = spec.length_m

    def forget(self, train: str) -> None:
        """Stop following a train that has left the line."""
        tr = self.trains.pop(train, None)
        if tr is not None:  # its agenda entries go stale with it
            self._open.pop(tr.seq, None)

    def reset(self, train: str, t_ns: int) -> list[IntegrityEvent]:
        """The operator accounts for the rear part (recoupled, or taken away): judge the train afresh."""
        tr = self.trains.get(train)
        if tr is None:
            return []
        self._at_once(tr)
        tr.parted_by = None
        tr.judged.clear()
        tr.gnss = tr.counters = tr.brake_opinion = NONE
        tr.brake.front.clear()
        tr.brake.rear.clear()
        tr.checks.clear()
        tr.rear_m = None
        if tr.state is None:
            return []
        # Doubtful until the witnesses judge it afresh.
        ev = IntegrityEvent(t_ns, tr.spec.train, DOUBTFUL, tr.state, (), ("reset by the operator: judged afresh",))
        tr.state = DOUBTFUL
        tr.events.append(ev)
        return [ev]

    def state(self, train: str) -> str | None:
        tr = self.trains.get(train)
        return None if tr is None else tr.state

    def evidence(self, train: str) -> tuple[str, ...]:
        tr = self.trains.get(train)
        return () if tr is None or not tr.events else tr.events[-1].evidence

    def rear_m(self, train: str) -> float | None:
        tr = self.trains.get(train)
        return None if tr is None else tr.rear_m

    def _clock(self, t_ns: int) -> int:
        self.now_ns = t_ns if self.now_ns is None else max(self.now_ns, t_ns)
        return self.now_ns

    # -- GNSS --------------------------------------------------------------
    def fix(
        self,
        t_ns: int,
        t_fix_ns: int,
        train: str,
        role: str,
        chainage_m: float,
        speed_mps: float = math.nan,
        brake_pipe_bar: float = math.nan,
        emergency: bool = False,
    ) -> list[IntegrityEvent]:
        """One fix of a train's head or EOT unit, received at ``t_ns`` (measured at ``t_fix_ns``);
        ``brake_pipe_bar``: the pressure its report carried (NaN: none); ``emergency``: the report is
        the unit's emergency status (its pipe venting)."""
        if not math.isnan(brake_pipe_bar) or emergency:
            self._brake(train, role, t_fix_ns, brake_pipe_bar, emergency)
        now = self._clock(t_ns)
        tr = self.trains.get(train)
        if tr is not None:
            self._at_once(tr)  # whatever of the fix it takes (a first reception, a jump) is its evidence
        if tr is None or role not in (HEAD, EOT) or math.isnan(chainage_m):
            return self.tick(now)
        unit = tr.head if role == HEAD else tr.eot
        if unit.first_rx_ns is None:
            unit.first_rx_ns = now
        if unit.last_fix_ns is not None and t_fix_ns <= unit.last_fix_ns:
            self.late_fixes += 1
            return self.tick(now)
        rep = unit.ev.offer(t_fix_ns, chainage_m, speed_mps)
        if rep is None:  # a position jump, set aside: it refreshes nothing
            return self.tick(now)
        if rep.restarted:
            # The unit's track started over from two agreeing set-aside fixes: what came before
            # is not comparable with what follows.
            for col in (unit.times, unit.chainage, unit.speed, unit.speed_hi):
                col.clear()
            if role == EOT:
                tr.judged.clear()
            else:
                tr.checks.clear()
                for j in tr.judged:  # judged against the old track: judge them again
                    j.verdict = None
        unit.last_fix_ns = t_fix_ns
        unit.times.append(t_fix_ns)
        unit.chainage.append(chainage_m)
        unit.speed.append(speed_mps)
        unit.speed_hi.append(rep.speed_hi_mps)
        unit.prune(t_fix_ns - int(self.s.history_s * NS))
        self._direction(tr)
        if role == EOT:
            tr.judged.append(_Judged(t_fix_ns, chainage_m, speed_mps, rep.speed_hi_mps, None))
            self._judge(tr)
        else:
            self._judge(tr)  # a new head fix brackets the EOT fixes before it
            self.counts.open_checks(tr.checks, tr.head.times, tr.head.chainage, tr.direction, tr.length_m, now)
        return self._evaluate(now)

    def _direction(self, tr: _Train) -> None:
        # The head unit's movement says it; the EOT's only while nothing else has (a rear part
        # falling behind must not turn the train round).
        d = tr.head.ev.direction() or (0 if tr.direction else tr.eot.ev.direction())
        if d and d != tr.direction:
            if tr.direction:
                tr.checks.clear()  # the train reversed: the counts so far were another run
            tr.direction = d
            for j in tr.judged:
                j.verdict = None

    def _judge(self, tr: _Train) -> None:
        """Judge the EOT fixes not yet judged against a head fix on each side."""
        d = tr.direction
        if not d or tr.head.ev.rejected_since_last:
            # No direction yet, or the head unit's last fix was set aside as a jump: its track is
            # in doubt until a fix agrees with it again (or it starts over).
            tr.gnss = self._gnss_opinion(tr)
            return
        for j in tr.judged:
            if j.verdict is not None and j.verdict.bracketed:
                continue
            around = tr.head.around(j.t_fix_ns, d)
            hb = head_bounds(around, j.t_fix_ns, self.lim)
            if hb is None:
                continue
            if hb.bracketed:
                k = bisect_left([p.t_fix_ns for p in around], j.t_fix_ns)
                j.bracket = (around[max(0, k - 1)].t_fix_ns, around[min(k, len(around) - 1)].t_fix_ns)
            eot = Point(j.t_fix_ns, d * j.s_m, j.speed_mps, j.speed_hi_mps)
            j.verdict = judge_eot(eot, hb, tr.length_m, self.lim)
            if tr.length_m is None and hb.bracketed and j.verdict.kind == CONSISTENT:
                self._learn(tr, 0.5 * (hb.lo_m + hb.hi_m) - eot.s_m)
        tr.gnss = self._gnss_opinion(tr)

    def _learn(self, tr: _Train, separation_m: float) -> None:
        """A head–EOT distance measured while both ran at one speed: the median of the first few
        is the train's length (then every EOT fix is judged again by it)."""
        tr.samples.append(separation_m)
        if len(tr.samples) >= LEARN_SAMPLES:
            tr.length_m = max(0.0, statistics.median(tr.samples))
            for j in tr.judged:
                j.verdict = None

    def _gnss_opinion(self, tr: _Train) -> Opinion:
        # The run of consecutive judged EOT fixes up to the latest judged one.
        run: list[_Judged] = []
        for j in reversed(tr.judged):
            if j.verdict is None:
                if run:
                    break
                continue
            run.append(j)
        if not run:
            return NONE
        run.reverse()
        kinds = [j.verdict.kind for j in run if j.verdict is not None]
        last = run[-1]
        v = last.verdict
        assert v is not None
        t = last.t_fix_ns
        length = tr.length_m
        if v.kind == STRONG:
            return Opinion(PARTED, (GNSS,), (v.describe(length),), t)
        prev = run[-2].verdict if len(run) >= 2 else None
        if prev is not None and prev.kind in SEPARATION and v.kind in SEPARATION and SLOWER in (v.kind, prev.kind):
            why = (f"{prev.describe(length)}, then {v.describe(length)} (two fixes in a row)",)
            return Opinion(PARTED, (GNSS,), why, t)
        if prev is not None and self._standing_rear(run[-2], last):
            why = (f"{v.describe(length)}, the EOT standing while the gap grew by {v.lag_m - prev.lag_m:.0f} m",)
            return Opinion(PARTED, (GNSS,), why, t)
        # Behind only (the head standing or crawling, or no speed reported): three fixes in a row,
        # each judged between head fixes on both sides, and not all between the same ones: after a
        # long gap in the head's fixes, one displaced head fix at its end put three EOT fixes 500 m
        # "behind" at once (a whole train parted, seen in the 3,000-run sweep).
        if (
            len(kinds) >= 3
            and all(j.verdict is not None and j.verdict.kind == BEHIND and j.verdict.bracketed for j in run[-3:])
            and not set.intersection(*(set(j.bracket or ()) for j in run[-3:]))
        ):
            why = (f"{v.describe(length)}, three fixes in a row",)
            return Opinion(PARTED, (GNSS,), why, t)
        if v.kind in SEPARATION:
            return Opinion("separation", (GNSS,), (v.describe(length) + " (one fix)",), t)
        if v.kind == INCONSISTENT:
            return Opinion("doubt", (GNSS,), ("fixes inconsistent: " + v.describe(length),), t)
        return Opinion("ok", (GNSS,), (v.describe(length),), t)

    def _standing_rear(self, a: _Judged, b: _Judged) -> bool:
        """Two fixes in a row behind, the EOT standing at both (its Doppler speed nil, its place the
        same) while the gap to the head grew by more than the noise: a rear part left standing.

        A displaced fix keeps its Doppler speed, so a moving train's jumps never read as standing;
        a whole train standing does not open the gap."""
        va, vb = a.verdict, b.verdict
        if va is None or vb is None or va.kind != BEHIND or vb.kind != BEHIND or not (va.bracketed and vb.bracketed):
            return False
        still = self.lim.speed_allow_mps
        if math.isnan(a.speed_mps) or math.isnan(b.speed_mps) or max(a.speed_mps, b.speed_mps) > still:
            return False
        noise = 2 * self.lim.pos_allow_m
        return abs(b.s_m - a.s_m) <= noise and vb.lag_m - va.lag_m > noise

    # -- the brake pipe ----------------------------------------------------
    def brake_pipe(
        self, t_ns: int, t_meas_ns: int, train: str, role: str, bar: float, emergency: bool = False
    ) -> list[IntegrityEvent]:
        """A unit's brake-pipe pressure (head: the front, EOT: the rear), measured at ``t_meas_ns``,
        received at ``t_ns``: a periodic report's, or an emergency status sent at once
        (``emergency``: the unit saw its pipe venting)."""
        now = self._clock(t_ns)
        if not math.isnan(bar) or emergency:
            self._brake(train, role, t_meas_ns, bar, emergency)
        return self._evaluate(now)

    def _brake(self, train: str, role: str, t_meas_ns: int, bar: float, emergency: bool = False) -> None:
        tr = self.trains.get(train)
        if tr is None or role not in (HEAD, EOT):
            return
        self._at_once(tr)
        tr.brake.report(role == EOT, t_meas_ns, bar, emergency)
        tr.brake_opinion = tr.brake.opinion(tr.length_m if tr.spec.length_known else None)

    # -- counters and sections ---------------------------------------------
    def detection(self, e: DetectionEvent) -> list[IntegrityEvent]:
        """A counting head's event: an axle (counted for the train passing), or the counter's own doubt."""
        self.counts.detection(e)
        return []

    def passage(self, head: str, t_first_ns: int, t_last_ns: int, axles: int, direction: int) -> list[IntegrityEvent]:
        """A head's passage at once: ``axles`` counted from ``t_first_ns`` to ``t_last_ns``."""
        self.counts.passage(head, t_first_ns, t_last_ns, axles, direction)
        return []

    def transition(self, tr: Transition) -> list[IntegrityEvent]:
        """A section's state change (from the section engine)."""
        self.counts.transition(tr)
        return []

    def _run_checks(self, tr: _Train, now: int) -> None:
        for c in tr.checks.values():  # at most one per counting head: done ones are kept, not redone
            if not self.counts.ready(c, now):
                continue
            c.done = True

            def others_in(_section: str, lo: float, hi: float, t_ns: int) -> bool:
                return self._other_train_in(tr, lo, hi, t_ns)

            op = self.counts.judge(c, tr.direction, tr.spec.axles, tr.length_m, others_in)
            if op is not None:
                tr.counters = op

    def _other_train_in(self, tr: _Train, lo: float, hi: float, t_ns: int) -> bool:
        """Another followed train had a unit in (or a body across) ``lo``–``hi`` around ``t_ns``."""
        lo, hi = lo - self.lim.pos_allow_m, hi + self.lim.pos_allow_m
        for other in self.trains.values():
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

    # -- the verdict -------------------------------------------------------
    def tick(self, now_ns: int) -> list[IntegrityEvent]:
        """The passing of time: stale units, counters' checks that have come due."""
        return self._evaluate(self._clock(now_ns))

    def _evaluate(self, now: int) -> list[IntegrityEvent]:
        """The trains whose verdict may change at ``now`` (see the agenda), in the order they were followed."""
        todo = dict(self._open)
        while self._due and self._due[0][0] <= now:
            due_ns, seq, train = heapq.heappop(self._due)
            tr = self.trains.get(train)
            if tr is not None and tr.seq == seq and tr.due_ns == due_ns:
                todo[seq] = train
        out: list[IntegrityEvent] = []
        for seq in sorted(todo):
            tr = self.trains[todo[seq]]
            self._run_checks(tr, now)
            out += self._settle(tr, now)
            self._arm(tr, now)
        return out

    def _at_once(self, tr: _Train) -> None:
        tr.due_ns = _AT_ONCE
        heapq.heappush(self._due, (_AT_ONCE, tr.seq, tr.spec.train))

    def _arm(self, tr: _Train, now: int) -> None:
        """``tr`` was just evaluated at ``now``: the next instant a unit of it turns stale (``now − t >
        stale_s``, first true at t + ⌊stale_s⌋ + 1 ns), and whether a counters' check is still open."""
        after = math.floor(self.s.stale_s * NS) + 1
        turns = [t + after for t in (tr.head.first_rx_ns, tr.head.last_fix_ns, tr.eot.last_fix_ns) if t is not None]
        later = [t for t in turns if t > now]
        tr.due_ns = min(later) if later else None
        if tr.due_ns is not None:
            heapq.heappush(self._due, (tr.due_ns, tr.seq, tr.spec.train))
        if any(not c.done for c in tr.checks.values()):
            self._open[tr.seq] = tr.spec.train
        else:
            self._open.pop(tr.seq, None)

    def _stale(self, tr: _Train, now: int) -> Opinion:
        stale = self.s.stale_s * NS
        head, eot = tr.head, tr.eot
        if eot.last_fix_ns is None:
            if head.first_rx_ns is not None and now - head.first_rx_ns > stale:
                return Opinion("doubt", (GNSS,), ("no EOT fix received",), now)
            return NONE
        head_stale = head.last_fix_ns is None or now - head.last_fix_ns > stale
        if now - eot.last_fix_ns > stale:
            return Opinion("doubt", (GNSS,), (f"EOT stale for {(now - eot.last_fix_ns) / NS:.0f} s",), now)
        if head.last_fix_ns is not None and head_stale:
            why = f"head unit stale for {(now - head.last_fix_ns) / NS:.0f} s: the EOT cannot be checked"
            return Opinion("doubt", (GNSS,), (why,), now)
        return NONE

    def _silent(self, tr: _Train, now: int) -> bool:
        stale = self.s.stale_s * NS
        last = [u.last_fix_ns for u in (tr.head, tr.eot) if u.last_fix_ns is not None]
        return bool(last) and now - max(last) > stale

    def _fuse(self, tr: _Train, now: int) -> tuple[str | None, Opinion]:
        g, c, b = tr.gnss, tr.counters, tr.brake_opinion
        stale = self._stale(tr, now)
        if self._silent(tr, now):
            # Both units silent: the train has left the line, or the data ended. Their last word
            # stands; only the counters can still change it.
            if c.level in ("none", "ok") or c.t_ns <= max(tr.head.last_fix_ns or 0, tr.eot.last_fix_ns or 0):
                return None, NONE
            g = stale = b = NONE
        if g.level == PARTED:
            return PARTED, g
        if b.level == PARTED:
            return PARTED, b
        if c.level == PARTED:
            # A consistent EOT fix measured after the counters' check: the unit riding on the
            # last vehicle says the train is whole there; the counters disagree (doubt).
            if g.level == "ok" and g.t_ns > c.t_ns:
                return DOUBTFUL, Opinion("doubt", (*c.witnesses, GNSS), (*c.evidence, "the EOT says whole"), now)
            return PARTED, c
        if g.level == "separation" and c.level == "separation":
            return PARTED, Opinion(PARTED, (*g.witnesses, *c.witnesses), (*g.evidence, *c.evidence), now)
        doubts = [o for o in (stale, g, b, c) if o.level in ("doubt", "separation")]
        if doubts:
            return DOUBTFUL, Opinion(
                "doubt",
                tuple(w for o in doubts for w in o.witnesses),
                tuple(e for o in doubts for e in o.evidence),
                now,
            )
        oks = [o for o in (g, c) if o.level == "ok"]
        if oks:
            return WHOLE, Opinion(
                "ok", tuple(w for o in oks for w in o.witnesses), tuple(e for o in oks for e in o.evidence)
            )
        return None, NONE

    def _settle(self, tr: _Train, now: int) -> list[IntegrityEvent]:
        if tr.parted_by is not None:
            if tr.eot.chainage:
                tr.rear_m = tr.eot.chainage[-1]
            return []
        state, why = self._fuse(tr, now)
        if state is None or state == tr.state:
            return []
        rear = None
        if state == PARTED:
            tr.parted_by = why
            rear = tr.rear_m = tr.eot.chainage[-1] if tr.eot.chainage else None
        ev = IntegrityEvent(now, tr.spec.train, state, tr.state, why.witnesses, why.evidence, rear)
        tr.state = state
        tr.events.append(ev)
        return [ev]


def timelines(events: list[IntegrityEvent]) -> list[dict[str, Any]]:
    """Per train (in the order they were first judged): its last state and every change, with evidence.

    What ``crossing --json``, the report and the tables show."""
    per: dict[str, list[IntegrityEvent]] = {}
    for e in sorted(events, key=lambda e: e.t_ns):
        per.setdefault(e.train, []).append(e)
    return [
        {"train": train, "state": evs[-1].state, "changes": [e.to_dict() for e in evs]} for train, evs in per.items()
    ]
