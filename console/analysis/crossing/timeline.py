"""Crossing timelines: per crossing and train, when the warning came and went.

Times estimated from the fixes themselves (a real log has no other truth):

* ``t_head_arrival`` — the head's chainage reaching the crossing,
  interpolated between the two head fixes around it (EOT + train length when
  the head unit was lost);
* ``t_tail_clear`` — the EOT passing the far edge of the road, interpolated
  between EOT fixes;
* lead time = head arrival − warning on (should be ≥ the warning time); the
  warning that counts is the one on when the head arrived (one released for a
  train proven out of reach, then on again, counts from its second onset);
* spare = lead − warning time, split in hindsight into physics (what the
  unit's bounds cost even knowing the motion) and doubt by cause
  (:mod:`console.analysis.crossing.spare`);
* excess = warning off − tail clear (road closed for nothing);
* a **violation** is the warning off (or not yet on) while any part of the
  train is within the crossing, or a **late warning**: on less than the
  crossing's warning time before the head arrived (``late_by_s`` says by how
  much; the road users did not get the time the crossing promises them).
  Late warnings are listed first.  Where the telemetry itself began too
  late for any controller to warn in time, ``late_cause`` says so;
* fixes the controller set aside as position jumps are left out here too;
* the fixed-time **baseline** switches off at head arrival + train length /
  speed + margin; where that comes before the tail clears, the baseline
  would have opened the road too early.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from console.analysis.crossing.controller import EOT, HEAD, ControllerSettings, CrossingController, Fix
from console.analysis.crossing.spare import SpareSplit, head_motion, split_spare
from console.analysis.timefmt import iso
from parsers.units import NS


@dataclass(frozen=True)
class TimelineRow:
    crossing: str
    train: str
    t_on_ns: int | None
    t_head_arrival_ns: int | None
    t_tail_clear_ns: int | None
    t_off_ns: int | None
    lead_s: float | None
    excess_s: float | None
    reason_on: str
    reason_off: str
    alarms: tuple[str, ...]
    violations: tuple[str, ...]
    baseline_off_ns: int | None
    baseline_early_s: float | None  # > 0: the baseline opened the road this long before the tail cleared
    baseline_excess_s: float | None
    warning_time_s: float = 0.0  # what the crossing promises road users
    late_by_s: float | None = None  # > 0: the warning came this much short of the warning time
    late_cause: str = ""  # what in the telemetry made it late, when the data show it
    spare: SpareSplit | None = None  # the lead beyond the warning time: physics and doubt, in hindsight
    released: int = 0  # warnings for this train switched off before it arrived (proven out of reach)

    def to_dict(self) -> dict[str, Any]:
        def r(x: float | None) -> float | None:
            return None if x is None else round(x, 3)

        return {
            "crossing": self.crossing,
            "train": self.train,
            "t_on": iso(self.t_on_ns),
            "t_head_arrival": iso(self.t_head_arrival_ns),
            "t_tail_clear": iso(self.t_tail_clear_ns),
            "t_off": iso(self.t_off_ns),
            "lead_time_s": r(self.lead_s),
            "warning_time_s": self.warning_time_s,
            "late_by_s": r(self.late_by_s),
            "late_cause": self.late_cause or None,
            "spare": self.spare.to_dict() if self.spare is not None else None,
            "released_warnings": self.released,
            "excess_warning_s": r(self.excess_s),
            "reason_on": self.reason_on,
            "reason_off": self.reason_off,
            "alarms": list(self.alarms),
            "violations": list(self.violations),
            "baseline_off": iso(self.baseline_off_ns),
            "baseline_early_s": r(self.baseline_early_s),
            "baseline_excess_s": r(self.baseline_excess_s),
        }


def crossing_time(times_ns: np.ndarray, chainage: np.ndarray, target: float, direction: int) -> int | None:
    """First time the chainage reaches ``target`` in the direction of travel (linear between fixes)."""
    if len(times_ns) == 0 or direction == 0:
        return None
    signed = direction * (chainage - target)
    reached = np.flatnonzero(signed >= 0)
    if len(reached) == 0:
        return None
    i = int(reached[0])
    if i == 0:
        return int(times_ns[0])
    a, b = signed[i - 1], signed[i]
    frac = -a / (b - a) if b != a else 1.0
    return int(times_ns[i - 1] + frac * (times_ns[i] - times_ns[i - 1]))


def _mean_speed_near(times_ns: np.ndarray, chainage: np.ndarray, t_ns: int, window_s: float = 20.0) -> float | None:
    """Mean speed (m/s) over the fixes within ``window_s`` of ``t_ns``: first to last, along the track."""
    sel = np.flatnonzero(np.abs(times_ns - t_ns) <= window_s * NS)
    if len(sel) < 2 or times_ns[sel[-1]] <= times_ns[sel[0]]:
        return None
    return float(abs(chainage[sel[-1]] - chainage[sel[0]]) / ((times_ns[sel[-1]] - times_ns[sel[0]]) / NS))


def timeline(
    ctl: CrossingController,
    fixes: Sequence[Fix],
    settings: ControllerSettings | None = None,
) -> list[TimelineRow]:
    """One row per train the controller tracked (from its fixes and events)."""
    s = settings or ctl.s
    c = ctl.crossing.chainage_m
    half = s.crossing_half_width_m
    rows = []
    wt = ctl.crossing.warning_time_s
    for train, tr in ctl.tracks.items():
        aside = {(role, t) for (tn, role), times in ctl.set_aside.items() if tn == train for t in times}
        own = [
            f
            for f in fixes
            if f.train == train and f.valid and not math.isnan(f.chainage_m) and (f.role, f.t_fix_ns) not in aside
        ]
        heads = sorted((f for f in own if f.role == HEAD), key=lambda f: f.t_fix_ns)
        eots = sorted((f for f in own if f.role == EOT), key=lambda f: f.t_fix_ns)
        d = tr.direction
        ht = np.array([f.t_fix_ns for f in heads], dtype=np.int64)
        hc = np.array([f.chainage_m for f in heads])
        et = np.array([f.t_fix_ns for f in eots], dtype=np.int64)
        ec = np.array([f.chainage_m for f in eots])
        t_head = crossing_time(ht, hc, c - d * half, d)
        if t_head is None and len(et):
            t_head = crossing_time(et, ec + d * tr.spec.length_m, c - d * half, d)
        t_tail = crossing_time(et, ec, c + d * half, d)
        t_on, t_off = tr.t_on, (tr.t_off if not tr.warned else None)
        if t_on is None and t_head is None:
            continue  # this train never came near the crossing
        violations = []
        late_by = None
        late_cause = ""
        if t_head is not None and (t_on is None or t_on > t_head):
            violations.append("warning not on when the head reached the crossing")
        if t_head is not None:
            lead = None if t_on is None else (t_head - t_on) / NS
            late_by = wt - lead if lead is not None else None
            if late_by is not None and late_by > 0:
                violations.insert(
                    0, f"late warning: on {lead:.1f} s before the head arrived, {late_by:.1f} s short of {wt:g} s"
                )
            if late_by is None or late_by > 0:
                first = min((f.t_fix_ns for f in own), default=None)
                if first is not None and (t_head - first) / NS < wt:
                    late_cause = f"the telemetry begins only {(t_head - first) / NS:.1f} s before the head arrived"
        if t_off is not None and (t_tail is None or t_off < t_tail):
            violations.append("warning off before the tail cleared the crossing")
        speeds = [f.speed_mps for f in heads if not math.isnan(f.speed_mps)] or [
            f.speed_mps for f in eots if not math.isnan(f.speed_mps)
        ]
        base_off = base_early = base_excess = None
        v_fixes = None
        if t_head is not None and not speeds:
            # An export without speed: the baseline takes the head's mean speed around arrival.
            v_fixes = _mean_speed_near(ht, hc, t_head) if len(ht) else _mean_speed_near(et, ec, t_head)
        if t_head is not None and (speeds or v_fixes is not None):
            # Speed near arrival: the fix closest before the head reached the crossing.
            near = [f.speed_mps for f in heads if f.t_fix_ns <= t_head and not math.isnan(f.speed_mps)]
            v = v_fixes if v_fixes is not None else (near[-1] if near else speeds[0]) or 0.1
            base_off = t_head + int((tr.spec.length_m / max(v, 0.1) + s.baseline_margin_s) * NS)
            if t_tail is not None:
                base_early = max(0.0, (t_tail - base_off) / NS)
                base_excess = (base_off - t_tail) / NS
        lead = None if t_on is None or t_head is None else (t_head - t_on) / NS
        spare = None
        if lead is not None and t_head is not None and lead >= 0:
            motion = head_motion(
                [(f.t_fix_ns, f.role, f.chainage_m, f.speed_mps) for f in own if f.t_fix_ns <= t_head],
                d,
                tr.spec.length_m,
                c,
                half,
                s.noise_m / 3.0,
                s.speed_sigma_mps,
                s.jerk_psd,
            )
            doubt = tr.onset.doubt_s if tr.onset is not None else {}
            spare = split_spare(lead, wt, t_head, motion, doubt, s.guard_distance_m, s.accel_mps2, s.line_speed_mps)
        rows.append(
            TimelineRow(
                crossing=ctl.crossing.code,
                train=train,
                t_on_ns=t_on,
                t_head_arrival_ns=t_head,
                t_tail_clear_ns=t_tail,
                t_off_ns=t_off,
                lead_s=None if t_on is None or t_head is None else (t_head - t_on) / NS,
                excess_s=None if t_off is None or t_tail is None else (t_off - t_tail) / NS,
                reason_on=tr.reason_on,
                reason_off=tr.reason_off if t_off is not None else "held on: no positive evidence the tail has passed",
                alarms=tuple(e.reason for e in ctl.events if e.train == train and e.kind == "alarm"),
                violations=tuple(violations),
                baseline_off_ns=base_off,
                baseline_early_s=base_early,
                baseline_excess_s=base_excess,
                warning_time_s=wt,
                late_by_s=late_by if late_by is not None and late_by > 0 else None,
                late_cause=late_cause,
                spare=spare,
                released=len(tr.releases),
            )
        )
    return rows
