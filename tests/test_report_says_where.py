"""`report -o FILE` says where it wrote, on stderr, when stderr is a terminal (a person); cron and pipes get
nothing."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
from pathlib import Path

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
TRACKSIDE = str(Path(sys.executable).with_name("trackside"))
ARGS = [str(SAMPLES / "example_station.log"), "--layout", "example", "--format", "html"]


def test_report_to_a_file_says_where_on_a_terminal(tmp_path: Path) -> None:
    out = tmp_path / "r.html"
    leader, follower = pty.openpty()
    try:
        proc = subprocess.run(
            [TRACKSIDE, "report", *ARGS, "-o", str(out)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=follower,
            timeout=120,
        )
        os.close(follower)
        said = b""
        while True:
            try:
                chunk = os.read(leader, 4096)
            except OSError:  # the terminal's other end is closed: all read
                break
            if not chunk:
                break
            said += chunk
    finally:
        os.close(leader)
    assert proc.returncode == 0
    assert proc.stdout == b""
    text = said.decode()
    assert f"wrote {out}" in text and "bytes" in text, text
    assert out.stat().st_size > 0


def test_report_to_a_file_is_quiet_when_stderr_is_not_a_terminal(tmp_path: Path) -> None:
    out = tmp_path / "r.html"
    proc = subprocess.run([TRACKSIDE, "report", *ARGS, "-o", str(out)], capture_output=True, timeout=120)
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, b"", b"")
    assert out.stat().st_size > 0
