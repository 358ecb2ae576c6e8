"""A warning released before the head arrives (:func:`check_release`).

**Release** (per train, at a fix while the head unit is fresh, before the head arrives): a warning
that came on early (a first fix without speed counts as the fastest train;
a train then stops out of reach) goes off when a settled estimate of a
fresh head unit proves the head cannot arrive within the warning time for a
while yet (``release_hold_s`` at least, and until the next fix is due: it
does not come on again before a new fix could renew the bound, no flicker), with no
jump set aside lately and no head-unit alarm: a train proven standing 2 km
out does not hold the road closed.  It comes on again by the same rule as any warning: from a
standstill the head cannot arrive sooner than √(2d/a).
"""

from __future__ import annotations

from console.analysis.crossing.arrival import Motion
from console.analysis.crossing.bounds import source_bound
from console.analysis.crossing.tail import eot_leads
from console.analysis.crossing.track import Track, fresh
from console.analysis.crossing.values import EOT, HEAD, TRAIN, ControllerSettings, Fix
from parsers.units import NS


def check_release(tr: Track, s: ControllerSettings, motion: Motion, horizon_s: float, fix: Fix) -> str | None:
    """Off before the head arrives, at a fix of either unit while the head unit is fresh, when a
    settled estimate proves the train cannot arrive for a while yet (a train standing out of
    reach, or slower than first feared).  An EOT fix counts only through the train's filter,
    where it is a witness of the head (at fixes every 10 s it comes between two head fixes).
    Released, the track's warning is ended and the reason returned; None: it stays on."""
    # A stale EOT does not hold a release back: whatever it would show is behind the head.
    # Direction unknown, the bound is the nearer way round (it holds whichever way the train goes).
    if not tr.warned or "head" in tr.alarms or not tr.kf_ok[HEAD] or not fresh(tr.head, fix.t_ns, s):
        return None
    if eot_leads(tr, s):
        # The head unit trails: its bound is not the front's, and a release by it came on again at the
        # next EOT fix (a pushed 300 m train: 22 times off and on, a second apart).
        return None
    # The head's own filter settled too: a bound that leans on the train's filter alone, just
    # after the head's track was in doubt (a brake, a jump), came on again within seconds.
    head_est = tr.kf[HEAD].estimate
    if head_est is None or not head_est.settled:
        return None
    b = source_bound(tr, s, motion, TRAIN) if tr.parted_ns is None else None
    if fix.role != HEAD:
        # An EOT fix renews the bound only as the train filter's witness of the head, and only
        # while the head reports on time: a head unit silent since would go stale, and the
        # EOT-plus-length bound that then counts can come due at once.
        assert tr.head is not None
        head_age_s = (fix.t_ns - tr.head.t_fix_ns) / NS
        if b is None or not b.settled or not tr.kf_ok[fix.role] or head_age_s > s.report_period_s + s.latency_s:
            return None
    if b is None or not b.settled:
        b = source_bound(tr, s, motion, HEAD)
    if b is None or not b.settled or b.ahead_m <= s.guard_distance_m:
        return None
    clean_s = max(s.speed_window_s, 3 * s.report_period_s)
    for role in (HEAD, EOT):
        last_doubt = tr.doubt_ns[role]
        if last_doubt is not None and fix.t_fix_ns - last_doubt < clean_s * NS:
            return None  # a jump set aside lately is doubt
    if tr.head_ev.rejected_since_last or tr.eot_ev.rejected_since_last:
        return None
    eta = (b.t_arrival_ns - fix.t_ns) / NS
    # The next fix of either unit is due one report period after its last, plus the latency:
    # until then nothing can renew the bound, so it must not come due before that.
    fresh_fix_ns = [r.t_fix_ns for r in (tr.head, tr.eot) if r is not None and fresh(r, fix.t_ns, s)]
    next_fix_s = (min(fresh_fix_ns) - fix.t_ns) / NS + s.report_period_s + s.latency_s
    # Released, the road stays open for release_hold_s at least by this bound, and until the
    # next fix is in (no flicker); a later fix can only push the bound out for a train as seen.
    if eta <= horizon_s + max(next_fix_s, s.release_hold_s):
        return None
    what = "train standing" if b.standing else f"head at most {b.speed_hi_mps:.1f} m/s"
    reason = f"released: {what} {b.ahead_m:.0f} m out cannot arrive within {eta:.0f} s"
    assert tr.t_on is not None
    tr.releases.append((tr.t_on, fix.t_ns, reason))
    tr.episodes.append((tr.t_on, fix.t_ns, tr.reason_on, reason))
    tr.warned, tr.t_off, tr.reason_off = False, fix.t_ns, reason
    return reason
