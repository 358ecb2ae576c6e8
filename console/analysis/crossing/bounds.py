"""The head's earliest arrival as the crossing unit bounds it: the speed cap from the model-free evidence
(reported speeds, the fixes, the EOT as a second witness), each source's bound (head, EOT + length, the
train's filter), the one that counts now, and, when a warning comes on, what each doubt cost."""

from __future__ import annotations

import math

from console.analysis.crossing.arrival import ArrivalBound, Motion, device_bound
from console.analysis.crossing.evidence import ESTIMATED, REPORTED
from console.analysis.crossing.track import Track, fresh
from console.analysis.crossing.values import (
    EOT,
    HEAD,
    JUMPS,
    NO_SPEED,
    SPARSE,
    STALE,
    TRAIN,
    ControllerSettings,
    Onset,
)
from parsers.units import NS

# The basis of a bound from the EOT and the length, nearer than the fresh head unit's own while
# the train's filter (head and EOT together) is not settled.
EOT_WITNESS = "eot+length (head unsettled)"


def speed_cap_mps(tr: Track, s: ControllerSettings, t_ns: int) -> float:
    """The fastest the train may be running at ``t_ns`` (m/s) by the model-free bounds: reported
    speeds where the devices give them, else the tightest bound the positions prove; unknown is
    the worst case.  Per device the largest of its last few fixes' bounds, each moved on to
    ``t_ns`` (it may have accelerated since): one fix that jumped back and seemed to prove a
    slow train cannot lower it."""
    per_device = []
    for role, r in ((HEAD, tr.head), (EOT, tr.eot)):
        if r is None or not (fresh(r, t_ns, s) or not any(fresh(q, t_ns, s) for q in (tr.head, tr.eot))):
            continue
        hi = max(q.speed_hi_mps + s.accel_mps2 * max(0.0, (t_ns - q.t_fix_ns) / NS) for q in tr.recent[role])
        per_device.append((r.speed_basis == REPORTED, hi))
    reported = [hi for rep, hi in per_device if rep]
    if reported:
        return max(reported)
    # Head and EOT ride one train: each bound holds for both, the smaller is the better.
    best = min((hi for _rep, hi in per_device), default=s.max_speed_mps)
    return min(best, witness_speed_mps(tr, s))


def witness_speed_mps(tr: Track, s: ControllerSettings) -> float:
    """The EOT as a second witness of the head: a head fix and an EOT fix taken at different
    times are two positions of the head (the EOT one a length behind it, the length known to
    ``3 · length_sigma_m``), so they bound the speed as two fixes of one device do, before
    either device has a second fix.  Direction unknown: the head could be a length either way.
    Holds at either fix's time (it may have braked since the first or accelerated since)."""
    h, e = tr.head, tr.eot
    if h is None or e is None or h.t_fix_ns == e.t_fix_ns:
        return math.inf
    if not (tr.kf_ok[HEAD] and tr.kf_ok[EOT]):
        # A fix its device's filter set aside is a jump: one position of it proves no slow train
        # (the speed bounds from the device's own fixes keep the most of its last few instead).
        return math.inf
    dt = abs(h.t_fix_ns - e.t_fix_ns) / NS
    d, length = tr.direction, tr.spec.length_m
    gap = abs(h.chainage_m - e.chainage_m - d * length) if d else abs(h.chainage_m - e.chainage_m) + length
    run_m = gap + s.noise_m * 2 + 3 * s.length_sigma_m
    return run_m / dt + max(s.accel_mps2, s.jump_accel_mps2) * dt / 2


def speed_basis_text(tr: Track) -> str:
    """How the speed cap is known, in words: the best basis any device of the train has."""
    bases = {r.speed_basis for r in (tr.head, tr.eot) if r is not None}
    for b, text in ((REPORTED, "reported"), (ESTIMATED, "estimated from the fixes")):
        if b in bases:
            return text
    return "unknown: the most a train runs"


def source_bound(tr: Track, s: ControllerSettings, motion: Motion, role: str) -> ArrivalBound | None:
    """The head's earliest arrival from one source's evidence (head, EOT + length, the train's
    filter); computed once after each fix of the train (the direction and the other device's
    speed bound take part), then kept."""
    if role in tr.bounds:
        return tr.bounds[role]
    last = tr.eot if role == EOT else tr.head
    b = None
    if last is not None:
        est = tr.kf[role].estimate
        # The cap holds at the time the bound is anchored: the train's filter may stand on a
        # later fix (of the EOT) than the head's last, and the train may have accelerated since.
        cap = speed_cap_mps(tr, s, last.t_fix_ns if est is None else max(last.t_fix_ns, est.t_ns))
        extra = tr.spec.length_m if role == EOT else 0.0
        b = device_bound(motion, est, tr.recent[EOT if role == EOT else HEAD], tr.direction, extra, cap)
    tr.bounds[role] = b
    return b


def acting_bound(tr: Track, s: ControllerSettings, motion: Motion, t_ns: int) -> tuple[ArrivalBound, str] | None:
    """The bound that counts now: the head unit's while it is fresh (the EOT's plus the train's
    length where it is nearer and the train's filter is not settled), else the EOT's plus the
    train's length, else (every unit stale) the one heard last: the train is not forgotten."""
    # A parted train's EOT rides on the rear part: it says nothing of the head (nor does the
    # train's filter, which took it as a witness of the head).
    whole = tr.parted_ns is None
    if fresh(tr.head, t_ns, s):
        tb = source_bound(tr, s, motion, TRAIN) if whole else None
        if tb is not None and tb.settled:
            return tb, "head"
        hb = source_bound(tr, s, motion, HEAD)
        if hb is not None:
            # The train's filter not settled, the head's and the EOT's fixes have not agreed
            # lately, and the head's bound stands on its own fixes alone: a first fix cannot be
            # told from a position jump (nothing to gate it against), nor a jump inside the wide
            # gate after a gap of sparse fixes from motion.  The EOT plus the length is a second
            # witness of the same head: the nearer of the two counts (a jump in either only
            # brings the warning forward).
            if whole and fresh(tr.eot, t_ns, s):
                eb = source_bound(tr, s, motion, EOT)
                if eb is not None and eb.t_arrival_ns < hb.t_arrival_ns:
                    return eb, EOT_WITNESS
            return hb, "head"
    if whole and fresh(tr.eot, t_ns, s) and (eb := source_bound(tr, s, motion, EOT)) is not None:
        return eb, "eot+length"
    heard = [(r.t_fix_ns, role) for role, r in ((HEAD, tr.head), (EOT, tr.eot)) if r is not None]
    if not whole and tr.head is not None:
        heard = [(tr.head.t_fix_ns, HEAD)]
    if not heard:
        return None
    role = max(heard)[1]
    b = source_bound(tr, s, motion, role)
    return (b, "stale " + ("head" if role == HEAD else "eot+length")) if b is not None else None


def onset_of(tr: Track, s: ControllerSettings, t_ns: int, b: ArrivalBound, basis: str) -> Onset:
    """The bound's parts when the warning came on: what each doubt cost (ETA s)."""
    eta = (b.t_arrival_ns - t_ns) / NS
    doubt: dict[str, float] = {}

    def add(cause: str, cost_s: float) -> None:
        if cost_s > 0.05:
            doubt[cause] = doubt.get(cause, 0.0) + cost_s

    last = tr.eot if "eot" in basis else tr.head
    no_speed = last is not None and last.speed_basis != REPORTED
    nominal = None
    if b.t_nominal_ns is not None and b.t_position_ns is not None and b.t_filter_ns is not None:
        nominal = (b.t_nominal_ns - t_ns) / NS
    if basis not in ("head", EOT_WITNESS):
        # The head unit lost (or every unit silent): the bound stands on the EOT and the length,
        # or on an old fix: all of what it cost is the stale units'.
        add(STALE, max(1.0, (nominal or eta) - eta))
    elif nominal is not None:
        assert b.t_nominal_ns is not None and b.t_position_ns is not None and b.t_filter_ns is not None
        add(SPARSE, (b.t_nominal_ns - b.t_position_ns) / NS)  # the position's σ
        add(NO_SPEED if no_speed else SPARSE, (b.t_position_ns - b.t_filter_ns) / NS)  # the speed's σ
        fallback = (b.t_filter_ns - b.t_arrival_ns) / NS  # the model-free bound came first
        clean_ns = int(max(s.speed_window_s, 3 * s.report_period_s) * NS)
        jumped = any(d is not None and t_ns - d < clean_ns for d in tr.doubt_ns.values())
        add(JUMPS if jumped else NO_SPEED if no_speed else SPARSE, fallback)
    return Onset(t_ns, eta, nominal, doubt)
