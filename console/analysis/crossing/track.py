"""One train as the crossing unit follows it (:class:`Track`): its devices' evidence and filters, its
direction, its warning and the unit's agenda for it; a fix fed to its filters; and whether a device of it
is heard from (fresh)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from console.analysis.crossing.arrival import ArrivalBound
from console.analysis.crossing.estimate import FilterLimits, MotionFilter
from console.analysis.crossing.evidence import DeviceEvidence, EvidenceLimits, Report
from console.analysis.crossing.values import EOT, HEAD, TRAIN, ControllerSettings, Fix, Onset, TrainSpec
from console.analysis.window import Window
from parsers.units import NS

RECENT_FIXES = 3  # the model-free bound takes each of this many last fixes on its own


@dataclass
class Track:
    """A train as the unit follows it: what its devices said, their filters, its direction and its warning."""

    spec: TrainSpec
    head_ev: DeviceEvidence
    eot_ev: DeviceEvidence
    kf: dict[str, MotionFilter]
    head: Report | None = None
    eot: Report | None = None
    recent: dict[str, Window[Report]] = field(
        default_factory=lambda: {HEAD: Window(RECENT_FIXES), EOT: Window(RECENT_FIXES)}
    )
    bounds: dict[str, ArrivalBound | None] = field(default_factory=dict)  # per source, since the last fix
    kf_ok: dict[str, bool] = field(default_factory=lambda: {HEAD: False, EOT: False})  # last fix taken by the filter
    doubt_ns: dict[str, int | None] = field(default_factory=lambda: {HEAD: None, EOT: None})  # last jump / set aside
    eot_kept: Report | None = None  # the last EOT fix the filter took (which unit leads is judged on it)
    direction: int = 0
    direction_set_ns: int = 0  # fix time of the last change of direction
    # The last direction known (±1; 0: never known): one the witnesses left unknown is not reversed by
    # less than reverses a known one.
    known_direction: int = 0
    # The direction the tail was last proven past the crossing in (0: not proven), by the off rule's own
    # evidence (:func:`console.analysis.crossing.tail.tail_past_evidence`); an EOT fix the filter took short
    # of it ends it.
    tail_past_dir: int = 0
    # The direction in which an EOT fix the filter took was last short of the crossing (0: none): a tail seen
    # on the near side and then past has crossed, standing there or not.
    eot_short_dir: int = 0
    warned: bool = False
    t_on: int | None = None
    reason_on: str = ""
    t_off: int | None = None
    reason_off: str = ""
    onset: Onset | None = None  # the last warning's
    onsets: list[Onset] = field(default_factory=list)  # every warning's, in order (a timeline row per pass)
    releases: list[tuple[int, int, str]] = field(default_factory=list)  # (on, off, why) of released warnings
    alarms: set[str] = field(default_factory=set)
    episodes: list[tuple[int, int | None, str, str]] = field(default_factory=list)
    parted_ns: int | None = None  # when the integrity monitor saw the train parted
    # The unit's agenda (see CrossingController): the order the train was first followed in, the
    # first instant after its last evaluation at which time alone may change what the unit does for
    # it (None: nothing pending), and its share of next_change_ns (None: none).
    seq: int = 0
    due_ns: int | None = None
    late_ns: int | None = None


def new_track(spec: TrainSpec, s: ControllerSettings, seq: int) -> Track:
    """A train to follow: its devices' evidence and filters under the settings, ``seq`` its place in the order
    trains were first followed."""
    lim = EvidenceLimits(
        s.noise_m,
        s.accel_mps2,
        s.jump_accel_mps2,
        s.max_speed_mps,
        s.speed_window_s,
        speed_error_mps=s.k_sigma * s.speed_sigma_mps,  # the same bound on a reported speed as the filter's
    )
    flim = FilterLimits(
        s.noise_m / 3.0,
        s.speed_sigma_mps,
        s.jerk_psd,
        s.max_speed_mps,
        k_sigma=s.k_sigma,
        settle_fixes=s.settle_fixes,
        adaptive_noise=s.adaptive_noise,
    )
    kf = {HEAD: MotionFilter(flim), EOT: MotionFilter(flim), TRAIN: MotionFilter(flim)}
    return Track(spec, DeviceEvidence(lim), DeviceEvidence(lim), kf, seq=seq)


def fresh(r: Report | None, t_ns: int, s: ControllerSettings) -> bool:
    """Heard from within the stale time: stale from ``stale_after_s`` after its fix on."""
    return r is not None and (t_ns - r.t_fix_ns) < int(s.stale_after_s * NS)


def feed_device_filter(tr: Track, fix: Fix, rep: Report, ev: DeviceEvidence) -> None:
    """Feed the device's filter; a fix it sets aside (or a track started over) is doubt."""
    kf = tr.kf[fix.role]
    if rep.restarted:
        kf.reset()
        tr.doubt_ns[fix.role] = fix.t_fix_ns
        if len(ev.history) > 1:  # the set-aside fix the new track began with
            t0, ch0 = ev.history[0]
            kf.offer(t0, ch0, math.nan, tr.direction)
    ok = kf.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps, tr.direction)
    tr.kf_ok[fix.role] = ok
    if not ok:
        tr.doubt_ns[fix.role] = fix.t_fix_ns
    elif fix.role == EOT:
        tr.eot_kept = rep


def feed_train_filter(tr: Track, s: ControllerSettings, fix: Fix, rep: Report) -> None:
    """The head's motion from both units: the EOT rides a train's length behind the head, so its
    fix is a head fix with the length's doubt added (only with the direction known)."""
    train = tr.kf[TRAIN]
    if rep.restarted:
        train.reset()
    # Each fix with its own device's noise (the two receivers need not be alike).
    sigma_m = tr.kf[fix.role].noise_sigma_m
    if fix.role == HEAD:
        train.offer(fix.t_fix_ns, fix.chainage_m, fix.speed_mps, tr.direction, sigma_m=sigma_m)
    elif tr.direction and tr.parted_ns is None:  # a parted train's EOT is on the rear part
        at = fix.chainage_m + tr.direction * tr.spec.length_m
        train.offer(fix.t_fix_ns, at, fix.speed_mps, tr.direction, s.length_sigma_m**2, sigma_m)
