"""station --serve: every app process it starts for a browser tab exits when the tab or the server goes.

Real processes: the server (``trackside station --serve`` on a free loopback port), real headless Chromium
tabs opening the page, killed while their app is still starting; then no child may remain, and none spin.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.live_fixtures import free_port, port_open, trackside, wait_until

pytestmark = [
    pytest.mark.timeout(180),
    pytest.mark.skipif(shutil.which("chromium") is None, reason="Debian's chromium is not installed"),
]
TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def _ppid_and_cpu(pid: int) -> tuple[int, int] | None:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return None
    if fields[0] == "Z":
        return None  # exited, not yet reaped
    return int(fields[1]), int(fields[11]) + int(fields[12])  # ppid, utime + stime


def descendants(root: int) -> set[int]:
    """Every live process below ``root`` (children, their children…)."""
    parent = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit() and (info := _ppid_and_cpu(int(d.name))) is not None:
            parent[int(d.name)] = info[0]
    out: set[int] = set()
    frontier = {root}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier} - out
        out |= frontier
    return out


def apps(server: int) -> set[int]:
    """The served app processes (python running the station view) below the server."""
    found = set()
    for pid in descendants(server):
        with contextlib.suppress(OSError):
            if (
                b"station" in Path(f"/proc/{pid}/cmdline").read_bytes()
                and b"--serve" not in Path(f"/proc/{pid}/cmdline").read_bytes()
            ):
                found.add(pid)
    return found


def alive(pids: set[int]) -> set[int]:
    return {p for p in pids if _ppid_and_cpu(p) is not None}


def cpu_share(pids: set[int], seconds: float = 1.0) -> dict[int, float]:
    before = {p: info[1] for p in pids if (info := _ppid_and_cpu(p)) is not None}
    time.sleep(seconds)
    after = {p: info[1] for p in pids if (info := _ppid_and_cpu(p)) is not None}
    return {p: (after[p] - before[p]) / TICKS_PER_S / seconds for p in after if p in before}


@contextlib.contextmanager
def served(tmp: Path) -> Iterator[tuple[subprocess.Popen[bytes], int]]:
    port = free_port()
    server = subprocess.Popen(
        trackside("station", "--serve", "--host", "127.0.0.1", "--port", str(port), "--layout", "example"),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        env={**os.environ, "COLUMNS": "160"},
    )
    try:
        assert wait_until(lambda: port_open(port), 30), "the server did not listen"
        yield server, port
    finally:
        left = descendants(server.pid)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(server.pid, signal.SIGKILL)
        for pid in left:  # a child that left the group: never leave one behind
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        server.wait(10)


def tab(tmp: Path, port: int, name: str) -> subprocess.Popen[bytes]:
    """A real headless Chromium with the page open (its own process group, to kill it whole)."""
    return subprocess.Popen(
        [
            "chromium", "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--no-first-run", f"--user-data-dir={tmp / name}", "--remote-debugging-port=0",
            "--remote-debugging-address=127.0.0.1", f"http://127.0.0.1:{port}/",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )  # fmt: skip


def close(browser: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(browser.pid, signal.SIGKILL)
    browser.wait(10)


def test_a_tab_closed_while_its_app_starts_leaves_no_process(tmp_path: Path) -> None:
    with served(tmp_path) as (server, port):
        browser = tab(tmp_path, port, "early")
        try:
            assert wait_until(lambda: bool(apps(server.pid)), 60, 0.01), "no app was started for the tab"
            started = descendants(server.pid)  # the app (and anything it runs), caught as it starts
        finally:
            close(browser)  # the tab goes while its app is still starting
        assert wait_until(lambda: not alive(started), 20, 0.1), f"left behind: {cpu_share(alive(started))}"
        assert server.poll() is None  # the server itself serves on
        # The server stops on Ctrl-C at once, and nothing is left; its exit code says Ctrl-C (README).
        os.kill(server.pid, signal.SIGINT)
        assert server.wait(15) == 130


def test_ctrl_c_to_the_server_alone_stops_every_app(tmp_path: Path) -> None:
    with served(tmp_path) as (server, port):
        browsers = [tab(tmp_path, port, f"tab{k}") for k in range(2)]
        try:
            assert wait_until(lambda: len(apps(server.pid)) >= 2, 90, 0.1), "two tabs, two apps"
            started = descendants(server.pid)
            os.kill(server.pid, signal.SIGINT)  # the server's PID alone, not its group
            server.wait(15)
            assert wait_until(lambda: not alive(started), 15, 0.1), f"left behind: {cpu_share(alive(started))}"
        finally:
            for b in browsers:
                close(b)


def _threads(pid: int) -> int:
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("Threads:"):
                return int(line.split()[1])
    return 0


def test_apps_exit_when_the_server_is_killed(tmp_path: Path) -> None:
    with served(tmp_path) as (server, port):
        browser = tab(tmp_path, port, "tab")
        try:
            # Up and drawing: the web driver's input and writer threads run beside the app's own.
            assert wait_until(lambda: any(_threads(p) >= 4 for p in apps(server.pid)), 60, 0.1)
            started = descendants(server.pid)
            server.kill()  # no chance to clean up: the apps notice their parent is gone
            server.wait(10)
            assert wait_until(lambda: not alive(started), 15, 0.1), f"left behind: {cpu_share(alive(started))}"
        finally:
            close(browser)
