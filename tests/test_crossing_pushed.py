"""A train running with its EOT end leading (backing, or pushed): its rear is the head unit's end.

The warning went off on two EOT fixes d_off past the crossing, as for a train the head unit leads: with the
EOT leading, the rear was then still a train's length short of it, and the road opened on the train."""

from __future__ import annotations

import pytest

from console.analysis.crossing.clock import run_controller
from console.analysis.crossing.values import EOT, HEAD, Fix, TrainSpec
from console.layout import load_layout
from parsers.units import NS

LAYOUT = load_layout("example")
SPEED = 15.0
START_M = 3000.0  # the leading end's distance from the crossing at t = 0


def _down(length: float, eot_leads: bool) -> list[Fix]:
    """Down the line at 15 m/s from 3 km above the crossing, a fix of each unit every second."""
    c = LAYOUT.crossings[0].chainage_m
    fixes = []
    for k in range(400):
        front = c + START_M - SPEED * k
        ends = {EOT: front, HEAD: front + length} if eot_leads else {HEAD: front, EOT: front + length}
        for role, dt in ((HEAD, 0.0), (EOT, 0.5)):
            t_fix = int((k + dt) * NS)
            fixes.append(Fix(t_fix + int(0.2 * NS), t_fix, "T", role, ends[role] - SPEED * dt, SPEED))
    return fixes


@pytest.mark.parametrize("length", [120.0, 300.0])
@pytest.mark.parametrize("eot_leads", [True, False])
def test_the_road_opens_only_when_the_rear_is_past(length: float, eot_leads: bool) -> None:
    crossing = LAYOUT.crossings[0]
    ctl = run_controller(crossing, [TrainSpec("T", length)], _down(length, eot_leads))
    # One warning, on until the rear is past: far out, a 300 m train pushed flickered on and off (on by "EOT
    # + train length", released by the trailing head unit's bound, a train's length further out).
    (off,) = [e for e in ctl.events if e.kind == "off"]
    assert [e.kind for e in ctl.events] == ["on", "off"]
    half = ctl.s.crossing_half_width_m
    rear_clears_s = (START_M + half + length) / SPEED  # the truth: the rear end past the road's far edge
    assert off.t_ns / NS >= rear_clears_s + crossing.d_off_m / SPEED - 1.0, (off, rear_clears_s)
    assert ("EOT leading" in off.reason) == eot_leads
    if not eot_leads:  # the head leading: off as before, about d_off past, not held a train's length longer
        assert off.t_ns / NS < rear_clears_s + (crossing.d_off_m + 2 * SPEED) / SPEED


@pytest.mark.parametrize("eot_leads", [True, False])
def test_the_timeline_times_the_front_and_the_rear_whichever_unit_leads(eot_leads: bool) -> None:
    """The timeline's arrival was the head unit's, its tail clear the EOT's: with the EOT leading, the arrival
    came a train's length late (the lead 8 s too long) and the tail cleared before the head arrived."""
    from console.analysis.crossing.timeline import timeline

    length = 120.0
    fixes = _down(length, eot_leads)
    ctl = run_controller(LAYOUT.crossings[0], [TrainSpec("T", length)], fixes)
    (row,) = timeline(ctl, fixes)
    half = ctl.s.crossing_half_width_m
    assert row.t_head_arrival_ns is not None and row.t_tail_clear_ns is not None
    assert abs(row.t_head_arrival_ns / NS - (START_M - half) / SPEED) < 1.0
    assert abs(row.t_tail_clear_ns / NS - (START_M + half + length) / SPEED) < 1.0
    assert row.violations == ()
