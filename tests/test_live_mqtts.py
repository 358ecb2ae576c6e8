"""mqtts:// — LoRaWAN uplinks over TLS from a real mosquitto whose certificate a test CA signed.

The CA and the broker's certificate are made in the test (``cryptography``);
``?ca=PATH`` names the CA.  Without it (system CAs only) or with another CA
the certificate does not verify: the source stays disconnected and says so.
"""

from __future__ import annotations

import json
import subprocess
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from console.inputs.base import GnssFix, Item, SourceError
from console.inputs.uri import open_source
from parsers.gnss.lora import UnitReport, chirpstack_topic, chirpstack_uplink, encode_payload
from tests.live_fixtures import REPO, MosquittoTLS, self_signed_ca, trackside, wait_until

pytestmark = pytest.mark.timeout(60)

T0 = 1772437056 * 10**9
EUI = "70b3d57ed0000101"
TOPIC = "application/+/device/+/event/up"


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[MosquittoTLS]:
    b = MosquittoTLS(tmp_path)
    b.start()
    try:
        yield b
    finally:
        b.stop()


def publish_tls(broker: MosquittoTLS, f_cnts: list[int]) -> None:
    import paho.mqtt.client as mqtt

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="test-tls-publisher")
    client.tls_set(ca_certs=str(broker.ca))
    client.connect("127.0.0.1", broker.port)
    client.loop_start()
    try:
        for k in f_cnts:
            payload = encode_payload(UnitReport("head", 7, 20.98 + k * 1e-4, 105.84, 12.5, 90.0, 80.0, T0 + k * 10**9))
            info = client.publish(chirpstack_topic(EUI), json.dumps(chirpstack_uplink(EUI, k, payload, T0)), qos=1)
            info.wait_for_publish(5)
    finally:
        client.loop_stop()
        client.disconnect()


def collect(uri: str) -> tuple[object, list[Item], threading.Lock]:
    src = open_source(uri)
    src.check()
    got: list[Item] = []
    lock = threading.Lock()

    def sink(item: Item) -> None:
        with lock:
            got.append(item)

    src.start(sink)
    return src, got, lock


def test_uplinks_arrive_over_tls_with_the_ca_named_in_the_uri(broker: MosquittoTLS) -> None:
    src, got, lock = collect(f"{broker.url}/{TOPIC}?ca={broker.ca}")
    try:
        assert wait_until(lambda: src.status().connected, 15), src.status()  # type: ignore[attr-defined]
        publish_tls(broker, [1, 2, 4])
        assert wait_until(lambda: src.status().messages == 3, 10), src.status()  # type: ignore[attr-defined]
    finally:
        src.stop()  # type: ignore[attr-defined]
    with lock:
        fixes = [i for i in got if isinstance(i, GnssFix)]
    assert [f.meta["f_cnt"] for f in fixes] == [1, 2, 4]
    assert fixes[0].t_fix_ns == T0 + 10**9 and fixes[0].role == "head"
    assert src.status().lost == 1  # type: ignore[attr-defined]


def test_a_certificate_from_another_ca_is_refused_and_the_source_says_why(broker: MosquittoTLS, tmp_path: Path) -> None:
    other = tmp_path / "other"
    other.mkdir()
    wrong_ca, _, _ = self_signed_ca(other)
    src, _, _ = collect(f"{broker.url}/{TOPIC}?ca={wrong_ca}")
    try:
        assert wait_until(lambda: "certificate" in src.status().detail.lower(), 10), src.status()  # type: ignore[attr-defined]
        assert not src.status().connected  # type: ignore[attr-defined]
    finally:
        src.stop()  # type: ignore[attr-defined]


def test_a_missing_or_bad_ca_file_and_ca_on_plain_mqtt_are_setup_errors(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="not a readable PEM CA bundle"):
        open_source(f"mqtts://127.0.0.1:8883/{TOPIC}?ca={tmp_path / 'none.pem'}").check()
    junk = tmp_path / "junk.pem"
    junk.write_text("not a certificate\n")
    with pytest.raises(SourceError, match="not a readable PEM CA bundle"):
        open_source(f"mqtts://127.0.0.1:8883/{TOPIC}?ca={junk}").check()
    with pytest.raises(SourceError, match=r"\?ca= is for mqtts://"):
        open_source(f"mqtt://127.0.0.1:1883/{TOPIC}?ca={junk}")


def test_follow_reads_uplinks_over_tls(broker: MosquittoTLS) -> None:
    proc = subprocess.Popen(
        trackside("follow", "--jsonl", "--duration", "20", f"{broker.url}/{TOPIC}?ca={broker.ca}"),
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = json.loads(proc.stdout.readline())
        assert (first["type"], first["kind"]) == ("source", "connected"), first
        publish_tls(broker, [10, 13])
        lost = json.loads(proc.stdout.readline())
        assert (lost["type"], lost["kind"]) == ("source", "lost"), lost
        assert "2" in lost["detail"]
    finally:
        proc.terminate()
        proc.communicate(timeout=20)
