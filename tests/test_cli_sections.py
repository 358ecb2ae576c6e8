"""`trackside sections`, `health`, `frames` and `analyze --layout` as a user runs them.

sample_logs/example_station.log and its truths: sample_logs/README.md.
"""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app

runner = CliRunner()
RESETS = ["--reset", "B1@2026-03-02T09:30:00", "--reset", "B2@2026-03-02T09:30:00"]


def _sections(samples: Path, *extra: str) -> dict:
    res = runner.invoke(
        app, ["sections", str(samples / "example_station.log"), "--layout", "example", "--json", *extra]
    )
    assert res.exit_code in (0, 1), res.output
    return json.loads(res.stdout)


def test_example_station_day(samples: Path) -> None:
    doc = _sections(samples, "--power-gap", "60", *RESETS, "--reset", "2G@2026-03-02T10:05:00")
    final = {s["section"]: s for s in doc["sections"]}
    assert {k: v["state"] for k, v in final.items()} == {"1G": "clear", "B1": "clear", "B2": "clear", "2G": "disturbed"}
    assert "power or contact lost at WS5" in final["2G"]["reason"]
    # The missed Sys2 wheel at WS3 at 09:04 disturbs B1 and B2 ...
    disturbed = [t for t in doc["timeline"] if t["state"] == "disturbed" and t["section"] in ("B1", "B2")]
    assert [t["time"][:19] for t in disturbed] == ["2026-03-02T09:04:01"] * 2
    assert all("Sys1 only at WS3" in t["reason"] for t in disturbed)
    # ... the resets are accepted, the sweep train clears them; the 2G reset is refused (WS5 dark).
    resets = [(r["section"], r["accepted"]) for r in doc["resets"]]
    assert resets == [("B1", True), ("B2", True), ("2G", False)]
    assert "no power or contact at WS5" in doc["resets"][2]["reason"]
    # The lone damping at WS2 at 10:30 holds 1G and B1, then releases them after 60 s of quiet.
    held = [t for t in doc["timeline"] if "2026-03-02T10:30" <= t["time"] < "2026-03-02T10:32"]
    # Occupied while the head is damped, then held as an isolated pulse, then clear after 60 s of quiet.
    states = [(t["section"], t["state"]) for t in held]
    assert states[:2] == [("1G", "occupied"), ("B1", "occupied")] and "WS2 damped" in held[0]["reason"]
    assert [t["reason"] for t in held[2:4]] == ["held: isolated pulse at WS2"] * 2
    assert states[4:] == [("1G", "clear"), ("B1", "clear")] and held[4]["time"] == "2026-03-02T10:31:00.000Z"


def test_without_resets_the_disturbed_sections_stay_disturbed(samples: Path) -> None:
    doc = _sections(samples)
    final = {s["section"]: s["state"] for s in doc["sections"]}
    assert final["B1"] == final["B2"] == "disturbed"
    assert final["2G"] == "clear"  # no --power-gap: a record gap is not read as power loss


def test_strict_exits_1_when_a_section_ends_disturbed(samples: Path) -> None:
    res = runner.invoke(app, ["sections", str(samples / "example_station.log"), "--layout", "example", "--strict"])
    assert res.exit_code == 1


def test_sections_table_marks_states_without_colour(samples: Path) -> None:
    res = runner.invoke(
        app, ["sections", str(samples / "example_station.log"), "--layout", "example"], env={"COLUMNS": "120"}
    )
    assert res.exit_code == 0
    assert "! disturbed" in res.output and "· clear" in res.output and "? preparatory" in res.output


def test_sections_errors_are_exit_2(samples: Path, tmp_path: Path) -> None:
    log = str(samples / "example_station.log")
    assert runner.invoke(app, ["sections", log, "--layout", str(tmp_path / "none.toml")]).exit_code == 2
    assert runner.invoke(app, ["sections", log, "--layout", "osong"]).exit_code == 2  # no sections
    res = runner.invoke(app, ["sections", log, "--layout", "example", "--reset", "B1@tomorrow-ish"])
    assert res.exit_code == 2 and "is not a date and time" in res.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text('[[heads]]\nid = "A"\nchainage_m = "x"\n', encoding="utf-8")
    res = runner.invoke(app, ["sections", log, "--layout", str(bad)])
    assert res.exit_code == 2 and "heads[0].chainage_m: expected a number" in res.stderr


def test_health_finds_the_failing_channel(samples: Path) -> None:
    res = runner.invoke(app, ["health", str(samples / "ws4_health.log"), "--json", "--fail-on", "critical"])
    assert res.exit_code == 1  # a critical finding reaches --fail-on
    doc = json.loads(res.stdout)
    crit = {(f["rule"], f["counting_head"], f["channel"]) for f in doc["findings"] if f["severity"] == "critical"}
    assert crit == {("analog_band", "WS5", 2), ("disturbance_rate", "WS5", 2)}


def test_health_voltage_table_alone(samples: Path) -> None:
    # Seed 000 Table 2: all twelve reliable; sensor 8 (186 mV) close to the 150 mV limit.
    res = runner.invoke(app, ["health", "--voltages", str(samples / "am_thuong_2021-06-06_voltages.csv"), "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    sev = {f["counting_head"]: f["severity"] for f in doc["findings"]}
    assert len(sev) == 12 and sev["8"] == "warning"
    assert all(v == "info" for k, v in sev.items() if k != "8")


def test_health_needs_some_input() -> None:
    assert runner.invoke(app, ["health"]).exit_code == 2


def test_frames_text_and_can_give_the_same_axles(samples: Path) -> None:
    def axles(name: str) -> list[tuple[str, str, int]]:
        res = runner.invoke(app, ["frames", str(samples / name), "--json"])
        assert res.exit_code == 0, res.output
        return [
            (e["time"], e["sensor"], e["direction"]) for e in json.loads(res.stdout)["events"] if e["kind"] == "axle"
        ]

    text = axles("sensor_frames.txt")
    assert len(text) == 8 + 8 + 4 and text == axles("can_counts.log") == axles("can_counts.asc")


def test_analyze_with_layout_adds_sections_and_health(samples: Path) -> None:
    res = runner.invoke(app, ["analyze", str(samples / "example_station.log"), "--layout", "example", "--json"])
    assert res.exit_code == 0
    doc = json.loads(res.stdout)
    assert {s["section"]: s["state"] for s in doc["sections"]}["B1"] == "disturbed"
    assert isinstance(doc["health"], list)
    kinds = [p["kind"] for p in doc["passages"]]
    assert kinds.count("train") == 4 * 5  # four trains past five heads
    assert kinds.count("damping") == 1  # the lone WS2 damping at 10:30: not a train


def test_a_reset_count_beside_totals_since_the_log_began_is_explained(samples: Path) -> None:
    log = str(samples / "example_station.log")
    reset = runner.invoke(app, ["sections", log, "--layout", "example", "--reset", "B1@2026-03-02T09:30"])
    assert reset.exit_code == 0, reset.output
    b1 = next(line.split() for line in reset.stdout.splitlines() if line.split()[:1] == ["B1"])
    count, n_in, n_out = (int(x) for x in b1[3:6])
    assert count != n_in - n_out  # the reset restarted the count, not the totals
    assert "In, Out: axles since the log began; Count: since the last sweep or reset" in reset.stdout


def test_a_reset_needs_a_section_of_the_layout_and_a_date_and_time(samples: Path) -> None:
    log = str(samples / "example_station.log")
    for reset, says in (
        ("B1@09:30", "is not a date and time"),  # not the machine's today: the log is from another day
        ("B1@9999-12-31T23:59:59", "outside 1970-2261"),
        ("B9@2026-03-02T09:30", "no section 'B9' in the layout"),
        ("B1@", "expected SECTION@DATE-TIME"),
    ):
        res = runner.invoke(app, ["sections", log, "--layout", "example", "--reset", reset])
        assert res.exit_code == 2, (reset, res.output)
        assert says in res.stderr and res.stderr.count("\n") == 1, res.stderr
    ok = runner.invoke(app, ["sections", log, "--layout", "example", "--reset", "B1@2026-03-02 09:30", "--json"])
    assert ok.exit_code == 0, ok.output
    (r,) = json.loads(ok.stdout)["resets"]
    assert r["section"] == "B1" and r["time"].startswith("2026-03-02T09:30:00")


def test_a_reset_outside_the_logs_span_is_decided_but_said(samples: Path) -> None:
    # A mistyped year: after the log it overrides B1's end state, before it moves every section's start there.
    doc = _sections(samples, "--reset", "B1@2030-03-02T09:30", "--reset", "B2@2020-03-02T09:30", *RESETS)
    outside = [w for w in doc["warnings"] if w.startswith("--reset")]
    assert len(outside) == 2
    after, before = outside
    assert after.startswith("--reset B1@2030-03-02T09:30:00") and "after the last record of the logs" in after
    assert before.startswith("--reset B2@2020-03-02T09:30:00") and "before the first record of the logs" in before
    text = runner.invoke(
        app, ["sections", str(samples / "example_station.log"), "--layout", "example", "--reset", "B1@2030-03-02"]
    )
    assert "warning: --reset B1@2030-03-02T00:00:00" in text.stdout


def test_a_log_without_detections_starts_its_sections_at_its_first_record_not_1970(
    samples: Path, tmp_path: Path
) -> None:
    # The Osong excerpt has records but no wheel on both systems: the start rows were timed 1970-01-01 00:00:00.
    res = runner.invoke(
        app, ["sections", str(samples / "osong_ws4_0932_detection.log"), "--layout", "example", "--json"]
    )
    assert res.exit_code == 0, res.output
    times = {t["time"] for t in json.loads(res.stdout)["timeline"]}
    assert times == {"2015-10-31T09:32:24.000Z"}, times
    text = runner.invoke(app, ["sections", str(samples / "osong_ws4_0932_detection.log"), "--layout", "example"])
    assert "1970" not in text.stdout and "2015-10-31 09:32:24" in text.stdout
    # An empty log has no time at all: no start rows timed 1970 either.
    empty = tmp_path / "empty.log"
    empty.write_bytes(b"")
    res = runner.invoke(app, ["sections", str(empty), "--layout", "example", "--json"])
    assert res.exit_code == 0, res.output
    assert "1970" not in res.stdout
