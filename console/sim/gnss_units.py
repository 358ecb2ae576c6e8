"""The GNSS units riding the trains: the fixes they send every report period (with noise, less those a
unit loss or a wearing unit keeps back), the EOT unit's emergency statuses, and the radio that loses
some of the fixes and delivers the others after its latency."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from console.analysis.crossing.values import EOT, HEAD
from console.analysis.geo import TrackProjector
from console.sim.faults import Fault
from console.sim.line_values import SentFix, SimTrain
from console.sim.slow_faults import unit_loss
from parsers.units import NS


def sent_fix(
    tr: SimTrain,
    role: str,
    t: float,
    x: float,
    proj: TrackProjector,
    noise_m: float,
    start_ns: int,
    rng: np.random.Generator,
    emergency: bool = False,
) -> SentFix:
    """The fix ``role``'s unit sends at ``t`` from chainage ``x``, its noise drawn from ``rng``."""
    plat, plon = proj.position(x)
    lat = float(plat[0]) + float(rng.normal(0, noise_m)) / proj.m_per_deg_lat
    lon = float(plon[0]) + float(rng.normal(0, noise_m)) / proj.m_per_deg_lon
    course = (proj.bearing_deg(x) + (0.0 if tr.direction > 0 else 180.0)) % 360.0
    speed = max(0.0, tr.v_mps + float(rng.normal(0, 0.1)))
    bar = round(tr.pipe_bar * 20) / 20  # the payload's 0.05 bar
    return SentFix(start_ns + int(t * NS), tr.id, role, lat, lon, speed, course, True, bar, emergency)


def unit_fixes(
    tr: SimTrain,
    t0: float,
    t1: float,
    x0: float,
    *,
    faults: Sequence[Fault],
    period_s: float,
    proj: TrackProjector,
    noise_m: float,
    start_ns: int,
    reports_lost: dict[tuple[str, str], int],
    rng: np.random.Generator,
    unit_rng: np.random.Generator,
    alarm_rng: np.random.Generator,
) -> list[SentFix]:
    """The fixes the train's units send in the step from t0 to t1 (its head moving from x0).

    ``reports_lost`` counts those an eot_loss / head_loss fault keeps back (updated here).  The draws:
    ``rng`` the periodic fixes' noise, ``unit_rng`` a wearing unit's losses (gnss_decay), ``alarm_rng``
    the emergency statuses' noise, each its own stream so that one never shifts another's."""
    out = []
    for role in tr.units:
        attr = "next_head_fix_s" if role == HEAD else "next_eot_fix_s"
        while getattr(tr, attr) < t1:
            t = getattr(tr, attr)
            setattr(tr, attr, t + period_s)
            lost = any(
                f.kind == ("head_loss" if role == HEAD else "eot_loss") and f.target == tr.id and f.active(t)
                for f in faults
            )
            if lost and t >= t0:
                key = (str(tr.id), role)
                reports_lost[key] = reports_lost.get(key, 0) + 1
            if lost or t < t0:
                continue
            p_lost = unit_loss(faults, f"{tr.id}-{role}", t)
            if p_lost > 0 and unit_rng.random() < p_lost:
                continue  # a wearing unit (gnss_decay): the report is never sent
            frac = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
            head_x = x0 + frac * (tr.x_m - x0)
            x = head_x if role == HEAD else head_x - tr.direction * tr.consist.length_m
            out.append(sent_fix(tr, role, t, x, proj, noise_m, start_ns, rng))
    # The EOT unit's emergency statuses due in this step: each a fresh report, the flag set.
    while tr.alarms_s and tr.alarms_s[0] < t1 and EOT in tr.units:
        t = max(tr.alarms_s.pop(0), t0)
        if any(f.kind == "eot_loss" and f.target == tr.id and f.active(t) for f in faults):
            continue
        frac = (t - t0) / (t1 - t0) if t1 > t0 else 1.0
        x = x0 + frac * (tr.x_m - x0) - tr.direction * tr.consist.length_m
        # The emergency statuses draw from their own stream: the periodic fixes' draws are as they were.
        out.append(sent_fix(tr, EOT, t, x, proj, noise_m, start_ns, alarm_rng, emergency=True))
    return out


def radio_delivery(
    sent: list[SentFix],
    in_flight: list[tuple[int, SentFix]],
    t1_ns: int,
    latency_s: float,
    loss: float,
    rng: np.random.Generator,
) -> list[SentFix]:
    """The radio: it loses a share ``loss`` of the fixes sent and delivers the others after its latency;
    those due by ``t1_ns``, in delivery order.  ``in_flight``: the fixes it is delivering, by delivery time,
    carried from step to step (updated here)."""
    latency_ns = int(latency_s * NS)
    for f in sent:
        if rng.random() < loss:
            continue
        in_flight.append((f.t_ns + latency_ns, f))
    in_flight.sort(key=lambda x: x[0])
    due = 0
    while due < len(in_flight) and in_flight[due][0] <= t1_ns:
        due += 1
    received = [f for _, f in in_flight[:due]]
    del in_flight[:due]
    return received
