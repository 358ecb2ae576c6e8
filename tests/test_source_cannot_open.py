"""A live source that cannot open says so at once (stderr; a `source` event with --jsonl), then retries;
and what the documented CAN walk-through needs is declared."""

from __future__ import annotations

import json
import selectors
import subprocess
import time
from importlib.metadata import requires

import pytest
from packaging.requirements import Requirement

from tests.live_fixtures import trackside

pytestmark = pytest.mark.timeout(60)
# No such CAN interface: socketcan cannot open it (no device, or no socketcan at all).
BUS = "can:socketcan:trackside-none0"
# "At once" is "long before the run is over": the line must come within WITHIN_S of the start, in a run of
# DURATION_S. The wait includes the command's start-up, which took over 6 s on a loaded 2-core runner (it
# failed at 6 s of 8), so both are generous; a note held back to the end of the run still fails.
DURATION_S = 60
WITHIN_S = 30


def _first_line(stream: object, within_s: float) -> tuple[str, float]:
    sel = selectors.DefaultSelector()
    sel.register(stream, selectors.EVENT_READ)  # type: ignore[arg-type]
    t0 = time.monotonic()
    assert sel.select(within_s), f"nothing within {within_s} s"
    return stream.readline(), time.monotonic() - t0  # type: ignore[attr-defined]


def test_a_bus_that_cannot_open_is_a_source_event_at_once_with_jsonl() -> None:
    proc = subprocess.Popen(
        trackside("follow", BUS, "--jsonl", "--duration", str(DURATION_S)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line, _ = _first_line(proc.stdout, WITHIN_S)  # start-up, then at once: long before the run is over
        ev = json.loads(line)
        assert ev["type"] == "source" and ev["source"] == BUS
        assert ev["kind"] == "disconnected" and "cannot open the bus" in ev["detail"] and "retrying" in ev["detail"]
        assert proc.poll() is None  # still running: it retries
    finally:
        proc.kill()
        proc.communicate()


def test_a_bus_that_cannot_open_says_so_on_stderr_at_once() -> None:
    proc = subprocess.Popen(
        trackside("follow", BUS, "--duration", str(DURATION_S)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line, _ = _first_line(proc.stderr, WITHIN_S)
        assert BUS in line and "cannot open the bus" in line and "retrying" in line
        assert proc.poll() is None
    finally:
        proc.kill()
        proc.communicate()


def test_the_can_walk_through_needs_nothing_undeclared() -> None:
    # python-can's udp_multicast interface (docs: a CAN bus between processes) imports msgpack.
    reqs = [Requirement(r) for r in requires("trackside") or []]
    can_req = next(r for r in reqs if r.name == "python-can" and not r.marker)
    assert "multicast" in can_req.extras
