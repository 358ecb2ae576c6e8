"""The GNSS witness of train integrity: does the EOT unit ride where a whole train puts it?

A whole train's EOT unit is, at every instant, a train length behind the
head (along the track, in the direction of travel) and runs at the head's
speed.  A parted train's rear part, braking to a stop as its parted brake
pipe makes it, falls behind and slows.  The head and the EOT report at
their own times, so the head is placed at the EOT fix's time by bounds,
not by a guess:

* from each head fix before it, moved on at its reported speed: the head
  can be no further than ``(v + e_v)·Δ + A·Δ²/2`` on, nor nearer than
  ``(v − e_v)·Δ − A·Δ²/2`` (``A`` the most any train changes speed by,
  braking included; ``e_v`` the speed allowance);
* from each head fix after it (when it has arrived), moved back likewise;
* all of them intersected, each widened by its fix's noise allowance
  ``k·σ``, so one displaced fix moves the bounds no further than the others
  allow (or empties them: no verdict); a fix without speed bounds the head
  only by the speed its device's positions prove
  (:mod:`console.analysis.crossing.evidence`).

The units' clocks may disagree by up to ``2·clock_offset``: the head's
time is widened by that much (its speed bound times it, and ``A`` times it
for the speed).

One EOT fix then gives, each beyond every allowance:

* ``lag_m``: how far behind the rearmost position a whole train allows;
* ``deficit_mps``: how much slower than the slowest head speed allowed
  (the EOT's own positions raise a frozen ``0.0`` to what they prove);
* ``ahead_m`` and ``excess_mps``: the other way round, which no parting
  explains (wrong length, swapped units): doubt, never parted.

:class:`Verdict` names the fix: ``strong`` (behind *and* slower: a rear
part falling behind; a position jump moves a fix but not its Doppler
speed, so the two together are no jump), ``slower``, ``behind``,
``inconsistent`` or ``consistent``.  The monitor
(:mod:`console.analysis.integrity.monitor`) turns sequences of them into states
(:mod:`console.analysis.integrity.gnss_run`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from parsers.units import NS

CONSISTENT, BEHIND, SLOWER, STRONG, INCONSISTENT = "consistent", "behind", "slower", "strong", "inconsistent"


@dataclass(frozen=True)
class GnssLimits:
    noise_m: float  # σ of a fix's position along the track
    speed_noise_mps: float  # σ of a reported (Doppler) speed
    k_sigma: float  # allowances are this many σ
    max_accel_mps2: float  # no train changes speed faster (emergency braking included)
    max_speed_mps: float
    clock_offset_s: float  # each unit's clock may be this far from the true time
    coupling_slack_m: float  # EOT mount beyond the last wheel, couplers' play

    @property
    def pos_allow_m(self) -> float:
        return self.k_sigma * self.noise_m

    @property
    def speed_allow_mps(self) -> float:
        return self.k_sigma * self.speed_noise_mps


@dataclass(frozen=True)
class Point:
    """One accepted fix of a unit, in the train's direction of travel (``s`` = direction × chainage)."""

    t_fix_ns: int
    s_m: float
    speed_mps: float  # NaN: not reported
    speed_hi_mps: float  # the fastest the unit can be running (its own positions' bound)


@dataclass(frozen=True)
class HeadBounds:
    lo_m: float
    hi_m: float
    v_lo_mps: float
    v_hi_mps: float
    bracketed: bool  # a head fix on each side of the time


def _from_fix(p: Point, dt_s: float, lim: GnssLimits) -> tuple[float, float, float, float]:
    """(lo, hi, v_lo, v_hi) of the head ``dt_s`` after (> 0) or before (< 0) fix ``p``."""
    a, ev, n = lim.max_accel_mps2, lim.speed_allow_mps, lim.pos_allow_m
    span = abs(dt_s)
    if math.isnan(p.speed_mps):
        v_lo, v_hi = 0.0, min(p.speed_hi_mps, lim.max_speed_mps)
    else:
        v_lo, v_hi = max(0.0, p.speed_mps - ev), p.speed_mps + ev
    turn = 0.5 * a * span * span
    if dt_s >= 0:
        lo = p.s_m + max(0.0, v_lo * span - turn)  # a train does not back up
        hi = p.s_m + min(v_hi * span + turn, lim.max_speed_mps * span)
    else:
        lo = p.s_m - min(v_hi * span + turn, lim.max_speed_mps * span)
        hi = p.s_m - max(0.0, v_lo * span - turn)
    return lo - n, hi + n, max(0.0, v_lo - a * span), min(v_hi + a * span, lim.max_speed_mps)


def head_bounds(points: Sequence[Point], t_ns: int, lim: GnssLimits) -> HeadBounds | None:
    """Where the head can be at ``t_ns`` (the EOT unit's clock), from the head fixes around it
    (a few on each side: each bounds the head; the bounds are intersected).

    None without a head fix, or when the fixes contradict each other (one of them jumped): a
    displaced fix cannot move the bounds beyond what the others allow."""
    if not points:
        return None
    lo, hi, v_lo, v_hi = -math.inf, math.inf, 0.0, math.inf
    before = after = False
    for p in points:
        dt_s = (t_ns - p.t_fix_ns) / NS
        before |= dt_s >= 0
        after |= dt_s <= 0
        a, b, c, d = _from_fix(p, dt_s, lim)
        lo, hi, v_lo, v_hi = max(lo, a), min(hi, b), max(v_lo, c), min(v_hi, d)
    if lo > hi or v_lo > v_hi:
        return None
    # The two units' clocks: the EOT's time may be up to twice the offset off the head's.
    skew = 2 * lim.clock_offset_s
    lo -= v_hi * skew
    hi += v_hi * skew
    v_lo = max(0.0, v_lo - lim.max_accel_mps2 * skew)
    v_hi += lim.max_accel_mps2 * skew
    return HeadBounds(lo, hi, v_lo, v_hi, before and after)


@dataclass(frozen=True)
class Verdict:
    kind: str  # consistent | behind | slower | strong | inconsistent
    lag_m: float  # > 0: behind the rearmost place a whole train allows, by this much
    deficit_mps: float  # > 0: slower than the slowest head speed allowed, by this much (NaN: no speed)
    ahead_m: float
    excess_mps: float
    bracketed: bool
    head_moving: bool  # the head surely runs faster than the speed allowance: a standing EOT shows

    def describe(self, length_m: float | None) -> str:
        train = "train" if length_m is None else f"{length_m:.0f} m train"
        if self.kind == STRONG:
            return f"EOT {self.lag_m:.0f} m behind and {self.deficit_mps:.1f} m/s slower than a whole {train} allows"
        if self.kind == BEHIND:
            return f"EOT {self.lag_m:.0f} m behind where a whole {train} puts it"
        if self.kind == SLOWER:
            return f"EOT {self.deficit_mps:.1f} m/s slower than the head allows"
        if self.kind == INCONSISTENT:
            if self.ahead_m > 0:
                return f"EOT {self.ahead_m:.0f} m ahead of where a {train} puts it"
            if self.excess_mps > 0:
                return f"EOT {self.excess_mps:.1f} m/s faster than the head allows"
            return f"EOT {self.lag_m:.0f} m behind, yet running at the head's speed (a position jump?)"
        if length_m is None:
            return "EOT running at the head's speed (the train's length still being learnt)"
        return f"EOT where a whole {train} puts it"


def judge_eot(eot: Point, head: HeadBounds, length_m: float | None, lim: GnssLimits) -> Verdict:
    """One EOT fix against the head's bounds at its time (``length_m`` None: by its speed only)."""
    n = lim.pos_allow_m + lim.coupling_slack_m
    if length_m is None:
        lag = ahead = math.nan
    else:
        lag = (head.lo_m - length_m - n) - eot.s_m
        ahead = eot.s_m - (head.hi_m - length_m + n)
    ev = lim.speed_allow_mps
    if math.isnan(eot.speed_mps):
        deficit = excess = math.nan
    else:
        # The EOT's own positions raise a speed that is too low (a frozen 0.0) to what they prove.
        v_e_hi = max(eot.speed_mps + ev, eot.speed_hi_mps)
        deficit = head.v_lo_mps - v_e_hi
        excess = (eot.speed_mps - ev) - head.v_hi_mps
    moving = head.v_lo_mps > 2 * ev
    behind, slower = lag > 0, deficit > 0
    if behind and slower:
        kind = STRONG
    elif slower:
        kind = SLOWER
    elif behind:
        # Behind, yet at the head's speed while the head surely runs: a rear part that fell
        # behind would be slower too; a fix displaced along the track keeps its Doppler speed.
        kind = INCONSISTENT if moving and not math.isnan(deficit) else BEHIND
    elif ahead > 0 or excess > 0:
        kind = INCONSISTENT
    else:
        kind = CONSISTENT
    return Verdict(kind, lag, deficit, ahead, excess, head.bracketed, moving)
