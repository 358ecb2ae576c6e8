"""Sensor and channel health (console/analysis/health/: the rules and their findings; parsers/voltages.py).

Truths: seed 000 Table 2 (Âm Thượng station, 2021-06-06) and the generated
sample_logs/ws4_health.log (sample_logs/make_ws4_health.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from console.analysis.events.detection import DetectionEvent, EventKind
from console.analysis.health.band import BandSettings, analog_band_findings, learn_band
from console.analysis.health.channel_faults import channel_fault_findings
from console.analysis.health.disturbance import disturbance_rate_findings
from console.analysis.health.findings import Finding, Severity
from console.analysis.health.rules import health_report
from console.analysis.health.voltage import voltage_margin_findings
from parsers.diag.read import read_diag
from parsers.voltages import parse_voltage_text, read_voltages

NS = 1_000_000_000
PAPER_EXCERPTS = (
    "osong_ws4_0932_detection.log",
    "osong_ws4_0932_passage.log",
    "osong_ws4_1032_detection.log",
    "osong_ws4_1732_passage.log",
)


def ns(text: str) -> int:
    """``2015-10-31T07:50:00.512`` → ns since the epoch (naive)."""
    return int(pd.Timestamp(text).value)


def warnings_or_worse(findings: list[Finding]) -> list[Finding]:
    return [f for f in findings if f.severity >= Severity.WARNING]


@pytest.fixture(scope="module")
def health_log() -> pd.DataFrame:
    records, report = read_diag([Path(__file__).parent.parent / "sample_logs" / "ws4_health.log"])
    assert report.rejected == 0
    return records


@pytest.fixture(scope="module")
def health_findings(health_log: pd.DataFrame) -> list[Finding]:
    return health_report(health_log)


def one(findings: list[Finding], rule: str, head: str | None, channel: int | None) -> Finding:
    (found,) = [f for f in findings if f.rule == rule and f.counting_head == head and f.channel == channel]
    return found


def counter_records(head: str, channel: int, readings: list[tuple[str, int]], address: int = 88) -> pd.DataFrame:
    """A record table with only 1-edge counter readings (time text, value)."""
    n = len(readings)
    return pd.DataFrame(
        {
            "time": pd.to_datetime([t for t, _ in readings]),
            "counting_head": pd.Categorical([head] * n),
            "channel": np.full(n, channel, dtype=np.int8),
            "address": np.full(n, address, dtype=np.int16),
            "label_canonical": pd.Categorical(["counter_1_edge"] * n),
            "value": np.array([v for _, v in readings], dtype=np.int64),
        }
    )


def analog_records(head: str, channel: int, values: list[int], start: str = "2015-10-31 06:00") -> pd.DataFrame:
    n = len(values)
    return pd.DataFrame(
        {
            "time": pd.date_range(start, periods=n, freq="5min"),
            "counting_head": pd.Categorical([head] * n),
            "channel": np.full(n, channel, dtype=np.int8),
            "address": np.full(n, 134, dtype=np.int16),
            "label_canonical": pd.Categorical(["analog_value"] * n),
            "value": np.array(values, dtype=np.int64),
        }
    )


# --------------------------------------------------------------------------- severity and findings


def test_severity_is_ordered_info_warning_critical() -> None:
    assert Severity.INFO < Severity.WARNING < Severity.CRITICAL
    assert max([Severity.WARNING, Severity.CRITICAL, Severity.INFO]) is Severity.CRITICAL
    assert [s.rank for s in Severity] == [0, 1, 2]
    assert Severity.parse(" Warning ") is Severity.WARNING
    with pytest.raises(ValueError, match="expected one of info, warning, critical"):
        Severity.parse("fatal")


def test_finding_to_dict_is_json_ready() -> None:
    f = Finding(Severity.WARNING, "analog_band", "WS5", 2, "text", 2300.0, float("nan"), ns("2015-10-31T07:50:00"))
    d = json.loads(json.dumps(f.to_dict(), allow_nan=False))
    assert d["severity"] == "warning" and d["threshold"] is None
    assert d["time"] == "2015-10-31T07:50:00.000Z"


# --------------------------------------------------------------------------- voltage margin (seed 000)

# Seed 000, Table 2 (Âm Thượng, 2021-06-06): in-phase / anti-phase mV per sensor.
TABLE_2 = [
    (346, -152),
    (250, -128),
    (180, -157),
    (284, -171),
    (230, -110),
    (188, -71),
    (233, -345),
    (120, -66),
    (216, -200),
    (230, -133),
    (313, -75),
    (293, -110),
]
# Seed 000, Table 2, last column "Điện áp chênh lệch (mv)".
TABLE_2_MARGINS = [498, 378, 337, 455, 340, 259, 578, 186, 416, 363, 388, 403]


def test_table_2_all_sensors_reliable_and_sensor_8_watched() -> None:
    # Seed 000 §3: counting is reliable when in-phase − anti-phase > 150 mV; all
    # twelve sensors are. Sensor 8 (186 mV) is the only one within 25 % of 150.
    table = pd.DataFrame(
        {
            "sensor": [str(i) for i in range(1, 13)],
            "in_phase_mv": [a for a, _ in TABLE_2],
            "anti_phase_mv": [b for _, b in TABLE_2],
        }
    )
    findings = voltage_margin_findings(table)
    assert [f.value for f in findings] == TABLE_2_MARGINS
    assert [f.counting_head for f in findings if f.severity is Severity.WARNING] == ["8"]
    assert all(f.severity is Severity.INFO for f in findings if f.counting_head != "8")
    assert "reliable, margin 498 mV" in findings[0].message


def test_margin_at_or_below_threshold_is_critical() -> None:
    table = pd.DataFrame({"sensor": ["A", "B"], "in_phase_mv": [100.0, 100.0], "anti_phase_mv": [-50.0, -20.0]})
    assert [f.severity for f in voltage_margin_findings(table)] == [Severity.CRITICAL, Severity.CRITICAL]


def test_no_phase_reversal_is_critical_whatever_the_margin() -> None:
    table = pd.DataFrame({"sensor": ["A"], "in_phase_mv": [400.0], "anti_phase_mv": [20.0]})
    (f,) = voltage_margin_findings(table)
    assert f.severity is Severity.CRITICAL and "does not reverse phase" in f.message


def test_am_thuong_sample_csv_reads_table_2_with_vietnamese_header(samples: Path) -> None:
    table, report = read_voltages([samples / "am_thuong_2021-06-06_voltages.csv"])
    report.check()
    assert (report.records, report.rejected) == (12, 0)
    assert table["sensor"].tolist() == [str(i) for i in range(1, 13)]
    assert list(zip(table["in_phase_mv"], table["anti_phase_mv"], strict=True)) == TABLE_2
    assert table["difference_mv"].tolist() == TABLE_2_MARGINS
    severities = [f.severity for f in voltage_margin_findings(table)]
    assert severities.count(Severity.WARNING) == 1 and Severity.CRITICAL not in severities


def test_voltages_accept_decimal_commas_and_english_header() -> None:
    text = "sensor;in_phase_mv;anti_phase_mv\nA;346,5;−152,25\nB;120;-66\n"
    table, report = parse_voltage_text(text, "v.csv")
    assert report.rejected == 0
    assert table["in_phase_mv"].tolist() == [346.5, 120.0]
    assert table["anti_phase_mv"].tolist() == [-152.25, -66.0]


def test_voltages_quoted_decimal_commas_in_comma_separated_file() -> None:
    text = 'Vị trí cảm biến,Điện áp chính pha (mV),Điện áp ngược pha (mV)\n1,"346,5","-152,5"\n'
    table, report = parse_voltage_text(text, "v.csv")
    assert report.rejected == 0 and table["in_phase_mv"].tolist() == [346.5]


def test_voltages_bad_row_is_rejected_with_file_line_and_reason() -> None:
    text = "sensor,in_phase_mv,anti_phase_mv\n1,346,-152\n2,abc,-128\n3,180\n\n"
    table, report = parse_voltage_text(text, "v.csv")
    report.check()
    assert table["sensor"].tolist() == ["1"]
    assert [(r.file, r.line) for r in report.rejections] == [("v.csv", 3), ("v.csv", 4)]
    assert "in_phase_mv: expected a number in mV" in report.rejections[0].reason
    assert "found 'abc'" in report.rejections[0].reason
    assert report.rejections[1].reason == "expected 3 fields, found 2"
    assert report.blank == 2  # the header and the blank line


def test_voltages_wrong_difference_is_rejected() -> None:
    text = "Vị trí cảm biến,Điện áp chính pha (mv),Điện áp ngược pha (mv),Điện áp chênh lệch (mv)\n1,346,-152,500\n"
    table, report = parse_voltage_text(text, "v.csv")
    assert table.empty
    (rej,) = report.rejections
    assert rej.line == 2
    assert rej.reason == "difference_mv: 500 mV does not equal in − anti = 346 − (-152) = 498 mV"


def test_voltages_lines_before_the_header_are_rejected() -> None:
    text = "Bảng 2 Tham số điện áp\nsensor,in_phase_mv,anti_phase_mv\n1,346,-152\n"
    table, report = parse_voltage_text(text, "v.csv")
    report.check()
    assert len(table) == 1
    (rej,) = report.rejections
    assert rej.line == 1 and rej.reason.startswith("not the header: unknown column 'Bảng 2 Tham số điện áp'")


def test_voltages_duplicate_sensor_is_rejected() -> None:
    text = "sensor,in_phase_mv,anti_phase_mv\n1,346,-152\n1,250,-128\n"
    _, report = parse_voltage_text(text, "v.csv")
    assert report.rejections[0].reason == "sensor '1' already given on line 2"


# --------------------------------------------------------------------------- analog band


def test_learned_band_is_median_plus_minus_six_mad_floored_at_two_percent() -> None:
    quiet = np.array([2400.0] * 20)
    assert learn_band(quiet)[:2] == (2352.0, 2448.0)  # MAD 0: ± 2 % of 2400
    noisy = np.array([2400.0 + (10 if i % 2 else -10) for i in range(40)])
    low, high, used = learn_band(noisy)
    assert used == 10  # the first quarter of 40
    assert (low, high) == (2340.0, 2460.0)  # MAD 10 → ± 60


def test_learned_band_uses_the_first_part_so_a_drift_cannot_hide() -> None:
    values = [2400] * 20 + [2400 - 10 * k for k in range(1, 21)]  # drifts down 200 over the second half
    (f,) = analog_band_findings(analog_records("WS9", 1, values))
    assert f.severity is Severity.CRITICAL
    assert f.threshold == 2352.0


def test_given_band_overrides_the_learned_one(health_log: pd.DataFrame) -> None:
    learned = {(f.counting_head, f.channel): f for f in analog_band_findings(health_log)}
    assert learned[("WS4", 1)].severity is Severity.INFO
    given = {(f.counting_head, f.channel): f for f in analog_band_findings(health_log, {"WS4": (2430.0, 2500.0)})}
    # WS4 Sys1 reads 2399–2421: below a band set at 2430–2500 from its first value.
    assert given[("WS4", 1)].severity is Severity.CRITICAL
    assert given[("WS4", 1)].threshold == 2430.0
    assert given[("WS4", 1)].time_ns == ns("2015-10-31T06:00:00.007")
    assert "set in the layout" in given[("WS4", 1)].message
    assert given[("WS5", 1)] == learned[("WS5", 1)]  # heads without a given band still learn theirs


def test_a_few_excursions_are_a_warning() -> None:
    values = [2400] * 30 + [2200] + [2400] * 9
    (f,) = analog_band_findings(analog_records("WS9", 2, values))
    assert f.severity is Severity.WARNING
    assert f.value == 2200.0 and f.time_ns == ns("2015-10-31T08:30:00")


def test_band_low_above_high_is_refused(health_log: pd.DataFrame) -> None:
    with pytest.raises(ValueError, match="low 2500 must be below high 2400"):
        analog_band_findings(health_log, {"WS4": (2500.0, 2400.0)})


def test_ws5_sys2_drift_is_critical_from_0750(health_findings: list[Finding]) -> None:
    # make_ws4_health.py: WS5 Sys2 drifts down 120 counts/h from 07:30; its band
    # learned from 06:00–07:00 is 2357–2453; the 07:50 dump's Adr 136 value is
    # the first below it.
    f = one(health_findings, "analog_band", "WS5", 2)
    assert f.severity is Severity.CRITICAL
    assert f.time_ns == ns("2015-10-31T07:50:00.512")
    assert f.threshold == pytest.approx(2356.9, abs=0.05)
    assert f.value == 2091.0
    assert "drifted below" in f.message


def test_ws5_sys2_disturbances_are_critical(health_findings: list[Finding]) -> None:
    # make_ws4_health.py: the rate climbs 100/h every hour from 07:30 (~200/h by 10:00).
    f = one(health_findings, "disturbance_rate", "WS5", 2)
    assert f.severity is Severity.CRITICAL
    assert f.time_ns == ns("2015-10-31T08:00:00.510")  # first 1-h window above 12/h
    assert f.value == pytest.approx(201.0)
    assert "above 60/h from 2015-10-31T08:40:00.51" in f.message


def test_healthy_head_and_channel_have_no_warnings(health_findings: list[Finding]) -> None:
    flagged = {(f.counting_head, f.channel) for f in warnings_or_worse(health_findings)}
    assert flagged == {("WS5", 2)}
    ws4 = [f for f in health_findings if f.counting_head == "WS4"]
    assert {f.rule for f in ws4} == {"analog_band", "disturbance_rate"} and len(ws4) == 4


def test_health_report_puts_critical_first(health_findings: list[Finding]) -> None:
    ranks = [f.severity.rank for f in health_findings]
    assert ranks == sorted(ranks, reverse=True)
    assert [(f.counting_head, f.channel) for f in health_findings if f.severity is Severity.INFO] == [
        ("WS4", 1),
        ("WS4", 1),
        ("WS4", 2),
        ("WS4", 2),
        ("WS5", 1),
        ("WS5", 1),
    ]


@pytest.mark.parametrize("name", [*PAPER_EXCERPTS, "ws4_subsecond.log"])
def test_shipped_healthy_logs_have_no_warnings(samples: Path, name: str) -> None:
    records, _ = read_diag([samples / name])
    assert warnings_or_worse(health_report(records)) == []


def test_paper_excerpts_together_have_no_warnings(samples: Path) -> None:
    records, _ = read_diag([samples / n for n in PAPER_EXCERPTS])
    findings = health_report(records)
    assert warnings_or_worse(findings) == []
    # 2416/2402 at 09:32 and 2417/2403 at 10:32 (seed 003) sit inside the learned band.
    assert one(findings, "analog_band", "WS4", 1).severity is Severity.INFO


# --------------------------------------------------------------------------- disturbance rate


def test_counter_reset_is_not_negative_growth() -> None:
    readings = [
        ("2015-10-31 06:00", 100),
        ("2015-10-31 06:30", 103),
        ("2015-10-31 07:00", 106),
        ("2015-10-31 07:10", 2),  # device restart: the counter starts again from 0
        ("2015-10-31 07:30", 5),
        ("2015-10-31 08:00", 8),
    ]
    (f,) = disturbance_rate_findings(counter_records("WS9", 1, readings))
    # growth 3 + 3 + 2 + 3 + 3 = 14 in 2 h; the 1-h windows see 6, 8 and 8.
    assert f.severity is Severity.INFO
    assert f.value == pytest.approx(8.0)
    assert "14 disturbances in 2.0 h (7.0/h overall, 1 counter reset seen)" in f.message


def test_clock_going_back_is_not_counter_resets() -> None:
    # A board's clock set back an hour at 08:00 (a reboot, a DST change of local time): the readings
    # are in the order the device wrote them, the counter rising by 1 every 10 minutes, 6/h.
    start = pd.Timestamp("2015-10-31 06:00")
    times = [start + pd.Timedelta(minutes=10 * k) for k in range(13)]  # 06:00 .. 08:00
    times += [t - pd.Timedelta(hours=1) for t in times[-1] + pd.Timedelta(minutes=10) * np.arange(1, 13)]
    readings = [(str(t), k) for k, t in enumerate(times)]
    (f,) = disturbance_rate_findings(counter_records("WS9", 1, readings))
    assert f.severity is Severity.INFO
    assert f"{len(readings) - 1} disturbances" in f.message
    assert "reset" not in f.message


def test_overlapping_exports_in_any_order_read_as_one_log() -> None:
    readings = [(f"2015-10-31 {6 + k // 6:02d}:{k % 6 * 10:02d}", 2 * k) for k in range(19)]  # 06:00 .. 09:00
    whole = disturbance_rate_findings(counter_records("WS9", 1, readings))
    early = counter_records("WS9", 1, readings[:12]).assign(file="a.log")
    late = counter_records("WS9", 1, readings[8:]).assign(file="b.log")  # repeats 4 readings of a.log
    for parts in ((early, late), (late, early)):
        assert disturbance_rate_findings(pd.concat(parts, ignore_index=True)) == whole


def test_disturbance_rate_thresholds() -> None:
    def verdict(per_hour: int) -> Severity:
        readings = [(f"2015-10-31 0{6 + h}:00", per_hour * h) for h in range(3)]
        (f,) = disturbance_rate_findings(counter_records("WS9", 2, readings))
        return f.severity

    assert [verdict(r) for r in (5, 12, 13, 60, 61)] == [
        Severity.INFO,
        Severity.INFO,
        Severity.WARNING,
        Severity.WARNING,
        Severity.CRITICAL,
    ]


def test_disturbance_rate_needs_ten_minutes_of_log() -> None:
    short = counter_records("WS9", 1, [("2015-10-31 06:00", 0), ("2015-10-31 06:05", 50)])
    assert disturbance_rate_findings(short) == []
    longer = counter_records("WS9", 1, [("2015-10-31 06:00", 0), ("2015-10-31 06:20", 50)])
    (f,) = disturbance_rate_findings(longer)
    assert f.severity is Severity.CRITICAL and f.value == pytest.approx(150.0)  # 50 in 20 min


# --------------------------------------------------------------------------- channel events

T0 = ns("2015-10-31T09:00:00")


def test_channel_fault_events_are_critical_per_head_and_channel() -> None:
    events = [
        DetectionEvent(T0 + 5 * NS, EventKind.CHANNEL_FAULT, "WS5", channel=2, source="diag"),
        DetectionEvent(T0 + 9 * NS, EventKind.CHANNEL_FAULT, "WS5", channel=2, source="diag"),
        DetectionEvent(T0 + 1 * NS, EventKind.CHANNEL_FAULT, "WS6", channel=None, source="frame"),
        DetectionEvent(T0 + 2 * NS, EventKind.AXLE, "WS5", direction=1, source="diag"),
    ]
    findings = channel_fault_findings(events)
    ws5 = one(findings, "faulty_channel", "WS5", 2)
    assert ws5.severity is Severity.CRITICAL
    assert ws5.time_ns == T0 + 5 * NS and ws5.value == 2.0
    assert "reported 2 times, first at 2015-10-31T09:00:05" in ws5.message
    whole = one(findings, "faulty_channel", "WS6", None)
    assert whole.severity is Severity.CRITICAL and whole.message.startswith("WS6 (whole head)")
    assert len(findings) == 2


def test_channel_fault_that_reported_ok_again_stays_critical() -> None:
    events = [
        DetectionEvent(T0, EventKind.CHANNEL_FAULT, "WS5", channel=1),
        DetectionEvent(T0 + 60 * NS, EventKind.CHANNEL_OK, "WS5", channel=1),
    ]
    (f,) = channel_fault_findings(events)
    assert f.severity is Severity.CRITICAL and "OK again at 2015-10-31T09:01:00" in f.message


def test_one_single_channel_event_is_a_trolley_three_are_a_warning() -> None:
    trolley = [DetectionEvent(T0, EventKind.SINGLE_CHANNEL, "WS4", channel=1)]
    (f,) = channel_fault_findings(trolley)
    assert f.severity is Severity.INFO
    failing = [DetectionEvent(T0 + k * 600 * NS, EventKind.SINGLE_CHANNEL, "WS4", channel=2) for k in range(3)]
    (g,) = channel_fault_findings(failing)
    assert g.severity is Severity.WARNING and g.value == 3.0 and g.time_ns == T0


def test_health_report_merges_events_and_voltages(health_log: pd.DataFrame, samples: Path) -> None:
    voltages, _ = read_voltages([samples / "am_thuong_2021-06-06_voltages.csv"])
    events = [DetectionEvent(T0, EventKind.CHANNEL_FAULT, "WS4", channel=1)]
    findings = health_report(health_log, events=events, voltages=voltages)
    critical = [(f.rule, f.counting_head, f.channel) for f in findings if f.severity is Severity.CRITICAL]
    assert critical == [
        ("faulty_channel", "WS4", 1),
        ("analog_band", "WS5", 2),
        ("disturbance_rate", "WS5", 2),
    ]
    warnings = [(f.rule, f.counting_head) for f in findings if f.severity is Severity.WARNING]
    assert warnings == [("voltage_margin", "8")]
    sensors = [f.counting_head for f in findings if f.rule == "voltage_margin" and f.severity is Severity.INFO]
    assert sensors == ["1", "2", "3", "4", "5", "6", "7", "9", "10", "11", "12"]  # natural order


def test_band_settings_sustained_rule_is_configurable() -> None:
    values = [2400] * 30 + [2300] * 3
    assert analog_band_findings(analog_records("WS9", 1, values))[0].severity is Severity.WARNING
    settings = BandSettings(sustained_samples=3)
    assert analog_band_findings(analog_records("WS9", 1, values), settings=settings)[0].severity is Severity.CRITICAL
