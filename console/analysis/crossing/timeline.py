"""Crossing timelines: per crossing, train and pass, when the warning came and went.

A row is one pass of a train over the crossing (:func:`trips`: a trainset back and forth
passes it trip after trip), paired with the warning on when its head arrived.
Times estimated from the fixes themselves (a real log has no other truth):

* ``t_head_arrival`` — the head's chainage reaching the crossing,
  interpolated between the two head fixes around it (EOT + train length when
  the head unit was lost); the EOT's when it got there first (the EOT end
  leading: a train backing, or pushed);
* ``t_tail_clear`` — the EOT passing the far edge of the road, interpolated
  between EOT fixes; the head unit's when it passed later (it trails);
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
from numpy.lib.stride_tricks import sliding_window_view

from console.analysis.crossing.controller import CrossingController
from console.analysis.crossing.spare import SpareSplit, head_motion, split_spare
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, Fix, Onset, TrainSpec
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


@dataclass(frozen=True)
class WarningSpan:
    """One warning for a train: on, off (None: still on), why, and what the unit knew when it came on."""

    t_on: int
    t_off: int | None
    reason_on: str
    reason_off: str
    onset: Onset | None
    released: bool  # switched off before the head arrived (the train proven out of reach)


def warnings_of(ctl: CrossingController, train: str) -> list[WarningSpan]:
    """Every warning the controller gave ``train``, in order: its episodes, then the one on now (or the last,
    where nothing closed it as an episode)."""
    tr = ctl.tracks[train]
    ons, eps = tr.onsets, tr.episodes
    released = {(on, off) for on, off, _why in tr.releases}
    out = []
    for i, (on, off, r_on, r_off) in enumerate(eps):
        onset = ons[i] if i < len(ons) else None
        t_on = onset.t_ns if onset is not None else on  # an episode's on may read 0 as unset: its onset's
        out.append(WarningSpan(t_on, off, r_on, r_off, onset, (t_on, off) in released))
    if tr.t_on is not None and (tr.warned or len(eps) < max(len(ons), 1)):
        off = None if tr.warned else tr.t_off
        out.append(WarningSpan(tr.t_on, off, tr.reason_on, tr.reason_off if off is not None else "", tr.onset, False))
    return out


def trips(
    times_ns: np.ndarray, chainage: np.ndarray, target: float, half_m: float, margin_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """A train's passes over the crossing at ``target`` from its (head) fixes, in time order: each pass's
    direction (+1 up, −1 down) and the fix times at which the passes after the first begin.

    A pass is the head going from beyond ``half_m + margin_m`` on one side of the crossing to beyond it
    on the other; a head on the road at the first fix (it left it) or at the last (it came to it) is a
    pass too, and so is a head that turned after the last pass and is coming back when the fixes end
    (a pass without an arrival yet).  A train back and forth passes it trip after trip: the next pass
    begins at the fix where the head came farthest out (within ``margin_m``) between the two, where
    the train turned."""
    if len(chainage) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    # A fix or two that jumped (the controller's filter set them aside, the fixes still hold them) must
    # not make a pass: the head's position is the median of five fixes around each.
    pos = np.median(sliding_window_view(np.pad(chainage, 2, mode="edge"), 5), axis=1) - target
    edge = half_m + margin_m
    side = np.where(pos < -edge, -1, np.where(pos > edge, 1, 0))
    nz = np.flatnonzero(side)
    if len(nz) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    sides = side[nz]
    change = np.flatnonzero(sides[1:] != sides[:-1])
    # Each pass's direction, and the fixes on the side it came from (last) and went to (first).
    dirs = list(sides[change + 1])
    came = list(nz[change])
    went = list(nz[change + 1])
    if nz[0] > 0:  # on the road at the first fix: a pass under way, left to the first side seen
        dirs.insert(0, sides[0])
        came.insert(0, 0)
        went.insert(0, nz[0])
    if nz[-1] < len(pos) - 1:  # on the road at the last fix: a pass begun from the last side seen
        dirs.append(-sides[-1])
        came.append(nz[-1])
        went.append(len(pos) - 1)
    elif dirs:
        # Turned after the last pass and coming back (by more than twice the margin) when the fixes end:
        # an approach of its own (its warning is not the last pass's), still short of the road.
        out = dirs[-1] * pos[went[-1] :]
        far = int(np.argmax(out >= out.max() - margin_m))
        if out[far:].min() < out[far] - 2 * margin_m:
            dirs.append(-dirs[-1])
            came.append(len(pos) - 1)
            went.append(len(pos) - 1)
    starts = []
    for k in range(1, len(dirs)):  # between two passes, the head's farthest out: where the train turned
        lo, hi = went[k - 1], came[k] + 1
        out = dirs[k - 1] * pos[lo:hi]
        starts.append(times_ns[lo + int(np.argmax(out >= out.max() - margin_m))])
    return np.asarray(dirs, dtype=np.int64), np.asarray(starts, dtype=np.int64)


def _arrival(
    ht: np.ndarray, hc: np.ndarray, et: np.ndarray, ec: np.ndarray, d: int, length_m: float, at: float
) -> int | None:
    """The head reaching ``at`` in direction ``d``: from its fixes, else the EOT's plus the length.  The
    train's front, whichever unit leads: an EOT there first (a train backing, pushed) is the arrival."""
    t_head = crossing_time(ht, hc, at, d)
    if t_head is None and len(et):
        return crossing_time(et, ec + d * length_m, at, d)
    t_eot = crossing_time(et, ec, at, d)
    return t_eot if t_head is not None and t_eot is not None and t_eot < t_head else t_head


def timeline(
    ctl: CrossingController,
    fixes: Sequence[Fix],
    settings: ControllerSettings | None = None,
) -> list[TimelineRow]:
    """One row per pass of each train the controller tracked (from its fixes and events); a train
    that has not come to the crossing yet, its warning on, has one row without a head arrival."""
    s = settings or ctl.s
    rows = []
    for train in ctl.tracks:
        aside = {(role, t) for (tn, role), times in ctl.set_aside.items() if tn == train for t in times}
        own = sorted(
            (
                f
                for f in fixes
                if f.train == train and f.valid and not math.isnan(f.chainage_m) and (f.role, f.t_fix_ns) not in aside
            ),
            key=lambda f: f.t_fix_ns,
        )
        rows += _train_rows(ctl, s, train, own)
    return rows


def _train_rows(ctl: CrossingController, s: ControllerSettings, train: str, own: list[Fix]) -> list[TimelineRow]:
    """``train``'s rows: one per pass, each paired with its own warning (the one on when the head arrived)."""
    tr = ctl.tracks[train]
    c, half = ctl.crossing.chainage_m, s.crossing_half_width_m
    alarms = [(e.t_ns, e.reason) for e in ctl.events if e.train == train and e.kind == "alarm"]
    ot = np.array([f.t_fix_ns for f in own], dtype=np.int64)
    heads = [f for f in own if f.role == HEAD]
    eots = [f for f in own if f.role == EOT]
    ht = np.array([f.t_fix_ns for f in heads], dtype=np.int64)
    hc = np.array([f.chainage_m for f in heads])
    et = np.array([f.t_fix_ns for f in eots], dtype=np.int64)
    ec = np.array([f.chainage_m for f in eots])
    dirs, starts = trips(ht, hc, c, half, s.noise_m) if len(ht) else trips(et, ec, c, half, s.noise_m)
    if len(dirs) == 0:  # not past the crossing (yet): the train's last warning, all its fixes
        t_off = tr.t_off if not tr.warned else None
        w = WarningSpan(tr.t_on, t_off, tr.reason_on, tr.reason_off, tr.onset, False) if tr.t_on is not None else None
        t_head = _arrival(ht, hc, et, ec, tr.direction, tr.spec.length_m, c - tr.direction * half)
        row = _row(ctl, s, tr.spec, own, heads, eots, tr.direction, t_head, w, len(tr.releases), alarms)
        return [row] if row is not None else []
    # Trip after trip: each pass's fixes from where the train turned before it to where it turns after.
    bounds = np.concatenate(([np.iinfo(np.int64).min], starts, [np.iinfo(np.int64).max]))
    wins = [(bounds[k], bounds[k + 1]) for k in range(len(dirs))]
    hi_, ei_, oi_ = (np.searchsorted(a, bounds) for a in (ht, et, ot))
    arrivals = [
        _arrival(
            ht[hi_[k] : hi_[k + 1]],
            hc[hi_[k] : hi_[k + 1]],
            et[ei_[k] : ei_[k + 1]],
            ec[ei_[k] : ei_[k + 1]],
            int(d),
            tr.spec.length_m,
            c - int(d) * half,
        )
        for k, d in enumerate(dirs)
    ]
    ws = warnings_of(ctl, train)
    paired = _pair(ws, arrivals)
    # A warning still on at the end for a train that has not come to the crossing again (yet): the row of
    # the approach it turned for (the last pass, without an arrival), else a row of its own.
    taken = max((j for j in paired if j is not None), default=-1)
    held = [j for j in range(taken + 1, len(ws)) if ws[j].t_off is None]
    if held and arrivals[-1] is None:
        paired[-1] = held.pop(0)
    came = [a for a in arrivals if a is not None]
    held_from = ws[held[0]].t_on if held else np.iinfo(np.int64).max  # its alarms are its own row's
    trailing = (paired[-1] is not None and arrivals[-1] is None) or bool(held)

    def released(after: int | None, upto: int | None) -> int:
        """Warnings released (a train proven out of reach) that came on in (after, upto]."""
        return sum(
            1 for w in ws if w.released and (after is None or w.t_on > after) and (upto is None or w.t_on <= upto)
        )

    rows = []
    for k, d in enumerate(dirs):
        t_head = arrivals[k]
        prev = max((a for a in arrivals[:k] if a is not None), default=None)
        # Those after the last arrival count on the last pass's row, unless a warning still on has its own.
        upto = None if t_head is None or (t_head == came[-1] and not trailing) else t_head
        lo, hi = wins[k]
        j = paired[k]
        row = _row(
            ctl,
            s,
            tr.spec,
            own[oi_[k] : oi_[k + 1]],
            heads[hi_[k] : hi_[k + 1]],
            eots[ei_[k] : ei_[k + 1]],
            int(d),
            t_head,
            None if j is None else ws[j],
            released(prev, upto),
            [(t, why) for t, why in alarms if lo <= t < min(hi, held_from)],
        )
        if row is not None:
            rows.append(row)
    for j in held:
        w = ws[j]
        after = [(t, why) for t, why in alarms if t >= w.t_on]
        row = _row(
            ctl, s, tr.spec, [], [], [], tr.direction, None, w, released(came[-1] if came else None, None), after
        )
        if row is not None:
            rows.append(row)
    return rows


def _pair(ws: list[WarningSpan], arrivals: list[int | None]) -> list[int | None]:
    """Each pass's warning (index into ``ws``): the one on when its head arrived (the last that came on
    at or before; a warning on through two passes is both's).  Without one, the first that came on
    after the arrival and before the next pass's, not released (a late warning); else the last that
    came on before, after the previous pass's (off before the head arrived: reported so)."""
    ons = np.array([w.t_on for w in ws], dtype=np.int64)
    out: list[int | None] = []
    prev = -1
    for k, th in enumerate(arrivals):
        got: int | None = None
        if th is not None:
            j = int(np.searchsorted(ons, th, side="right")) - 1
            off = ws[j].t_off if j >= 0 else None
            nxt = next((a for a in arrivals[k + 1 :] if a is not None), None)
            if j >= 0 and (off is None or off >= th):
                got = j
            else:
                late = (i for i in range(max(j, prev) + 1, len(ws)) if not ws[i].released)
                got = next((i for i in late if nxt is None or ws[i].t_on < nxt), j if j > prev else None)
            prev = prev if got is None else got
        out.append(got)
    return out


def _row(
    ctl: CrossingController,
    s: ControllerSettings,
    spec: TrainSpec,
    own: Sequence[Fix],
    heads: Sequence[Fix],
    eots: Sequence[Fix],
    d: int,
    t_head: int | None,
    w: WarningSpan | None,
    released: int,
    alarms: Sequence[tuple[int, str]],
) -> TimelineRow | None:
    """One pass's row from its fixes (``own``, in time order), its head arrival and its warning."""
    c = ctl.crossing.chainage_m
    half = s.crossing_half_width_m
    wt = ctl.crossing.warning_time_s
    ht = np.array([f.t_fix_ns for f in heads], dtype=np.int64)
    hc = np.array([f.chainage_m for f in heads])
    et = np.array([f.t_fix_ns for f in eots], dtype=np.int64)
    ec = np.array([f.chainage_m for f in eots])
    t_tail = crossing_time(et, ec, c + d * half, d)
    t_rear = crossing_time(ht, hc, c + d * half, d) if t_tail is not None else None
    if t_rear is not None and t_tail is not None and t_rear > t_tail:  # the head unit trails: the EOT leads
        t_tail = t_rear
    t_on, t_off = (None, None) if w is None else (w.t_on, w.t_off)
    if t_on is None and t_head is None:
        return None  # this train never came near the crossing
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
        base_off = t_head + int((spec.length_m / max(v, 0.1) + s.baseline_margin_s) * NS)
        if t_tail is not None:
            base_early = max(0.0, (t_tail - base_off) / NS)
            base_excess = (base_off - t_tail) / NS
    lead = None if t_on is None or t_head is None else (t_head - t_on) / NS
    spare = None
    if lead is not None and t_head is not None and lead >= 0:
        motion = head_motion(
            [(f.t_fix_ns, f.role, f.chainage_m, f.speed_mps) for f in own if f.t_fix_ns <= t_head],
            d,
            spec.length_m,
            c,
            half,
            s.noise_m / 3.0,
            s.speed_sigma_mps,
            s.jerk_psd,
        )
        doubt = w.onset.doubt_s if w is not None and w.onset is not None else {}
        spare = split_spare(lead, wt, t_head, motion, doubt, s.guard_distance_m, s.accel_mps2, s.line_speed_mps)
    return TimelineRow(
        crossing=ctl.crossing.code,
        train=spec.train,
        t_on_ns=t_on,
        t_head_arrival_ns=t_head,
        t_tail_clear_ns=t_tail,
        t_off_ns=t_off,
        lead_s=None if t_on is None or t_head is None else (t_head - t_on) / NS,
        excess_s=None if t_off is None or t_tail is None else (t_off - t_tail) / NS,
        reason_on=w.reason_on if w is not None else "",
        reason_off=w.reason_off
        if w is not None and t_off is not None
        else "held on: no positive evidence the tail has passed",
        alarms=tuple(why for _t, why in alarms),
        violations=tuple(violations),
        baseline_off_ns=base_off,
        baseline_early_s=base_early,
        baseline_excess_s=base_excess,
        warning_time_s=wt,
        late_by_s=late_by if late_by is not None and late_by > 0 else None,
        late_cause=late_cause,
        spare=spare,
        released=released,
    )
