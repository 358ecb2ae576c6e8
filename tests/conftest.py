"""Shared fixtures: paths to the shipped samples and a helper to write logs."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# The fuzz suite's long run (tests/test_fuzz_*.py): pytest -m fuzz --hypothesis-profile long
settings.register_profile("long", max_examples=2000, deadline=None, suppress_health_check=list(HealthCheck))
# Hypothesis's per-example deadline (200 ms) measures the machine's load, not the code: on a shared
# 2-core CI runner an example that takes 40 ms alone took 279 ms and failed the run.
settings.register_profile("default", deadline=None)
settings.load_profile("default")

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_logs"

RECORD = (
    "Diag_id:00002\tID:4083\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:WS4\tch:{ch}\tAdr:{adr}\t"
    "Label:{label}\tData:{data}\tDate:{date}\tTime:{time}"
)


def record(
    ch: int | str = 1,
    adr: str = "080",
    label: str = "Summenzä",
    data: str = "18",
    date: str = "2015-10-31",
    time: str = "09:32:24",
) -> str:
    """One diagnostic record line (no newline)."""
    return RECORD.format(ch=ch, adr=adr, label=label, data=data, date=date, time=time)


@pytest.fixture
def samples() -> Path:
    return SAMPLES
