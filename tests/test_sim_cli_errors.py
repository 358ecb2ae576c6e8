"""simulate on a layout the simulator cannot run: one line, exit 2, before any work."""

from __future__ import annotations

import json
from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app
from console.layouts import __file__ as layouts_init


def test_simulate_on_a_layout_without_consists_is_a_usage_error(tmp_path: Path) -> None:
    example = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    kept, skipping = [], False
    for line in example.splitlines():
        if line.strip() == "[[consists]]":
            skipping = True
        elif line.startswith("[") and skipping:
            skipping = False
        if not skipping:
            kept.append(line)
    layout = tmp_path / "no_consists.toml"
    layout.write_text("\n".join(kept) + "\n", encoding="utf-8")
    result = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "60s", "--layout", str(layout)]
    )
    assert result.exit_code == 2
    assert "needs [[consists]]" in result.output
    assert "internal error" not in result.output
    assert not (tmp_path / "run").exists()


def test_simulate_on_a_layout_with_a_spaced_head_id_is_a_usage_error(tmp_path: Path) -> None:
    # The run's sensor_frames.txt ("<time> <sensor> <frame>") could not carry it: frames rejected every line of it.
    example = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    layout = tmp_path / "spaced.toml"
    layout.write_text(example.replace('"WS3"', '"WS 3"'), encoding="utf-8")
    result = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "60s", "--layout", str(layout)]
    )
    assert result.exit_code == 2, result.output
    assert "head 'WS 3': the simulator writes head ids into sensor frames" in result.stderr
    assert result.stderr.count("\n") == 1 and "internal error" not in result.output
    assert not (tmp_path / "run").exists()


def test_fault_rates_and_times_out_of_range_are_one_line_usage_errors(tmp_path: Path) -> None:
    for fault, says in (
        ("analog_drift:WS3:0s::1:1e308", "at most 10000 counts/day"),
        ("disturbance_growth:WS3:0s::1:1e308", "at most 10000 per hour, each day"),
        ("disturbance_growth:WS3:0s::1:nan", "rate must be above 0"),
        ("gnss_decay:T1-eot:0s::1:2", "at most 1 share/day"),
        ("dead_channel:WS3:5m:1m", "END must come after START"),
        # Said in the option's words, not int()'s or float()'s ("invalid literal for int() with base 10").
        ("dead_channel:WS3:5m::x", "channel must be 1 or 2, found 'x'"),
        ("dead_channel:WS3:5m::1.5", "channel must be 1 or 2, found '1.5'"),
        ("analog_drift:WS3:0s::1:fast", "RATE: expected a number, found 'fast'"),
    ):
        result = CliRunner().invoke(
            app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "20m", "--fault", fault]
        )
        assert result.exit_code == 2, (fault, result.output)
        assert says in result.stderr and result.stderr.count("\n") == 1, result.stderr
        assert "internal error" not in result.output
        assert not (tmp_path / "run").exists()


def test_the_summary_says_what_each_file_holds_in_words(tmp_path: Path) -> None:
    run = tmp_path / "run"
    result = CliRunner().invoke(app, ["simulate", "-o", str(run), "--duration", "20m"])
    assert result.exit_code == 0, result.output
    out = result.stdout
    assert "{" not in out and "'" not in out  # no Python dict shown
    assert f"{run / 'diagnostic.log'}: " in out and " lines" in out
    assert f"{run / 'nmea'}/: T1-head " in out and " fixes" in out
    for name in ("gnss_devices.csv", "layout.toml"):
        assert str(run / name) in out and (run / name).is_file()


def test_a_duration_past_two_days_points_to_days(tmp_path: Path) -> None:
    for duration in ("99999999d", "3d", "0s"):
        result = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "run"), "--duration", duration])
        assert result.exit_code == 2, (duration, result.output)
        assert "between 1s and 2d (longer runs: --days N" in result.stderr and result.stderr.count("\n") == 1
    assert not (tmp_path / "run").exists()


def test_a_live_run_of_no_time_is_refused(tmp_path: Path) -> None:
    # --live --duration 0s wrote a run's first records, said "simulated 0 s" and exited 0.
    result = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "run"), "--live", "--duration", "0s"])
    assert result.exit_code == 2, result.output
    assert result.stderr == "trackside: error: --duration: a live run lasts more than 0s\n"
    assert not (tmp_path / "run").exists()


def test_a_fault_for_a_train_that_never_ran_is_said(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "20m", "--fault", "train_parting:T9:1m"]
    )
    assert result.exit_code == 0, result.output
    assert "--fault train_parting:T9: no train T9 ran (T1, T2); nothing was injected" in result.stderr
    ok = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run2"), "--duration", "20m", "--fault", "train_parting:T1:5m"]
    )
    assert ok.exit_code == 0 and "warning" not in ok.stderr


def test_a_gnss_decay_of_a_unit_whose_train_never_ran_is_said(tmp_path: Path) -> None:
    # It was silent: the truth listed the fault, the run had no T9 to wear.
    run = ["simulate", "--duration", "20m", "--fault"]
    result = CliRunner().invoke(app, [*run, "gnss_decay:T9-eot:0s::2:0.02", "-o", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert "--fault gnss_decay:T9-eot: no train T9 ran (T1, T2); nothing was injected" in result.stderr
    ok = CliRunner().invoke(app, [*run, "gnss_decay:T1-eot:0s::2:0.02", "-o", str(tmp_path / "run2")])
    assert ok.exit_code == 0 and "warning" not in ok.stderr


def test_a_parting_after_the_train_left_the_line_is_said(tmp_path: Path) -> None:
    # T1 runs the line from 1 min to about 9: a parting at 10m never happened, and nothing said so.
    run = ["simulate", "--duration", "30m", "--fault"]
    late = CliRunner().invoke(app, [*run, "train_parting:T1:10m", "-o", str(tmp_path / "run")])
    assert late.exit_code == 0, late.output
    assert (
        "--fault train_parting:T1: T1 did not run at or after 2026-03-02 08:10:00; nothing was injected" in late.stderr
    )
    assert json.loads((tmp_path / "run" / "truth.json").read_text("utf-8"))["partings"] == []
    ok = CliRunner().invoke(app, [*run, "train_parting:T2:10m", "-o", str(tmp_path / "run2")])
    assert ok.exit_code == 0 and "warning" not in ok.stderr


def test_a_unit_loss_while_the_train_was_off_the_line_is_said(tmp_path: Path) -> None:
    # T1 runs from about 1 min to 9: an EOT loss from 25m lost nothing, and nothing said so.
    run = ["simulate", "--duration", "30m", "--fault"]
    late = CliRunner().invoke(app, [*run, "eot_loss:T1:25m", "-o", str(tmp_path / "run")])
    assert late.exit_code == 0, late.output
    assert (
        "--fault eot_loss:T1: T1 was not running from 2026-03-02 08:25:00 to the fault's end, no EOT report to"
        " lose; nothing was injected" in late.stderr
    )
    for fault in ("eot_loss:T1:5m", "head_loss:T1:2m:3m"):
        ok = CliRunner().invoke(app, [*run, fault, "-o", str(tmp_path / fault.replace(":", "_"))])
        assert ok.exit_code == 0 and "warning" not in ok.stderr, (fault, ok.stderr)


def test_the_days_summary_counts_in_words(tmp_path: Path) -> None:
    # plural.count's rule: a single thing is never "1 days" (it said "1 days written", "1 heads" on osong).
    result = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run"), "--days", "1", "--health-only", "--layout", "osong"]
    )
    assert result.exit_code == 0, result.output
    line = " ".join(result.stdout.split())
    assert line.startswith("simulated 1 day of health registers of 1 head on ")
    assert "0 trips; 1 day written into " in line


def test_heads_off_the_track_are_said(tmp_path: Path) -> None:
    # A head beyond the track polyline is never passed: the run had no axle passage there, without a word.
    example = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    layout = tmp_path / "off.toml"
    layout.write_text(
        example.replace('"WS5"\ndevice_id = 4085\nchainage_m = 13950', '"WS5"\ndevice_id = 4085\nchainage_m = 99950'),
        encoding="utf-8",
    )
    result = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "20m", "--layout", str(layout), "--json"]
    )
    assert result.exit_code == 0, result.output
    assert "warning: 1 counting head outside the track (10000 to 14200 m)" in result.stderr
    assert result.stderr.rstrip().endswith(": WS5") and result.stderr.count("\n") == 1
    truth = json.loads((tmp_path / "run" / "truth.json").read_text(encoding="utf-8"))
    assert truth["axles"] and not [a for a in truth["axles"] if a["head"] == "WS5"]
    ok = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "run2"), "--duration", "1m"])
    assert ok.exit_code == 0 and "warning" not in ok.stderr


def test_a_layout_name_with_control_characters_is_shown_escaped(tmp_path: Path) -> None:
    # The summary printed the [line] name raw: an escape sequence in a layout recoloured the terminal.
    example = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    layout = tmp_path / "named.toml"
    layout.write_text(example.replace('name = "Example line:', 'name = "\\u001b[31mRed line:', 1), encoding="utf-8")
    for args in (["--duration", "1m"], ["--days", "0.01", "--health-only"]):
        result = CliRunner().invoke(
            app, ["simulate", "-o", str(tmp_path / "run"), "--replace", "--layout", str(layout), *args]
        )
        assert result.exit_code == 0, result.output
        assert "\x1b" not in result.stdout and "on \\x1b[31mRed line:" in result.stdout


def test_a_fault_that_starts_after_the_run_ends_is_refused(tmp_path: Path) -> None:
    # --fault dead_channel:WS3:40m --duration 30m ran a clean run, said nothing and exited 0.
    for args in (["--duration", "30m"], ["--days", "1"]):
        start = "40m" if args[0] == "--duration" else "2d"
        result = CliRunner().invoke(
            app, ["simulate", "-o", str(tmp_path / "run"), *args, "--fault", f"dead_channel:WS3:{start}"]
        )
        assert result.exit_code == 2, (args, result.output)
        assert result.stderr.count("\n") == 1 and "after the run ends" in result.stderr, result.stderr
    assert not (tmp_path / "run").exists()
    ok = CliRunner().invoke(
        app, ["simulate", "-o", str(tmp_path / "ok"), "--duration", "30m", "--fault", "dead_channel:WS3:29m"]
    )
    assert ok.exit_code == 0, ok.output


def test_days_and_duration_together_are_refused(tmp_path: Path) -> None:
    # --days 0.5 --duration 1h simulated half a day and dropped --duration without a word.
    result = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "run"), "--days", "0.5", "--duration", "1h"])
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and "--days" in result.stderr and "--duration" in result.stderr
    assert not (tmp_path / "run").exists()


def test_a_bare_duration_is_said_in_seconds(tmp_path: Path) -> None:
    # --duration 30 is 30 s: the summary said "simulated 30 on …: 0 trains", leaving the unit to guess.
    result = CliRunner().invoke(app, ["simulate", "-o", str(tmp_path / "run"), "--duration", "30"])
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("simulated 30s on "), result.stdout
