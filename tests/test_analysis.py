"""console.analysis: passages, axle pairing, overlap, whole-second logs."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from benchmarks.gen_diag_log import generate
from console.analysis.counting.speed import axle_kmh, per_second_method_kmh, whole_train_kmh
from console.analysis.counting.wheels import PairingSettings, pair_axles
from console.analysis.passages.speed_settings import SpeedSettings
from tests.conftest import record
from tests.reads import whole_job


def _analyze(tmp_path: Path, lines: list[str], **settings: float) -> list[dict]:
    p = tmp_path / "log.txt"
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return whole_job([p], SpeedSettings(**settings)).analysis.passages_json()  # type: ignore[arg-type]


def test_speed_formulas() -> None:
    assert per_second_method_kmh(0.13, 34) == pytest.approx(15.912)
    assert whole_train_kmh(28.6, 0.13, 6.0) == pytest.approx(17.238)
    assert whole_train_kmh(28.6, 0.13, 0.0) is None
    assert axle_kmh(0.13, 0.026) == pytest.approx(18.0)
    assert axle_kmh(0.13, 0.0) is None


def test_idle_gap_splits_passages(tmp_path: Path) -> None:
    lines = [record(time="09:00:00"), record(time="09:00:08"), record(time="09:00:30")]
    assert [p["records"] for p in _analyze(tmp_path, lines)] == [2, 1]
    assert [p["records"] for p in _analyze(tmp_path, lines, idle_gap_s=30)] == [3]
    assert [p["records"] for p in _analyze(tmp_path, lines, idle_gap_s=5)] == [1, 1, 1]


def test_passages_are_per_counting_head(tmp_path: Path) -> None:
    other = record(time="09:00:01").replace("Trackinfo:WS4", "Trackinfo:WS5")
    ps = _analyze(tmp_path, [record(time="09:00:00"), other, record(time="09:00:02")])
    assert sorted((p["counting_head"], p["records"]) for p in ps) == [("WS4", 2), ("WS5", 1)]


def _onsets(rows: list[tuple[int, int, float, bool]]) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "head": [r[0] for r in rows],
            "channel": [r[1] for r in rows],
            "time_ns": [int(r[2] * 1e9) for r in rows],
            "subsecond": [r[3] for r in rows],
        }
    )


def test_pairing_is_one_to_one_and_windowed() -> None:
    onsets = _onsets(
        [
            (0, 1, 10.000, True),
            (0, 1, 10.010, True),  # a second Sys1 onset wants the same Sys2 onset
            (0, 2, 10.030, True),
            (0, 1, 20.000, True),
            (0, 2, 21.000, True),  # 1 s later: beyond the 0.47 s window
            (1, 2, 30.000, True),  # other head, Sys2 first
            (1, 1, 30.020, True),
        ]
    )
    axles, unpaired = pair_axles(onsets, PairingSettings())
    assert len(axles) == 2 and unpaired == 3
    first = axles.sort_values("time_ns").iloc[0]
    assert first["t_sys1_ns"] == int(10.010e9)  # the nearer Sys1 onset keeps it
    assert first["speed_kmh"] == pytest.approx(0.13 / 0.020 * 3.6)
    assert list(axles["direction"]) == ["sys1_to_sys2", "sys2_to_sys1"]


def test_whole_second_onsets_pair_by_their_order() -> None:
    # Three wheels in one whole second, a stray Sys1 onset before them: the
    # order of the lines pairs them (every second link of a run), one to one.
    rows = [(0, 1, 9.0, False)] + [(0, ch, 10.0, False) for _ in range(3) for ch in (1, 2)]
    axles, unpaired = pair_axles(_onsets(rows), PairingSettings())
    assert (len(axles), unpaired) == (3, 1)
    assert set(axles["direction"]) == {"sys1_to_sys2"}
    assert axles["speed_kmh"].isna().all()  # whole seconds cannot time 0.13 m


def test_per_axle_speed_only_where_the_stamps_time_the_delay() -> None:
    # 0.13 m in 4 ms (117 km/h): millisecond stamps cannot say 3.5 from 4.5 ms; microseconds can.
    rows = [(0, 1, 10.000, True), (0, 2, 10.004, True), (1, 1, 10.000123, True), (1, 2, 10.004123, True)]
    axles, unpaired = pair_axles(_onsets(rows), PairingSettings())
    assert (len(axles), unpaired) == (2, 0)
    by_head = axles.set_index("head")["speed_kmh"]
    assert pd.isna(by_head[0])
    assert by_head[1] == pytest.approx(0.13 / 0.004 * 3.6, rel=1e-3)


def test_each_head_pairs_at_its_own_resolution() -> None:
    # A whole-second head elsewhere in the log does not widen a millisecond head's window.
    rows = [(0, 1, 10.0, False), (0, 2, 10.0, False), (1, 1, 20.000, True), (1, 2, 20.900, True)]
    axles, unpaired = pair_axles(_onsets(rows), PairingSettings())
    assert list(axles["head"]) == [0] and unpaired == 2


def test_whole_second_log_pairs_but_times_no_axle(tmp_path: Path) -> None:
    lines = [
        record(ch=1, adr="026", label="Radsensor", data="1", time="09:00:00"),
        record(ch=2, adr="026", label="Radsensor", data="1", time="09:00:00"),
        record(ch=1, adr="026", label="Radsensor", data="1", time="09:00:03"),
        record(ch=2, adr="026", label="Radsensor", data="1", time="09:00:04"),
    ]
    (p,) = _analyze(tmp_path, lines)
    assert p["axles"] == 2
    assert p["speed_kmh_per_axle"] is None  # whole seconds cannot time 0.13 m
    assert p["direction"] == "sys1_to_sys2"  # the line order, and the pair split across seconds
    assert p["whole_train_basis"] == "detections"
    assert p["speed_kmh_whole_train"] == pytest.approx((28.6 + 0.13) / 4 * 3.6)


def test_overlapping_exports_count_once(tmp_path: Path) -> None:
    a, b = tmp_path / "a.log", tmp_path / "b.log"
    a.write_text("\n".join(record(time=f"09:00:0{i}") for i in range(4)) + "\n", encoding="utf-8")
    b.write_text("\n".join(record(time=f"09:00:0{i}") for i in range(2, 6)) + "\n", encoding="utf-8")
    job = whole_job([a, b], SpeedSettings())
    (p,) = job.analysis.passages_json()
    assert p["records"] == 6 and job.analysis.overlap_records == 2
    assert job.report.records == 8  # the parser still accounts for every line


def test_generated_log_round_trip(tmp_path: Path) -> None:
    """benchmarks/gen_diag_log.py: every record parses; each train is found at every head."""
    path = tmp_path / "gen.log"
    n = generate(5000, path, seed=7)
    job = whole_job([path], SpeedSettings())
    assert job.report.records == n and job.report.rejected == 0
    ps = job.analysis.passages_json()
    assert len(ps) % 4 == 0 and len(ps) >= 4
    for p in ps:
        assert p["axles"] == 8 and p["direction"] in ("sys1_to_sys2", "sys2_to_sys1")
        axle_mean = p["speed_kmh_per_axle_mean"]
        whole = p["speed_kmh_whole_train"]
        assert 3.0 * 3.6 * 0.9 < whole < 16.0 * 3.6 * 1.1
        if axle_mean is None:
            # Millisecond stamps cannot time a delay under 10 ms (0.13 m above 46.8 km/h) to 10 %.
            assert whole > 0.13 / 0.0105 * 3.6 and p["speed_kmh_per_axle"] is None
        else:
            # Constant speed: per-axle and whole-train agree within millisecond rounding
            # (a delay of at least 10 ms steps: within 10 %).
            assert whole == pytest.approx(axle_mean, rel=0.11)
    assert {d.device_id for d in job.analysis.devices} == {4081, 4082, 4083, 4084}
    assert all(d.designation == "TMC" and d.serial_number == "4803" for d in job.analysis.devices)
