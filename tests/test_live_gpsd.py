"""gpsd:// — a real gpsd fed by gpsfake with a real receiver capture (no mock of gpsd)."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest

from console.inputs.base import GnssFix, Item
from console.inputs.gpsd import GpsdSource
from parsers.gnss.lora import parse_time_rfc3339
from tests.live_fixtures import NMEA_DIR, GpsFake, wait_until

pytestmark = pytest.mark.timeout(90)

CAPTURE = NMEA_DIR / "haicom-305N.log"
DAY_NS = 86_400 * 10**9


def truth(capture: Path) -> set[tuple[int, float, float]]:
    """What gpsd itself decoded from the capture (the .chk file): fixes with a time of day.

    The capture's GGA carries no date, so a live gpsd dates it by its own clock:
    times are compared within the day."""
    out = set()
    for line in capture.with_name(capture.name + ".chk").read_text().splitlines():
        if line.startswith('{"class":"TPV"'):
            doc = json.loads(line)
            if doc.get("mode", 0) >= 2 and "time" in doc and "lat" in doc:
                t = parse_time_rfc3339(doc["time"])
                assert t is not None
                out.add((t % DAY_NS, round(doc["lat"], 6), round(doc["lon"], 6)))
    return out


class Got:
    def __init__(self) -> None:
        self.items: list[Item] = []
        self.lock = threading.Lock()

    def __call__(self, item: Item) -> None:
        with self.lock:
            self.items.append(item)

    def fixes(self) -> list[GnssFix]:
        with self.lock:
            return [i for i in self.items if isinstance(i, GnssFix)]


@pytest.fixture
def gpsfake() -> GpsFake:
    if not CAPTURE.exists():
        pytest.skip(f"{CAPTURE} is not there (the shared NMEA captures)")
    g = GpsFake(CAPTURE, cycle_s=0.01)
    g.start()
    yield g
    g.stop()


def test_tpv_fixes_from_gpsd_are_the_captures_fixes(gpsfake: GpsFake) -> None:
    src = GpsdSource(f"gpsd://127.0.0.1:{gpsfake.port}", "127.0.0.1", gpsfake.port)
    got = Got()
    src.start(got)
    try:
        # 60 s: on a machine at load 26 gpsfake had not fed its gpsd a sentence after 30 s
        assert wait_until(lambda: len(got.fixes()) >= 30, 60), src.status()
    finally:
        src.stop()
    known = truth(CAPTURE)
    seen = {(f.t_fix_ns % DAY_NS, round(f.lat_deg, 6), round(f.lon_deg, 6)) for f in got.fixes()}
    assert seen and seen <= known
    moving = [f for f in got.fixes() if f.speed_mps == f.speed_mps and f.speed_mps > 1]
    assert moving, "the capture moves: some fixes carry a speed"


def test_gpsd_restarted_mid_run_is_reconnected(gpsfake: GpsFake) -> None:
    src = GpsdSource(f"gpsd://127.0.0.1:{gpsfake.port}", "127.0.0.1", gpsfake.port)
    got = Got()
    src.start(got)
    try:
        assert wait_until(lambda: len(got.fixes()) >= 5, 30), src.status()
        gpsfake.stop()
        assert wait_until(lambda: not src.status().connected, 10)
        before = len(got.fixes())
        gpsfake.start()  # the same port
        assert wait_until(lambda: src.connects >= 2 and len(got.fixes()) >= before + 5, 30), src.status()
    finally:
        src.stop()
    kinds = [getattr(i, "kind", "") for i in got.items]
    assert kinds.count("connected") >= 2 and "disconnected" in kinds
