"""Every metric trackside exposes follows Prometheus' naming rules for units (base units, ``_total`` on
counters), checked in Python always and by ``promtool check metrics`` where it is installed."""

from __future__ import annotations

import re
import subprocess

import pytest
from prometheus_client import generate_latest
from prometheus_client.parser import text_string_to_metric_families

from console.analysis.health.forecast import Forecast
from console.layout import load_layout
from console.sinks.metrics import MetricsSink, forecast_exposition
from parsers.units import NS_PER_DAY
from tests.live_fixtures import need

# Units Prometheus has a base unit for: a name must carry the base one (seconds, bytes, meters, ...).
NOT_BASE = re.compile(
    r"_(days?|hours?|minutes?|milliseconds?|microseconds?|nanoseconds?|ms|us|ns|kilobytes|megabytes|"
    r"kilometers|km|millimeters|mm|celsius|millivolts|mv|percent)(_|$)"
)
LAST_DAY_END = 20_543 * NS_PER_DAY


def unit_problems(text: str) -> list[str]:
    """What promtool's lint says about units, in its terms, for an exposition."""
    out = []
    for fam in text_string_to_metric_families(text):
        if m := NOT_BASE.search(fam.name):
            out.append(f"{fam.name}: use the base unit instead of {m.group(1)!r}")
        if fam.type == "counter" and any(not s.name.endswith("_total") for s in fam.samples):
            out.append(f"{fam.name}: a counter's samples end in _total")
    return out


def _forecasts() -> list[Forecast]:
    def one(target: str, status: str, crossing_days: float | None) -> Forecast:
        crossing = None if crossing_days is None else LAST_DAY_END + round(crossing_days * NS_PER_DAY)
        return Forecast(
            "analog_margin", target, 2, status, 400.0, 20, LAST_DAY_END, 450.0, -3.0, -4.0, -2.0, 500.0,
            crossing, None, None, now_ns=LAST_DAY_END,
        )  # fmt: skip

    return [one("WS2", "due", 5.4), one("WS3", "past", -1.5), one("WS4", "due", None)]


def _live_exposition() -> str:
    sink = MetricsSink(load_layout("example"))
    sink.consume({"type": "crossing", "crossing": "11+850", "train": "T1", "kind": "on"})
    sink.consume({"type": "crossing", "crossing": "11+850", "train": "T1", "kind": "off", "lead_s": 40.0})
    return generate_latest(sink.registry).decode()


def test_the_forecast_textfile_names_its_time_left_in_seconds() -> None:
    text = forecast_exposition(_forecasts()).decode()
    assert unit_problems(text) == []
    left = {
        s.value
        for fam in text_string_to_metric_families(text)
        for s in fam.samples
        if s.name == "trackside_forecast_time_left_seconds"
    }
    assert sorted(left) == [-1.5 * 86400, pytest.approx(5.4 * 86400)]  # none for the series without a date
    assert "days_left" not in text


def test_the_live_metrics_use_base_units() -> None:
    assert unit_problems(_live_exposition()) == []


def test_the_rule_catches_a_days_name() -> None:
    bad = "# HELP x_days_left d\n# TYPE x_days_left gauge\nx_days_left 1.0\n"
    assert unit_problems(bad) == ["x_days_left: use the base unit instead of 'days'"]


@pytest.mark.parametrize("which", ["forecast", "live"])
def test_promtool_finds_nothing_to_lint(which: str) -> None:
    promtool = need("promtool")
    text = forecast_exposition(_forecasts()).decode() if which == "forecast" else _live_exposition()
    res = subprocess.run([promtool, "check", "metrics"], input=text, capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout + res.stderr == ""
