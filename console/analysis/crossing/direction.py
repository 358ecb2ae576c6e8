"""A train's direction of travel, from the witnesses one wild fix cannot fake (:func:`update_direction`)."""

from __future__ import annotations

from console.analysis.crossing.track import Track
from console.analysis.crossing.values import EOT, HEAD, Fix


def update_direction(tr: Track, fix: Fix) -> None:
    """Direction of travel from evidence one wild fix cannot fake; kept when there is none.

    The witnesses, each +1, −1 or silent:

    * the fix's course against the track's bearing (a receiver's course over ground at
      speed: a measurement of the direction, it counts twice);
    * each device's filter, settled, its speed clear of zero by k·σ and 2 m/s (its gate
      sets jumps aside; the model overshoots a little below zero when a train stops dead);
    * each device's own fixes: the median of the three oldest in the window against the
      median of the three newest.

    An unknown direction is set by any witness no other contradicts; a known one is
    reversed by two that agree with none against.  Witnesses that disagree make the
    direction unknown: a wrong direction reads a train approaching as one whose tail is
    past the crossing (ignored, or its warning ended), an unknown one is treated as
    approaching from the nearer side.  A direction left unknown so is set against the last
    one known only as a reversal is (two witnesses): else one witness, after another had
    disagreed, reversed it.  A standing train gives none but its devices' medians, which
    position jumps its filter took can tilt; reversed so, its EOT standing before the
    crossing read as past it, and its warning ended (found on a randomized run: the road
    opened for a train standing 560 m out, and closed 26 s late when it moved on).  Two fixes
    alone, or the head ahead of the EOT, are no witness: fixes some seconds apart on a fast
    train put the EOT ahead of an older head fix.
    """
    votes = [fix.direction_hint, fix.direction_hint] if fix.direction_hint else []
    for role, ev in ((HEAD, tr.head_ev), (EOT, tr.eot_ev)):
        est = tr.kf[role].estimate
        if est is not None and est.settled and abs(est.speed_mps) > est.k_sigma * est.sigma_speed_mps + 2.0:
            votes.append(1 if est.speed_mps > 0 else -1)
        if moved := ev.direction(medians_only=True):
            votes.append(moved)
    up, down = votes.count(1), votes.count(-1)
    before = tr.direction
    if up and down:
        tr.direction = 0
    elif up or down:
        d, w = (1, up) if up else (-1, down)
        against = before or tr.known_direction  # the direction this would reverse, if any
        if not against or d == against or w >= 2:
            tr.direction = d
    if tr.direction != before:
        tr.direction_set_ns = fix.t_fix_ns
    if tr.direction:
        tr.known_direction = tr.direction
