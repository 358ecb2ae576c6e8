"""The verdict on a train from its witnesses' opinions: a unit gone stale (:func:`stale_opinion`), both
units silent (:func:`silent`), and the fusion of the GNSS, brake-pipe and counters' opinions into a
state with its evidence (:func:`fuse`).
"""

from __future__ import annotations

from console.analysis.integrity.counts import NONE, Opinion
from console.analysis.integrity.state import Train
from console.analysis.integrity.values import DOUBTFUL, GNSS, PARTED, WHOLE, IntegritySettings
from parsers.units import NS


def stale_opinion(tr: Train, now: int, s: IntegritySettings) -> Opinion:
    stale = s.stale_s * NS
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


def silent(tr: Train, now: int, s: IntegritySettings) -> bool:
    stale = s.stale_s * NS
    last = [u.last_fix_ns for u in (tr.head, tr.eot) if u.last_fix_ns is not None]
    return bool(last) and now - max(last) > stale


def fuse(tr: Train, now: int, s: IntegritySettings) -> tuple[str | None, Opinion]:
    g, c, b = tr.gnss, tr.counters, tr.brake_opinion
    stale = stale_opinion(tr, now, s)
    if silent(tr, now, s):
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
