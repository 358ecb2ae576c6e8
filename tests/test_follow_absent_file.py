"""``follow --idle-exit`` on a file that is not there (never was, or deleted): it ends, never waits forever.

Decided: a followed file still absent when nothing has arrived for the idle time is an error (one line, exit
2), and so is a source that never connected (gpsd, a broker not up); a file that appears within it is
followed; one deleted after its records ends as an idle follow does (the summary, exit 0)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.conftest import SAMPLES

TRACKSIDE = str(Path(sys.executable).with_name("trackside"))


@pytest.fixture
def follow() -> Iterator[Callable[..., subprocess.Popen[str]]]:
    """``follow FILE --idle-exit 1 …`` started; killed at the end if it is still running (it waited forever)."""
    started: list[subprocess.Popen[str]] = []

    def start(path: Path, *extra: str) -> subprocess.Popen[str]:
        p = subprocess.Popen(
            [TRACKSIDE, "follow", str(path), "--idle-exit", "1", *extra],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        started.append(p)
        return p

    yield start
    for p in started:
        if p.poll() is None:
            p.kill()
            p.communicate()


def _small_log(path: Path) -> None:
    lines = (SAMPLES / "example_station.log").read_text("utf-8").splitlines(keepends=True)
    path.write_text("".join(lines[:400]), "utf-8")


def test_a_file_that_never_appears_is_one_line_and_exit_2(tmp_path: Path) -> None:
    # It waited forever ("waiting for the file"): --idle-exit counted only from a first record.
    started = time.monotonic()
    p = subprocess.run(
        [TRACKSIDE, "follow", str(tmp_path / "none.log"), "--idle-exit", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert p.returncode == 2 and p.stdout == ""
    assert p.stderr.splitlines()[-1] == (
        f"trackside: error: {tmp_path / 'none.log'}: no such file (nothing arrived within --idle-exit 1 s)"
    )
    assert "Traceback" not in p.stderr and time.monotonic() - started < 30


def test_a_file_deleted_before_any_record_is_the_same_error(
    tmp_path: Path, follow: Callable[..., subprocess.Popen[str]]
) -> None:
    log = tmp_path / "ex.log"
    _small_log(log)
    p = follow(log, "--jsonl")  # from the end: nothing of it read
    time.sleep(0.5)
    log.unlink()
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2 and '"type": "passage"' not in out, err
    assert err.splitlines()[-1].endswith("ex.log: no such file (nothing arrived within --idle-exit 1 s)")


def test_a_file_that_appears_within_the_idle_time_is_followed(
    tmp_path: Path, follow: Callable[..., subprocess.Popen[str]]
) -> None:
    log = tmp_path / "late.log"
    p = follow(log, "--from-start", "--jsonl")
    time.sleep(0.3)
    _small_log(tmp_path / "late.tmp")
    shutil.move(tmp_path / "late.tmp", log)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    assert '"type": "passage"' in out and '"type": "summary"' in out


def test_a_file_deleted_after_its_records_ends_as_an_idle_follow(
    tmp_path: Path, follow: Callable[..., subprocess.Popen[str]]
) -> None:
    log = tmp_path / "ex.log"
    _small_log(log)
    p = follow(log, "--from-start", "--jsonl")
    deadline = time.monotonic() + 30
    assert p.stdout is not None
    while '"type": "passage"' not in p.stdout.readline():  # its records read
        assert time.monotonic() < deadline
    log.unlink()
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0, err
    assert '"type": "summary"' in out


def test_a_source_that_never_connects_is_one_line_and_exit_2() -> None:
    """gpsd (or a broker) not up: follow --idle-exit retried it forever, as a missing file."""
    from tests.live_fixtures import free_port

    uri = f"gpsd://127.0.0.1:{free_port()}"
    p = subprocess.run([TRACKSIDE, "follow", uri, "--idle-exit", "1"], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and p.stdout == ""
    assert p.stderr.splitlines()[-1] == (
        f"trackside: error: {uri}: never connected: cannot connect: Connection refused"
        " (nothing arrived within --idle-exit 1 s)"
    )


def test_a_stream_slow_to_write_is_still_waited_for() -> None:
    # A pipe is connected from the start: its writer may be slow, and the end of it ends follow (exit 0).
    p = subprocess.run(
        f"sleep 2 | {TRACKSIDE} follow - --idle-exit 1 --jsonl", shell=True, capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 0, p.stderr
    assert '"type": "summary"' in p.stdout
