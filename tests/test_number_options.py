"""Number options of every command: nan, inf and absurd sizes are one-line usage errors, never internal errors.

Click's FloatRange lets nan through and inf or 1e308 past an open bound; found by fuzzing (each of these
gave an internal error or a silent nonsense before console.cli.options.finite_numbers).
"""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from tests.conftest import SAMPLES

LOG = str(SAMPLES / "ws4_subsecond.log")
STATION = str(SAMPLES / "example_station.log")

CASES = [
    (["analyze", LOG, "--idle-gap"], "--idle-gap"),
    (["analyze", LOG, "--json", "--spacing"], "--spacing"),
    (["analyze", LOG, "--train-length"], "--train-length"),
    (["speeds", LOG, "--idle-gap"], "--idle-gap"),
    (["sections", STATION, "--layout", "example", "--power-gap"], "--power-gap"),
    (["sections", STATION, "--layout", "example", "--isolation"], "--isolation"),
    (["approach", STATION, "--layout", "example", "--head", "WS3", "--distance"], "--distance"),
    (
        ["approach", STATION, "--layout", "example", "--head", "WS3", "--distance", "100", "--warning-time"],
        "--warning-time",
    ),
    (["frames", str(SAMPLES / "sensor_frames.txt"), "--comm-timeout"], "--comm-timeout"),
    (["follow", f"file:{LOG}", "--idle-exit", "1", "--idle-gap"], "--idle-gap"),
    (["follow", f"file:{LOG}", "--duration"], "--duration"),
    (["simulate", "-o", "never-written", "--trains-per-hour"], "--trains-per-hour"),
    (["simulate", "-o", "never-written", "--days"], "--days"),
    (["simulate", "-o", "never-written", "--live", "--speed"], "--speed"),
    (["speeds", LOG, "--spacing"], "--spacing"),
    (["speeds", LOG, "--train-length"], "--train-length"),
    (["follow", f"file:{LOG}", "--idle-exit"], "--idle-exit"),
    (["station", "--speed"], "--speed"),
]


def test_every_number_option_of_the_app_has_a_case_here() -> None:
    """A number option added later is in CASES too (the check is one for all, its proof per option)."""
    import typer

    group = typer.main.get_command(app)
    floats = {
        (name, max(p.opts, key=len))
        for name, cmd in group.commands.items()  # type: ignore[attr-defined]
        for p in cmd.params
        # Typer carries its own Click: its float types are known by name.
        if any(k.__name__ == "FloatParamType" for k in type(p.type).__mro__)
    }
    # follow --duration is a duration (30m), parsed by its command: nan and 1e308 are refused there.
    assert floats | {("follow", "--duration")} == {(args[0], option) for args, option in CASES}


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "1e308"])
@pytest.mark.parametrize(("args", "option"), CASES, ids=[f"{a[0]}{o}" for a, o in CASES])
def test_a_number_option_that_is_no_number_is_one_line(args: list[str], option: str, value: str) -> None:
    res = CliRunner().invoke(app, [*args, value])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("trackside: error: ") and res.stderr.count("\n") == 1, res.stderr
    assert option in res.stderr
    assert "internal error" not in res.output
    assert res.stdout == ""  # not half a JSON document first


@pytest.mark.parametrize("length", ["nan", "inf", "0", "-5", "1e308"])
def test_a_train_length_out_of_range_is_one_line(length: str) -> None:
    res = CliRunner().invoke(
        app,
        [
            "crossing",
            str(SAMPLES / "crossing_example.csv"),
            "--layout",
            "example",
            "--train",
            f"A=A-head,A-eot,{length}",
        ],
    )
    assert res.exit_code == 2, res.output
    assert "expected above 0 and at most 5000" in res.stderr and res.stderr.count("\n") == 1


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["analyze", "--spacing", "-1", LOG], "'--spacing': -1.0 is not in the range"),
        (["forecast", "--trend-days", "2"], "'--trend-days': 2 is not in the range 3<=x<=3650"),
        (["analyze"], "Missing argument 'FILE...'"),
        (["analyze", "--no-such-option", LOG], "No such option: --no-such-option"),
        (["no-such-command"], "No such command 'no-such-command'"),
    ],
)
def test_click_usage_errors_are_one_line_too(args: list[str], says: str) -> None:
    """The README promises one line for usage errors; Click writes usage, a hint and the error (three)."""
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("trackside: error: ") and res.stderr.count("\n") == 1, res.stderr
    assert says in res.stderr and "--help)" in res.stderr


def test_no_arguments_still_shows_the_help() -> None:
    res = CliRunner().invoke(app, [])
    assert "Usage: trackside [OPTIONS] COMMAND [ARGS]..." in res.output
    assert "Commands" in res.output
