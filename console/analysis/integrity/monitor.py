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

from console.analysis.crossing.evidence import DeviceEvidence, EvidenceLimits
from console.analysis.events.detection import DetectionEvent
from console.analysis.integrity.brake_pipe import BrakePipeWitness, BrakeSettings
from console.analysis.integrity.counts import NONE, CountsWitness
from console.analysis.integrity.gnss_run import judge_fixes, set_direction
from console.analysis.integrity.state import Judged, Train, Unit, other_train_in
from console.analysis.integrity.values import (
    DOUBTFUL,
    EOT,
    HEAD,
    PARTED,
    ConsistSpec,
    IntegrityEvent,
    IntegritySettings,
)
from console.analysis.integrity.verdict import fuse
from console.analysis.sections.state import Transition
from console.layout import Layout
from parsers.units import NS

# A train to evaluate at the next fix or tick whatever the time (its evidence changed).
_AT_ONCE = -(2**63)


class IntegrityMonitor:
    """Integrity states of the trains the console follows.  Pure: feed it, read the events."""

    def __init__(self, settings: IntegritySettings | None = None, layout: Layout | None = None) -> None:
        self.s = settings or IntegritySettings()
        self.lim = self.s.gnss_limits()
        self.layout = layout
        self.trains: dict[str, Train] = {}
        self.now_ns: int | None = None  # the units' clock: the latest fix reception or tick
        self.counts = CountsWitness(
            layout, self.lim.pos_allow_m, self.lim.coupling_slack_m, self.s.counter_lag_s, self.s.history_s
        )
        self.late_fixes = 0  # fixes older than their unit's last one: set aside
        # The agenda: a fix or a tick evaluates the trains whose verdict it can change, not every train
        # followed.  A train's verdict changes with its own evidence (its fixes, brake reports, the
        # operator's reset: it is evaluated at once), with the counters' evidence (a train with a
        # counters' check still open is evaluated every time, as before), and with time alone only
        # as a unit goes stale (the instants stale_opinion and silent turn at: its due instant).  Between
        # them evaluating it finds the same verdict and changes nothing, so it is left out; doubt is
        # never late: a train is evaluated at the first fix or tick at or after each of its instants.
        self._seq = 0
        self._due: list[tuple[int, int, str]] = []  # (due_ns, seq, train), stale entries skipped
        self._open: dict[int, str] = {}  # seq → train: trains with a counters' check still open

    # -- trains ------------------------------------------------------------
    def _unit(self) -> Unit:
        s = self.s
        noise = s.k_sigma * s.noise_m
        lim = EvidenceLimits(noise, s.max_accel_mps2, s.max_accel_mps2, s.max_speed_mps, speed_error_mps=0.5)
        return Unit(DeviceEvidence(lim))

    def add_train(self, spec: ConsistSpec) -> None:
        """Follow a train (again: its consist is updated, its history kept)."""
        tr = self.trains.get(spec.train)
        if tr is None:
            self._seq += 1
            tr = self.trains[spec.train] = Train(spec, self._unit(), self._unit(), seq=self._seq)
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
        set_direction(tr)
        if role == EOT:
            tr.judged.append(Judged(t_fix_ns, chainage_m, speed_mps, rep.speed_hi_mps, None))
            judge_fixes(tr, self.lim)
        else:
            judge_fixes(tr, self.lim)  # a new head fix brackets the EOT fixes before it
            self.counts.open_checks(tr.checks, tr.head.times, tr.head.chainage, tr.direction, tr.length_m, now)
        return self._evaluate(now)

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

    def _run_checks(self, tr: Train, now: int) -> None:
        for c in tr.checks.values():  # at most one per counting head: done ones are kept, not redone
            if not self.counts.ready(c, now):
                continue
            c.done = True

            def others_in(_section: str, lo: float, hi: float, t_ns: int) -> bool:
                return other_train_in(self.trains.values(), tr, lo, hi, t_ns, self.lim.pos_allow_m)

            op = self.counts.judge(c, tr.direction, tr.spec.axles, tr.length_m, others_in)
            if op is not None:
                tr.counters = op

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

    def _at_once(self, tr: Train) -> None:
        tr.due_ns = _AT_ONCE
        heapq.heappush(self._due, (_AT_ONCE, tr.seq, tr.spec.train))

    def _arm(self, tr: Train, now: int) -> None:
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

    def _settle(self, tr: Train, now: int) -> list[IntegrityEvent]:
        if tr.parted_by is not None:
            if tr.eot.chainage:
                tr.rear_m = tr.eot.chainage[-1]
            return []
        state, why = fuse(tr, now, self.s)
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
