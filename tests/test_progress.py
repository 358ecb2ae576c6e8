"""The progress bar: on a terminal for big inputs, silent otherwise."""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from rich.console import Console

from console.progress import MIN_BYTES_FOR_PROGRESS, byte_progress


def test_bar_on_a_terminal_for_big_inputs() -> None:
    buf = io.StringIO()
    term = Console(file=buf, force_terminal=True, width=80)
    with byte_progress(MIN_BYTES_FOR_PROGRESS * 2, "parsing", console=term) as advance:
        assert advance is not None
        advance(MIN_BYTES_FOR_PROGRESS)
    assert "parsing" in buf.getvalue()


def test_silent_when_not_a_terminal() -> None:
    buf = io.StringIO()
    with byte_progress(MIN_BYTES_FOR_PROGRESS * 2, "parsing", console=Console(file=buf)) as advance:
        assert advance is None
    assert buf.getvalue() == ""


def test_silent_for_small_inputs() -> None:
    term = Console(file=io.StringIO(), force_terminal=True)
    with byte_progress(1000, "parsing", console=term) as advance:
        assert advance is None


def test_bar_shows_bytes_read_records_per_second_and_time_left() -> None:
    buf = io.StringIO()
    term = Console(file=buf, force_terminal=True, width=160)
    with byte_progress(MIN_BYTES_FOR_PROGRESS * 4, "parsing", console=term) as advance:
        assert advance is not None
        advance(MIN_BYTES_FOR_PROGRESS)
        advance.records(50_000)
        time.sleep(0.2)  # the bar refreshes 10 times a second
    shown = buf.getvalue()
    assert "records/s" in shown
    assert "4.2/16.8 MB" in shown  # bytes read of the total
    assert "-:--:--" in shown or re.search(r"\d+:\d\d:\d\d", shown)  # time remaining


@pytest.mark.skipif(sys.platform == "win32", reason="needs a pty")
def test_analyze_shows_progress_on_a_terminal_stderr_only(tmp_path: Path) -> None:
    """stderr a terminal (a pty): the bar with records/s; stdout (a pipe) gets the JSON alone."""
    import pty

    from benchmarks.gen_realistic_diag import generate
    from tests.live_fixtures import trackside

    log = tmp_path / "big.log"
    generate(60_000, log, boards=8)
    assert log.stat().st_size > MIN_BYTES_FOR_PROGRESS * 1.5
    master, slave = pty.openpty()
    env = {**os.environ, "TERM": "xterm", "COLUMNS": "160"}
    proc = subprocess.Popen(trackside("analyze", "--json", str(log)), stdout=subprocess.PIPE, stderr=slave, env=env)
    os.close(slave)
    seen = bytearray()
    reader = threading.Thread(target=lambda: _drain(master, seen), daemon=True)
    reader.start()
    out, _ = proc.communicate(timeout=120)
    reader.join(timeout=10)
    os.close(master)
    assert proc.returncode == 0
    assert json.loads(out)["parse_report"]["records"] > 0
    text = seen.decode("utf-8", "replace")
    assert "parsing" in text and "records/s" in text


def _drain(fd: int, into: bytearray) -> None:
    while True:
        try:
            data = os.read(fd, 65536)
        except OSError:  # the pty's other end closed
            return
        if not data:
            return
        into += data
