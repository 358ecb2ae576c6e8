"""Slow faults in the simulator: heads and units that wear over days, and the registers and truth they leave."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from console.archive.health_days import gnss_loss_per_day
from console.archive.reader import Window
from console.archive.views import connect
from console.cli.app import app
from console.layout import load_layout
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.slow_faults import DEFAULT_RATES, HealthRows, threshold_crossings
from console.sim.station import StationSim

runner = CliRunner()
DAY = 86_400.0


def _rows(sim: StationSim) -> HealthRows:
    return HealthRows.concat(sim.health_rows)


def test_a_health_only_run_writes_the_registers_a_full_run_writes() -> None:
    """One simulator: stepped with its trains, or for the registers alone, the same rounds come out."""
    faults = (
        Fault("analog_drift", "WS2", 600.0, channel=1, rate=40.0),
        Fault("disturbance_growth", "WS3", 0.0, rate=50.0),
    )
    cfg = SimConfig(seed=5, faults=faults, health_period_s=300.0)
    full = StationSim(load_layout("example"), cfg)
    full.run(3 * 3600.0)
    alone = StationSim(load_layout("example"), cfg)
    alone.run_health_only(3 * 3600.0)
    a, b = _rows(full), _rows(alone)
    assert len(a) == 36 * 5 * 6  # 36 rounds, 5 heads, 2 channels × (counter + two analog values)
    for name in ("t_ns", "head", "channel", "register", "value"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert len(full.all_records) > 0 and not alone.all_records  # trains only in the full run


def test_the_registers_follow_the_faults() -> None:
    lay = load_layout("example")
    faults = (
        Fault("analog_drift", "WS2", 0.0, channel=1, rate=24.0),
        Fault("disturbance_growth", "WS3", 0.0, rate=48.0),
    )
    sim = StationSim(lay, SimConfig(seed=2, faults=faults, health_period_s=600.0))
    sim.run_health_only(DAY / 2)
    h = sim.health
    assert h is not None
    r = _rows(sim)
    t_h = (r.t_ns - sim.cfg.start_ns) / 3.6e12
    ws2 = h.index["WS2"]
    # WS2 Sys1 falls 24 counts a day: 1 an hour; Sys2 stays; readings within noise and a day's wander of it.
    for ch, drop_per_h in ((1, 1.0), (2, 0.0)):
        sel = (r.head == ws2) & (r.channel == ch) & (r.register > 0)
        expected = h.base[ws2, ch - 1] - drop_per_h * t_h[sel]
        assert np.abs(r.value[sel] - expected).max() <= h.s.address_offset + h.s.reading_noise + 5 * h.s.day_sigma + 1
    # WS3 Sys2's counter grows 1.8/h + 2/h per hour: ≈ 1.8·12 + 12² = 165 by noon; Sys1 ≈ 22 (Poisson).
    ws3 = h.index["WS3"]
    last = {ch: int(r.value[(r.head == ws3) & (r.channel == ch) & (r.register == 0)][-1]) for ch in (1, 2)}
    assert 120 < last[2] < 210 and 8 < last[1] < 40


def test_the_truth_gives_each_threshold_crossing() -> None:
    base = load_layout("example")
    heads = tuple(dataclasses.replace(h, analog_band=(2300.0, 2500.0)) if h.id == "WS1" else h for h in base.heads)
    lay = dataclasses.replace(base, heads=heads)
    faults = (
        Fault("analog_drift", "WS1", DAY, channel=1, rate=10.0),  # 100 counts from the middle: 10 days after its start
        Fault("disturbance_growth", "WS2", 0.0, channel=2),  # default: (12 - 1.8) / 0.6 = 17 days
        Fault("disturbance_growth", "WS3", 0.0, end_s=5 * DAY, channel=1),  # repaired before it got there
        Fault("gnss_decay", "T2-eot", 2 * DAY, rate=0.05),  # 25 % after 5 days
        Fault("gnss_decay", "T2-eot", 3 * DAY, rate=0.05),  # … sooner with a second: 0.05 at day 3, then 0.1/day
    )
    sim = StationSim(lay, SimConfig(faults=faults, health_period_s=3600.0))
    got = {(c["target"], c["figure"]): c for c in threshold_crossings(sim.health, faults, sim.cfg.start_ns, 3 * DAY)}
    start = np.datetime64(sim.cfg.start_ns, "ns")

    def at(days: float) -> str:
        return str(start + np.timedelta64(round(days * 86_400_000), "ms")) + "Z"

    assert got[("WS1", "analog_margin")]["time"].startswith(at(11.0)[:23])
    assert got[("WS1", "analog_margin")]["band"] == [2300.0, 2500.0]
    assert got[("WS2", "disturbance_rate")]["time"].startswith(at(17.0)[:23])
    assert got[("WS2", "disturbance_rate")]["rate"] == DEFAULT_RATES["disturbance_growth"]
    assert got[("WS3", "disturbance_rate")]["time"] is None
    assert got[("T2-eot", "gnss_loss")]["time"].startswith(at(3.0 + 2.0)[:23])
    assert not got[("T2-eot", "gnss_loss")]["within_run"]


def test_a_decaying_unit_loses_a_growing_share_and_trainsets_come_back() -> None:
    faults = (Fault("gnss_decay", "T2-eot", 0.0, rate=3.0),)  # 3 per day: 0.125 an hour
    sim = StationSim(load_layout("example"), SimConfig(seed=3, faults=faults, trains_per_hour=8, fleet=3))
    sim.run(3 * 3600.0)
    assert {t.id for t in sim.trains} == {"T1", "T2", "T3"} and len(sim.trains) > 6
    sent = {role: [f.t_ns for f in sim.all_fixes if f.train == "T2" and f.role == role] for role in ("head", "eot")}
    hours = {role: np.array(ts, np.int64) - sim.cfg.start_ns for role, ts in sent.items()}
    # The head unit sends every report; the EOT unit, fewer and fewer: kept = 1 − 0.125 t (t in hours).
    kept = [
        np.sum((hours["eot"] >= k * 3.6e12) & (hours["eot"] < (k + 1) * 3.6e12))
        / max(1, np.sum((hours["head"] >= k * 3.6e12) & (hours["head"] < (k + 1) * 3.6e12)))
        for k in range(3)
    ]
    assert kept[0] > kept[2] and abs(kept[2] - (1 - 0.125 * 2.5)) < 0.15, kept


def test_one_growing_log_is_the_days_one_after_another(tmp_path: Path) -> None:
    common = ["--days", "2", "--health-only", "--health-every", "1h", "--fault", "analog_drift:WS1:6h::1"]
    res = runner.invoke(app, ["simulate", "-o", str(tmp_path / "days"), *common])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["simulate", "-o", str(tmp_path / "one"), *common, "--one-log"])
    assert res.exit_code == 0, res.output
    days = sorted(p for p in (tmp_path / "days").iterdir() if p.is_dir())
    assert [p.name for p in days] == ["2026-03-02", "2026-03-03"]
    for p in days:  # each day's log holds that day's records only
        dates = {line.rsplit("Date:", 1)[1][:10] for line in (p / "diagnostic.log").read_text().splitlines()}
        assert dates == {p.name}
    joined = "".join((p / "diagnostic.log").read_text() for p in days)
    assert (tmp_path / "one" / "diagnostic.log").read_text() == joined
    truth = json.loads((tmp_path / "one" / "truth.json").read_text())
    assert truth["threshold_crossings"][0]["target"] == "WS1" and truth["health_registers"]["period_s"] == 3600.0


def _unit_csv(path: Path, day: str, lost_every: dict[str, int]) -> None:
    """Two trips of 200 reports 5 s apart per unit, an hour between trips; every k-th report lost."""
    t0 = np.datetime64(f"{day}T06:00:00", "ms")
    lines = ["time,device,role,lat,lon,speed,course"]
    for device, k in lost_every.items():
        for trip in range(2):
            for i in range(200):
                if k and i % k == k - 1:
                    continue
                t = t0 + np.timedelta64(trip * 3_600_000 + i * 5_000, "ms")
                lines.append(f"{t}Z,{device},eot,20.75,105.9,10.0,160.0")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_the_daily_loss_of_a_unit_counts_the_reports_missing_from_its_period(tmp_path: Path) -> None:
    src = tmp_path / "in"
    src.mkdir()
    _unit_csv(src / "d1.csv", "2026-03-02", {"U1-eot": 4, "U2-eot": 0})
    _unit_csv(src / "d2.csv", "2026-03-03", {"U1-eot": 2, "U2-eot": 10})
    arc = tmp_path / "arc"
    res = runner.invoke(app, ["ingest", str(src), "--archive", str(arc)])
    assert res.exit_code == 0, res.output
    con, _ = connect(arc, tables={"fixes"})
    try:
        got = {
            (r["day"], r["device"]): (r["fixes"], r["missing"], r["period_s"]) for r in gnss_loss_per_day(con, Window())
        }
    finally:
        con.close()
    # Every 4th of 200 lost: 150 sent, 49 missing between the first and the last (the trip's last is lost: unseen).
    assert got[("2026-03-02", "U1-eot")] == (300, 98, 5.0)
    assert got[("2026-03-02", "U2-eot")] == (400, 0, 5.0)
    assert got[("2026-03-03", "U1-eot")] == (200, 198, 5.0)  # every other one: the period is still 5 s
    assert got[("2026-03-03", "U2-eot")] == (360, 38, 5.0)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--fault", "gnss_decay:WS1:0s"], "not a GNSS unit"),
        (["--days", "2", "--fault", "gnss_decay:T9-eot:0s"], "T1 to T3"),
        (["--days", "2", "--health-only", "--fault", "gnss_decay:T1-eot:0s"], "no GNSS unit"),
        # Train faults aimed at no trainset, and faults a health-only run never applies, did nothing silently.
        (["--days", "0.02", "--fault", "train_parting:T9:1h"], "the fleet's trainsets are T1 to T3"),
        (["--days", "0.02", "--fleet", "2", "--fault", "eot_loss:T3:1h"], "the fleet's trainsets are T1 to T2"),
        (["--days", "0.02", "--health-only", "--fault", "train_parting:T1:1h"], "only analog_drift and"),
        (["--days", "2", "--fleet", "1000000000000", "--fault", "gnss_decay:T01-eot:0s"], "T1 to T1000000000000"),
        (["--days", "0.02", "--health-only", "--fault", "dead_channel:WS1:1h"], "only analog_drift and"),
        (["--fault", "dead_channel:WS1:0s::1:0.5"], "a RATE is for the slow faults"),
        (["--fault", "gnss_decay:T1-eot:0s::2:1.5"], "at most 1"),
        (["--fault", "analog_drift:WS1:0s::3"], "channel must be 1 or 2"),
        (["--one-log"], "go with --days"),
        (["--days", "2", "--live"], "give one or the other"),
    ],
)
def test_slow_fault_usage_errors_are_one_line(tmp_path: Path, args: list[str], says: str) -> None:
    res = runner.invoke(app, ["simulate", "-o", str(tmp_path / "run"), *args])
    assert res.exit_code == 2 and says in res.output, res.output
    assert not (tmp_path / "run").exists()
