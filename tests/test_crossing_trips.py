"""A train passing a crossing trip after trip: one timeline row per pass, each with its own warning.

A trainset that ran back and forth over a crossing used to get one row pairing its first head
arrival with its last warning: false late warnings of −40 000 s.  The truth here is the
simulator's (each pass's head arrival and tail clearance) and a hand-made back-and-forth.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from console.analysis.crossing.clock import run_controller
from console.analysis.crossing.timeline import timeline
from console.analysis.crossing.values import EOT, HEAD, Fix, TrainSpec
from console.cli.app import app
from console.layout import load_layout
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_run
from parsers.units import NS

LAYOUT = load_layout("example")


def _s(iso: str) -> float:
    return float(np.datetime64(iso.rstrip("Z"), "ns").astype(np.int64)) / NS


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, list[dict]]:
    """Three trainsets, trip after trip for 75 minutes: each passes each crossing three times."""
    sim = StationSim(LAYOUT, SimConfig(seed=4, fleet=3, trains_per_hour=30))
    sim.run(75 * 60)
    out = tmp_path_factory.mktemp("fleet") / "run"
    write_run(sim, out)
    nmea = sorted(str(p) for p in (out / "nmea").glob("*.nmea"))
    res = CliRunner().invoke(app, ["crossing", *nmea, "--layout", str(out / "layout.toml"), "--json"])
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout), json.loads((out / "truth.json").read_text())["crossings"]


def test_every_pass_of_a_trainset_has_its_own_row(fleet: tuple[dict, list[dict]]) -> None:
    doc, truth = fleet
    rows = doc["timelines"]
    passes: dict[tuple[str, str], int] = {}
    for t in truth:
        passes[(t["crossing"], t["train"])] = passes.get((t["crossing"], t["train"]), 0) + 1
    assert len(passes) == 6 and min(passes.values()) >= 3  # every trainset, every crossing, trip after trip
    for t in truth:
        near = [
            r
            for r in rows
            if (r["crossing"], r["train"]) == (t["crossing"], t["train"])
            and r["t_head_arrival"] is not None
            and abs(_s(r["t_head_arrival"]) - _s(t["t_head_arrival"])) < 3.0
        ]
        assert len(near) == 1, (t, near)
        (r,) = near
        if t["t_tail_clear"] is not None:
            assert r["t_off"] is not None and _s(r["t_off"]) >= _s(t["t_tail_clear"])
    arrived = [r for r in rows if r["t_head_arrival"] is not None]
    assert len(arrived) == len(truth)  # no row for a pass that did not happen


def test_no_pass_is_reported_unsafe(fleet: tuple[dict, list[dict]]) -> None:
    doc, _truth = fleet
    assert doc["violations"] == 0
    for r in doc["timelines"]:
        assert r["violations"] == [], r
        if r["t_head_arrival"] is not None:
            assert r["lead_time_s"] is not None and r["lead_time_s"] >= r["warning_time_s"] > 0, r
            assert r["late_by_s"] is None and r["late_cause"] is None
            assert r["spare"] is not None and r["spare"]["spare_s"] >= 0


def _trip(t0_s: float, x0_m: float, d: int, v_mps: float, accel_s: float, cruise_s: float, brake_s: float) -> tuple:
    """Head position each second of a trip: accelerate (or start at speed), cruise, brake to a stop."""
    t = np.arange(0.0, accel_s + cruise_s + brake_s + 1e-9, 1.0)
    a = v_mps / accel_s if accel_s else 0.0
    b = v_mps / brake_s if brake_s else 0.0
    v = np.where(t < accel_s, a * t, np.where(t < accel_s + cruise_s, v_mps, v_mps - b * (t - accel_s - cruise_s)))
    x = np.where(
        t < accel_s,
        a * t**2 / 2,
        np.where(
            t < accel_s + cruise_s,
            a * accel_s**2 / 2 + v_mps * (t - accel_s),
            a * accel_s**2 / 2
            + v_mps * cruise_s
            + v_mps * (t - accel_s - cruise_s)
            - b * (t - accel_s - cruise_s) ** 2 / 2,
        ),
    )
    return t0_s + t, x0_m + d * x, np.maximum(v, 0.0), d


def _back_and_forth(length: float, until_s: float = 1e9, swap: bool = True) -> list[Fix]:
    """Up over the crossing, stabled 2.5 km past it (the units off, the crew changing ends: the head
    unit the other end's, ``swap``), back down."""
    c = LAYOUT.crossings[0].chainage_m
    up = _trip(0.0, c - 3000, 1, 20.0, 0.0, 255.0, 40.0)  # stops with the head at c + 2500
    down = _trip(600.0, c + 2500 - swap * length, -1, 20.0, 40.0, 250.0, 0.0)  # the other end leads
    fixes = []
    for ts, xs, vs, d in (up, down):
        for t, x, v in zip(ts, xs, vs, strict=True):
            for role, dt, at in ((HEAD, 0.0, x), (EOT, 0.5, x - d * length)):
                t_fix = int((t + dt) * NS)
                if t + dt <= until_s:
                    fixes.append(Fix(t_fix + int(0.2 * NS), t_fix, "T", role, float(at), float(v)))
    return fixes


def test_one_train_two_passes_in_opposite_directions() -> None:
    crossing = LAYOUT.crossings[0]
    length = 100.0
    fixes = _back_and_forth(length)
    ctl = run_controller(crossing, [TrainSpec("T", length)], fixes)
    rows = timeline(ctl, fixes)
    # The truth: the head at the road's near edge, the tail past its far edge.
    half = ctl.s.crossing_half_width_m
    heads = [(3000 - half) / 20.0, 600.0 + 40.0 + (2400 - half - 400) / 20.0]
    tails = [(3000 + half + length) / 20.0, 600.0 + 40.0 + (2400 + half + length - 400) / 20.0]
    assert len(rows) == 2
    for r, th, tt in zip(rows, heads, tails, strict=True):
        assert r.t_head_arrival_ns is not None and abs(r.t_head_arrival_ns / NS - th) < 1.0
        assert r.t_tail_clear_ns is not None and abs(r.t_tail_clear_ns / NS - tt) < 1.0
        assert r.violations == () and r.late_by_s is None
        assert r.lead_s is not None and r.lead_s >= crossing.warning_time_s
        assert r.t_on_ns is not None and r.t_off_ns is not None and r.t_on_ns < r.t_head_arrival_ns
        assert r.t_off_ns >= r.t_tail_clear_ns
        assert r.spare is not None and r.spare.spare_s >= 0
    first, second = rows
    assert first.t_off_ns is not None and second.t_on_ns is not None and first.t_off_ns < second.t_on_ns
    # Each pass's spare split is its own warning's: the controller kept both onsets.
    onsets = ctl.tracks["T"].onsets
    assert [o.t_ns for o in onsets][-1] == second.t_on_ns and first.t_on_ns in [o.t_ns for o in onsets]


@pytest.mark.parametrize(("until_s", "swap"), [(612.0, False), (660.0, True)])
def test_a_warning_for_the_next_trip_is_not_paired_with_the_last_arrival(until_s: float, swap: bool) -> None:
    """The fixes end with the train just off on its way back (612 s: 36 m moved, its head unit where it
    stood; 660 s: 800 m), its warning on: the pass keeps its own warning, and the one on now is a row
    without a head arrival, not a late warning of the pass."""
    crossing = LAYOUT.crossings[0]
    length = 100.0
    alone = timeline(run_controller(crossing, [TrainSpec("T", length)], f := _back_and_forth(length, 400.0)), f)
    fixes = _back_and_forth(length, until_s, swap)
    ctl = run_controller(crossing, [TrainSpec("T", length)], fixes)
    assert ctl.tracks["T"].warned  # on for the way back
    passed, coming = timeline(ctl, fixes)
    assert passed == alone[0]  # the row it gets without the way back
    assert passed.violations == () and passed.lead_s is not None and passed.lead_s >= crossing.warning_time_s
    assert coming.t_head_arrival_ns is None and coming.t_off_ns is None and coming.violations == ()
    assert passed.t_off_ns is not None and coming.t_on_ns is not None and coming.t_on_ns > passed.t_off_ns
