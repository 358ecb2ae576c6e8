"""Per-axle speed and direction from Sys1 → Sys2 timing (sample_logs/README.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from console.analysis.passages.speed_settings import SpeedSettings
from tests.reads import whole_job


@pytest.fixture
def passages(samples: Path) -> list[dict]:
    job = whole_job([samples / "ws4_subsecond.log"], SpeedSettings())
    assert job.report.rejected == 0
    return job.analysis.passages_json()


def test_three_passages_trolley_is_not_a_train(passages: list[dict]) -> None:
    assert [p["axles"] for p in passages] == [8, 0, 8]
    trolley = passages[1]
    assert (trolley["detections_sys1"], trolley["detections_sys2"]) == (1, 0)
    assert trolley["speed_kmh_per_axle"] is None and trolley["direction"] is None


def test_per_axle_speeds_are_spacing_over_delay(passages: list[dict]) -> None:
    delays_ms = [26, 26, 27, 27, 28, 28, 29, 29]
    truth = [0.13 / (d / 1000) * 3.6 for d in delays_ms]
    assert passages[0]["speed_kmh_per_axle"] == pytest.approx(truth, abs=1e-3)
    assert passages[2]["speed_kmh_per_axle"] == pytest.approx([23.4] * 8, abs=1e-3)


def test_direction_from_channel_order(passages: list[dict]) -> None:
    assert passages[0]["direction"] == "sys1_to_sys2"
    assert passages[2]["direction"] == "sys2_to_sys1"


def test_whole_train_speed_uses_entering_and_leaving_system(passages: list[dict]) -> None:
    # (28.6 + 0.13) / 6.163 s and / 4.421 s (first entering onset → last leaving onset)
    assert passages[0]["speed_kmh_whole_train"] == pytest.approx(28.73 / 6.163 * 3.6, abs=1e-3)
    assert passages[2]["speed_kmh_whole_train"] == pytest.approx(28.73 / 4.421 * 3.6, abs=1e-3)
    assert passages[0]["whole_train_basis"] == "detections"
