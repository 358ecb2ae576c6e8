"""A command line naming a command builds that command alone: the same help, errors and exit codes as the
whole app gives, without importing the other commands (start-up of a short `trackside query`)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.cli.app import COMMANDS, app

ROOT = Path(__file__).resolve().parent.parent
# Runs the app as the `trackside` script does (or with its arguments given: the whole app), then lists the
# command modules it imported (on stderr).
_RUN = (
    "import sys, atexit; sys.argv[0] = 'trackside'; "
    "atexit.register(lambda: print(sorted(m for m in sys.modules if m.startswith('console.cli.commands.')), "
    "file=sys.stderr)); from console.cli.app import app; "
)


def _run(*args: str, whole: bool = False) -> tuple[int, str, str, str]:
    """Exit code, stdout, stderr and the command modules imported."""
    code = _RUN + ("app(args=sys.argv[1:])" if whole else "app()")
    p = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=ROOT, timeout=120)
    err, _, modules = p.stderr.rstrip("\n").rpartition("\n")
    return p.returncode, p.stdout, err, modules


@pytest.mark.parametrize(
    "args",
    [
        ("query", "--help"),
        ("report", "--help"),
        ("query", "--format"),  # an option without its value: a usage error
        ("report", "--bogus"),
        ("query", "--list-presets", "--format", "csv"),
    ],
)
def test_one_command_as_the_whole_app(args: tuple[str, ...]) -> None:
    one = _run(*args)
    whole = _run(*args, whole=True)
    assert one[:3] == whole[:3]
    # Only the named command's module (and what it imports itself: query takes ingest's --archive option).
    assert f"console.cli.commands.{args[0]}" in one[3]
    assert "console.cli.commands.analyze" not in one[3]
    assert "console.cli.commands.analyze" in whole[3]


def test_the_runner_sees_every_command() -> None:
    result = CliRunner().invoke(app, ["--help"])
    assert result.exit_code == 0
    assert all(f"  {name} " in result.stdout for name in COMMANDS)


def test_no_command_named_lists_them_all() -> None:
    code, out, _, _ = _run("--help")
    assert code == 0
    for name in COMMANDS:
        assert f"  {name} " in out
    code, _, err, _ = _run("quer")  # not a command: the whole app's error, with its suggestion
    assert code == 2 and "No such command 'quer'" in err
