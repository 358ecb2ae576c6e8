"""The GNSS witness over a train's run of EOT fixes: its direction, each EOT fix judged against the
head fixes on each side (:mod:`console.analysis.integrity.gnss`), the length learnt where it was only
guessed, and the witness's opinion from the latest judged fixes in a row (:func:`gnss_opinion`).
"""

from __future__ import annotations

import math
import statistics
from bisect import bisect_left

from console.analysis.integrity.counts import NONE, Opinion
from console.analysis.integrity.gnss import (
    BEHIND,
    CONSISTENT,
    INCONSISTENT,
    SLOWER,
    STRONG,
    GnssLimits,
    Point,
    head_bounds,
    judge_eot,
)
from console.analysis.integrity.state import LEARN_SAMPLES, Judged, Train
from console.analysis.integrity.values import GNSS, PARTED, SEPARATION


def set_direction(tr: Train) -> None:
    # The head unit's movement says it; the EOT's only while nothing else has (a rear part
    # falling behind must not turn the train round).
    d = tr.head.ev.direction() or (0 if tr.direction else tr.eot.ev.direction())
    if d and d != tr.direction:
        if tr.direction:
            tr.checks.clear()  # the train reversed: the counts so far were another run
        tr.direction = d
        for j in tr.judged:
            j.verdict = None


def judge_fixes(tr: Train, lim: GnssLimits) -> None:
    """Judge the EOT fixes not yet judged against a head fix on each side."""
    d = tr.direction
    if not d or tr.head.ev.rejected_since_last:
        # No direction yet, or the head unit's last fix was set aside as a jump: its track is
        # in doubt until a fix agrees with it again (or it starts over).
        tr.gnss = gnss_opinion(tr, lim)
        return
    for j in tr.judged:
        if j.verdict is not None and j.verdict.bracketed:
            continue
        around = tr.head.around(j.t_fix_ns, d)
        hb = head_bounds(around, j.t_fix_ns, lim)
        if hb is None:
            continue
        if hb.bracketed:
            k = bisect_left([p.t_fix_ns for p in around], j.t_fix_ns)
            j.bracket = (around[max(0, k - 1)].t_fix_ns, around[min(k, len(around) - 1)].t_fix_ns)
        eot = Point(j.t_fix_ns, d * j.s_m, j.speed_mps, j.speed_hi_mps)
        j.verdict = judge_eot(eot, hb, tr.length_m, lim)
        if tr.length_m is None and hb.bracketed and j.verdict.kind == CONSISTENT:
            learn_length(tr, 0.5 * (hb.lo_m + hb.hi_m) - eot.s_m)
    tr.gnss = gnss_opinion(tr, lim)


def learn_length(tr: Train, separation_m: float) -> None:
    """A head–EOT distance measured while both ran at one speed: the median of the first few
    is the train's length (then every EOT fix is judged again by it)."""
    tr.samples.append(separation_m)
    if len(tr.samples) >= LEARN_SAMPLES:
        tr.length_m = max(0.0, statistics.median(tr.samples))
        for j in tr.judged:
            j.verdict = None


def gnss_opinion(tr: Train, lim: GnssLimits) -> Opinion:
    # The run of consecutive judged EOT fixes up to the latest judged one.
    run: list[Judged] = []
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
    if prev is not None and standing_rear(run[-2], last, lim):
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


def standing_rear(a: Judged, b: Judged, lim: GnssLimits) -> bool:
    """Two fixes in a row behind, the EOT standing at both (its Doppler speed nil, its place the
    same) while the gap to the head grew by more than the noise: a rear part left standing.

    A displaced fix keeps its Doppler speed, so a moving train's jumps never read as standing;
    a whole train standing does not open the gap."""
    va, vb = a.verdict, b.verdict
    if va is None or vb is None or va.kind != BEHIND or vb.kind != BEHIND or not (va.bracketed and vb.bracketed):
        return False
    still = lim.speed_allow_mps
    if math.isnan(a.speed_mps) or math.isnan(b.speed_mps) or max(a.speed_mps, b.speed_mps) > still:
        return False
    noise = 2 * lim.pos_allow_m
    return abs(b.s_m - a.s_m) <= noise and vb.lag_m - va.lag_m > noise
