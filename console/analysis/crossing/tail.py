"""Where a train's tail is, and the warning going off when it is past the crossing: functions of the
train's :class:`~console.analysis.crossing.track.Track`, the crossing and the unit's settings.

**Off** (per train): on positive evidence only: two consecutive accepted
EOT fixes past the crossing by ``d_off`` in the direction of travel, the
second consistent with the first (it moved forward, by no more than the
train could have run), with no fix set aside as a jump between them and
the device's track not just restarted: one wild fix, plausible-looking or
not, cannot open the road.  This is the paper's "d ≤ d_off, then
increasing" in signed form: past the crossing by the margin and moving
away, which a standing EOT is not unless it was seen short of the
crossing first (it crossed): read in a wrong direction, a standing EOT
before the crossing is "past" it.  The same evidence, latched, is what
puts the tail past (no more warnings for the train); one EOT fix never
is.  A train with its EOT end leading (backing, pushed: the EOT ahead of
the head unit) has its rear a train's length behind the EOT: past by
``d_off`` plus the length.
"""

from __future__ import annotations

from console.analysis.crossing.evidence import REPORTED, Report
from console.analysis.crossing.track import Track
from console.analysis.crossing.values import EOT, ControllerSettings, Fix
from console.layout import LevelCrossing
from parsers.units import NS


def past_m(tr: Track, crossing: LevelCrossing, chainage_m: float) -> float:
    """How far past the crossing a chainage is in the train's direction of travel (m; < 0 short of it)."""
    return tr.direction * (chainage_m - crossing.chainage_m)


def past_margin(tr: Track, crossing: LevelCrossing, s: ControllerSettings, eot_chainage_m: float) -> bool:
    """An EOT position past the crossing by the margin its tail needs (:func:`eot_off_m`)."""
    return past_m(tr, crossing, eot_chainage_m) >= eot_off_m(tr, crossing, s)


def eot_leads(tr: Track, s: ControllerSettings) -> bool:
    """The EOT unit ahead of the head unit in the direction of travel, by more than the head can have
    run between their last fixes (and the noise): a train backing, or pushed.  Its rear is then the
    head unit's end, a train's length behind the EOT."""
    eot = tr.eot_kept or tr.eot
    if eot is None or tr.head is None or not tr.direction:
        return False
    reach = tr.head.speed_hi_mps * abs(eot.t_fix_ns - tr.head.t_fix_ns) / NS + 2 * s.noise_m
    return tr.direction * (eot.chainage_m - tr.head.chainage_m) > reach


def eot_off_m(tr: Track, crossing: LevelCrossing, s: ControllerSettings) -> float:
    """How far past the crossing the EOT must be for the tail to be past by d_off: the train's length
    more when the EOT leads (it was d_off alone, and a pushed train's rear was still on the road)."""
    return crossing.d_off_m + (tr.spec.length_m if eot_leads(tr, s) else 0.0)


def tail_past(tr: Track, crossing: LevelCrossing, s: ControllerSettings) -> bool:
    """The tail is past the crossing by d_off in the direction of travel: proven by the off rule's
    evidence (two EOT fixes past, moving away) and no EOT fix the filter took since short of it (one
    fix that jumped back does not put the tail on the road again).  One EOT fix is no proof: a first
    fix that jumped past the crossing (the device's next, true, fix then set aside against it, the
    device silent after) kept a train approaching from ever being warned."""
    if not tr.direction:
        return False
    if tr.eot is not None:
        return tr.tail_past_dir == tr.direction
    if tr.head is None or tr.head.speed_basis != REPORTED:
        return False
    # No EOT at all: only the head's own position (moved on by a reported speed) can tell.
    head_past_m = tr.direction * (tr.head.chainage_m - crossing.chainage_m)
    return head_past_m > tr.spec.length_m + crossing.d_off_m + 2 * s.noise_m


def tail_past_evidence(
    tr: Track, crossing: LevelCrossing, s: ControllerSettings, fix: Fix, prev_eot: Report | None, rep: Report
) -> float | None:
    """How far past the crossing an EOT fix proves the tail (m), with the one before it; None when it
    proves nothing: the two past by the margin in a known direction, consistent, and moving away."""
    if fix.role != EOT or tr.direction == 0:
        return None
    if not past_margin(tr, crossing, s, fix.chainage_m):
        return None
    if prev_eot is None or rep.restarted or tr.direction_set_ns >= prev_eot.t_fix_ns:
        # A first EOT fix alone is not evidence, nor a pair read in a direction that has
        # just changed: wait for the next.
        return None
    if not past_margin(tr, crossing, s, prev_eot.chainage_m):
        return None  # one fix past could be a jump: two in a row are evidence
    dt = (fix.t_fix_ns - prev_eot.t_fix_ns) / NS
    step = tr.direction * (fix.chainage_m - prev_eot.chainage_m)
    if dt <= 0 or step < -s.noise_m or step > s.max_speed_mps * dt + s.noise_m:
        return None  # not consistent with the previous fix: not evidence
    if not moving_away(tr, s, step):
        return None
    return past_m(tr, crossing, fix.chainage_m)


def moving_away(tr: Track, s: ControllerSettings, step_m: float) -> bool:
    """The EOT moves in the direction of travel, beyond its noise (the paper's "distance increasing"),
    or it was seen short of the crossing in this direction and is past it now: it crossed.  A standing
    EOT never seen on the near side is no evidence: read in a wrong direction (turned round by position
    jumps), a train standing before the crossing, or with its tail on the road, was "past it and moving
    away" (randomized runs: the road opened with the train standing on it).  A train that crossed and
    stands beyond (a station past the crossing) is past."""
    if tr.direction and tr.eot_short_dir == tr.direction:
        return True
    if step_m > 2 * s.noise_m:
        return True
    if tr.eot_ev.direction(medians_only=True) == tr.direction:
        return True
    est = tr.kf[EOT].estimate
    return (
        est is not None
        and est.settled
        and tr.kf_ok[EOT]
        and tr.direction * est.speed_mps > est.k_sigma * est.sigma_speed_mps + 2.0
    )


def note_tail(
    tr: Track, crossing: LevelCrossing, s: ControllerSettings, fix: Fix, prev_eot: Report | None, rep: Report
) -> float | None:
    """After an accepted fix: the tail proven past (→ how far, latched), or no longer (an EOT fix the
    filter took, short of the margin)."""
    if fix.role == EOT and tr.kf_ok[EOT] and past_m(tr, crossing, fix.chainage_m) < 0:
        tr.eot_short_dir = tr.direction
    past = tail_past_evidence(tr, crossing, s, fix, prev_eot, rep)
    if past is not None:
        tr.tail_past_dir = tr.direction
    elif fix.role == EOT and tr.kf_ok[EOT] and not past_margin(tr, crossing, s, fix.chainage_m):
        tr.tail_past_dir = 0
    return past


def cleared(tr: Track, crossing: LevelCrossing, s: ControllerSettings) -> bool:
    """The whole train is past this crossing and its warning is off: its head
    unit no longer matters here (a head running off the mapped line at the
    end of the run is not worth an alarm at a crossing it left behind)."""
    if tr.warned or tr.eot is None or not tr.direction:
        return False
    return past_margin(tr, crossing, s, tr.eot.chainage_m)


def check_off(tr: Track, crossing: LevelCrossing, s: ControllerSettings, past: float | None, fix: Fix) -> str | None:
    """The warning off on the tail's evidence (``past``, from :func:`note_tail`): the track's warning ended,
    the reason returned (None: no warning on, or no evidence)."""
    if not tr.warned or past is None:
        return None
    need = eot_off_m(tr, crossing, s)
    tr.warned, tr.t_off = False, fix.t_ns
    leads = " (the EOT leading: the head unit's end a train's length behind)" if need > crossing.d_off_m else ""
    tr.reason_off = f"EOT {past:.0f} m past the crossing and moving away{leads}"
    tr.episodes.append((tr.t_on or fix.t_ns, fix.t_ns, tr.reason_on, tr.reason_off))
    return tr.reason_off
