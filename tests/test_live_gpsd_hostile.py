"""gpsd:// against a hostile peer on loopback: every bad line counted once, never a fix, never a crash."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest

from console.inputs.gpsd import MAX_LINE_BYTES, GpsdSource
from tests.live_fixtures import wait_until
from tests.test_live_gpsd import Got

pytestmark = pytest.mark.timeout(60)


def tpv(**kw: object) -> bytes:
    doc = {"class": "TPV", "device": "/dev/ttyUSB0", "mode": 3, "lat": 20.75, "lon": 105.9}
    doc["time"] = time.strftime("%Y-%m-%dT%H:%M:%S.000Z", time.gmtime())
    doc.update(kw)
    return json.dumps(doc).encode() + b"\n"


def serve_once(payload: bytes) -> int:
    """A gpsd on 127.0.0.1 that answers one watcher with ``payload``, then hangs up."""
    srv = socket.create_server(("127.0.0.1", 0))

    def run() -> None:
        conn, _ = srv.accept()
        with conn:
            conn.recv(1024)  # ?WATCH
            conn.sendall(payload)
        srv.close()

    threading.Thread(target=run, daemon=True).start()
    return int(srv.getsockname()[1])


def follow(payload: bytes) -> tuple[GpsdSource, Got]:
    port = serve_once(payload)
    src = GpsdSource(f"gpsd://127.0.0.1:{port}", "127.0.0.1", port)
    got = Got()
    src.start(got)
    try:
        assert wait_until(lambda: any(getattr(i, "kind", "") == "disconnected" for i in got.items), 20)
    finally:
        src.stop()
    return src, got


def test_a_line_too_long_to_keep_is_one_malformed_line_and_the_next_is_read() -> None:
    huge = b'{"class":"TPV","pad":"' + b"A" * (80 * MAX_LINE_BYTES) + b'"}\n'
    src, got = follow(huge + tpv())
    assert src.status().malformed == 1  # was 41: one each time the buffer outgrew MAX_LINE_BYTES
    assert len(got.fixes()) == 1


def test_gpsd_hanging_up_mid_line_counts_the_cut_line() -> None:
    src, got = follow(tpv() + b'{"class":"TPV","mode":3,"lat":20.7')
    assert len(got.fixes()) == 1
    assert src.status().malformed == 1


@pytest.mark.parametrize(("lat", "lon"), [(1000.0, 105.9), (20.75, -5000.0), (1e308, 1e308)])
def test_a_position_off_the_globe_is_malformed_not_a_fix(lat: float, lon: float) -> None:
    src, got = follow(tpv(lat=lat, lon=lon) + tpv())
    assert [f.lat_deg for f in got.fixes()] == [20.75]
    assert src.status().malformed == 1
