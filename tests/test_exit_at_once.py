"""The `trackside` program ends at once when its command is done (console.cli.app.run): the same output, exit
status and exit handlers as the app's normal exit, without the interpreter's teardown; and never while
another thread still runs."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
ROOT = Path(__file__).resolve().parent.parent
PROGRAM = "import sys; sys.argv[0] = 'trackside'; from console.cli.app import run; run()"
APP = "import sys; sys.argv[0] = 'trackside'; from console.cli.app import app; app()"


def _run(launch: str, *args: str, stdout: int | None = subprocess.PIPE, **kw: object) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(  # type: ignore[call-overload]
        [sys.executable, "-c", launch, *args], stdout=stdout, stderr=subprocess.PIPE, env=env, timeout=120, **kw
    )


@pytest.mark.parametrize(
    "args",
    [
        ("analyze", "--json", str(SAMPLES / "example_station.log")),
        ("speeds", str(SAMPLES / "example_station.log")),
        ("analyze", str(SAMPLES / "no_such.log")),  # a one-line error, exit 2
        ("analyze", "--no-such-option"),  # a usage error
        ("--version",),
    ],
)
def test_the_program_ends_as_the_app_does(args: tuple[str, ...]) -> None:
    program, app = _run(PROGRAM, *args), _run(APP, *args)
    assert program.returncode == app.returncode
    assert program.stdout == app.stdout
    assert program.stderr == app.stderr


def test_output_to_a_full_disk_is_the_same_one_line_failure() -> None:
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    args = ("analyze", "--json", str(SAMPLES / "example_station.log"))
    with open("/dev/full", "wb") as full:
        program = _run(PROGRAM, *args, stdout=full.fileno())
    with open("/dev/full", "wb") as full:
        app = _run(APP, *args, stdout=full.fileno())
    assert program.returncode == app.returncode != 0
    assert program.stderr == app.stderr
    assert b"Traceback" not in program.stderr


def test_exit_handlers_run_and_buffered_output_is_flushed() -> None:
    # An exit handler that writes, and text still in stdout's buffer when the command ends.
    launch = (
        "import atexit, sys; atexit.register(lambda: print('handler ran', file=sys.stderr)); "
        "sys.stdout.write('pending'); " + PROGRAM
    )
    out = _run(launch, "--version")
    assert out.returncode == 0
    assert out.stdout.startswith(b"pending")
    assert b"handler ran" in out.stderr


def test_a_thread_still_running_is_waited_for() -> None:
    # Ending at once would cut it off: its line would never be written.
    launch = (
        "import threading, time; "
        "t = threading.Thread(target=lambda: (time.sleep(0.5), print('thread done', flush=True))); t.start(); "
        + PROGRAM
    )
    out = _run(launch, "--version")
    assert out.returncode == 0
    assert b"thread done" in out.stdout
