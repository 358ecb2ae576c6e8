"""mqtt:// — LoRaWAN uplinks through a real mosquitto broker (no mock): ChirpStack v4 and
The Things Stack v3 messages, duplicates, fCnt gaps, 10,000 malformed messages, broker restart."""

from __future__ import annotations

import base64
import json
import random
import threading
from collections.abc import Iterator
from typing import Any

import pytest

from console.inputs.base import GnssFix, Item, SourceError
from console.inputs.mqtt import MqttSource
from console.inputs.uri import open_source
from parsers.gnss.lora import UnitReport, chirpstack_topic, chirpstack_uplink, encode_payload
from tests.live_fixtures import Mosquitto, mosquitto, wait_until  # noqa: F401 - the fixture

pytestmark = pytest.mark.timeout(90)

T0 = 1772437056 * 10**9
EUI_HEAD, EUI_EOT = "70b3d57ed0000101", "70b3d57ed0000102"


def report(k: int, role: str = "head") -> bytes:
    return encode_payload(UnitReport(role, 7, 20.98 + k * 1e-4, 105.84, 12.5, 90.0, 80.0, T0 + k * 10**9, True))


class Publisher:
    def __init__(self, port: int) -> None:
        import paho.mqtt.client as mqtt

        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="test-publisher")
        self.client.max_queued_messages_set(0)
        self.client.max_inflight_messages_set(1000)
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def send(self, topic: str, payload: bytes | str, qos: int = 1) -> Any:
        return self.client.publish(topic, payload, qos=qos)

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


@pytest.fixture
def publisher(mosquitto: Mosquitto) -> Iterator[Publisher]:  # noqa: F811
    p = Publisher(mosquitto.port)
    try:
        yield p
    finally:
        p.close()


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


def start(broker: Mosquitto, topic: str = "application/+/device/+/event/up") -> tuple[MqttSource, Got]:
    src = MqttSource(f"{broker.url}/{topic}", "127.0.0.1", broker.port, topic)
    got = Got()
    src.start(got)
    assert wait_until(lambda: src.status().connected, 10), src.status()
    return src, got


def cs(
    eui: str, f_cnt: int, payload: bytes, gateways: tuple[tuple[str, float, float], ...] = (("gw-1", -97, 7.5),)
) -> str:
    return json.dumps(chirpstack_uplink(eui, f_cnt, payload, T0 + f_cnt * 10**9, gateways=gateways))


def test_chirpstack_and_tts_uplinks_become_fixes_with_radio_data(mosquitto: Mosquitto, publisher: Publisher) -> None:  # noqa: F811
    src, got = start(mosquitto, "#")
    try:
        publisher.send(chirpstack_topic(EUI_HEAD), cs(EUI_HEAD, 1, report(1)))
        tts = {
            "end_device_ids": {"device_id": "eot-7", "dev_eui": EUI_EOT.upper()},
            "received_at": "2026-03-02T07:37:40Z",
            "uplink_message": {
                "f_cnt": 5,
                "f_port": 1,
                "frm_payload": base64.b64encode(report(2, "eot")).decode(),
                "rx_metadata": [{"gateway_ids": {"gateway_id": "g"}, "rssi": -120, "snr": -7.25}],
            },
        }
        publisher.send("v3/trackside@ttn/devices/eot-7/up", json.dumps(tts))
        assert wait_until(lambda: len(got.fixes()) == 2, 10)
    finally:
        src.stop()
    head, eot = sorted(got.fixes(), key=lambda f: f.role == "eot")
    assert (head.device, head.role, head.train, head.meta["f_cnt"]) == (EUI_HEAD, "head", "7", 1)
    assert head.meta["rssi_dbm"] == -97 and head.meta["network"] == "chirpstack"
    assert head.t_fix_ns == T0 + 10**9 and head.speed_mps == 12.5 and head.battery_pct == 80.0
    assert (eot.device, eot.role, eot.meta["snr_db"], eot.meta["network"]) == (EUI_EOT, "eot", -7.25, "tts")


def test_a_topic_ending_in_the_multi_level_wildcard_is_subscribed_as_written(
    mosquitto: Mosquitto,  # noqa: F811
    publisher: Publisher,
) -> None:
    # urlsplit read `#` as a URL fragment: `…/application/#` subscribed to `application/`, which no uplink is
    # published on, and the source sat connected and silent.
    src = open_source(f"{mosquitto.url}/application/#")
    got = Got()
    src.start(got)
    try:
        assert wait_until(lambda: src.status().connected, 10), src.status()
        assert src.status().detail == "subscribed to application/#"
        publisher.send(chirpstack_topic(EUI_HEAD), cs(EUI_HEAD, 1, report(1)))
        assert wait_until(lambda: len(got.fixes()) == 1, 10), src.status()
    finally:
        src.stop()


@pytest.mark.parametrize("topic", ["up#", "up/#/x", "up/#x"])
def test_a_wildcard_that_does_not_end_the_topic_is_refused(topic: str) -> None:
    with pytest.raises(SourceError, match="wildcard"):
        open_source(f"mqtt://127.0.0.1:1883/{topic}")


def test_duplicates_are_merged_and_fcnt_gaps_are_lost_uplinks(mosquitto: Mosquitto, publisher: Publisher) -> None:  # noqa: F811
    src, got = start(mosquitto)
    try:
        topic = chirpstack_topic(EUI_HEAD)
        for f_cnt in (1, 2, 2, 2, 6, 7, 4):  # 2 from three gateways; 3-5 missing, then 4 comes late
            publisher.send(topic, cs(EUI_HEAD, f_cnt, report(f_cnt), ((f"gw-{f_cnt}", -90, 5),)))
        assert wait_until(lambda: src.status().messages == 5 and src.status().duplicates == 2, 10), src.status()
    finally:
        src.stop()
    assert sorted(f.meta["f_cnt"] for f in got.fixes()) == [1, 2, 4, 6, 7]
    assert src.status().lost == 2  # 3 and 5
    assert src.ledger.devices[EUI_HEAD].duplicates == 2


def test_ten_thousand_malformed_messages_among_good_ones_are_counted_never_fatal(
    mosquitto: Mosquitto,  # noqa: F811
    publisher: Publisher,
) -> None:
    src, got = start(mosquitto)
    rng = random.Random(8)
    good_raw = report(1)
    bad_kinds = [
        lambda k: "{not json " + str(k),
        lambda k: json.dumps({"deviceInfo": {"devEui": EUI_HEAD}, "fCnt": k, "data": "!!not base64!!"}),
        lambda k: cs(EUI_HEAD, k, good_raw[: k % 21]),  # wrong length
        lambda k: cs(EUI_HEAD, k, good_raw[:3] + (2_000_000_000).to_bytes(4, "big") + good_raw[7:]),  # lat > 90
        lambda k: json.dumps([k]),
        lambda k: bytes([0xFF, 0xFE, k % 256]),
    ]
    topic = chirpstack_topic(EUI_HEAD)
    n_good = 0
    try:
        info = None
        for k in range(10_000):
            info = publisher.send(topic, rng.choice(bad_kinds)(k))
            if k % 100 == 0:
                n_good += 1
                info = publisher.send(topic, cs(EUI_HEAD, 100_000 + n_good, report(n_good)))
        assert info is not None
        info.wait_for_publish(30)
        assert wait_until(lambda: src.status().malformed == 10_000 and len(got.fixes()) == n_good, 40), src.status()
        assert src.status().connected
    finally:
        src.stop()
    shown = [i for i in got.items if getattr(i, "kind", "") == "malformed"]
    assert 20 <= len(shown) <= 40  # the first twenty one by one, then one per thousand
    assert src.status().lost == 0


def test_broker_restart_reconnects_resubscribes_and_duplicates_nothing(
    mosquitto: Mosquitto,  # noqa: F811
) -> None:
    src, got = start(mosquitto)
    topic = chirpstack_topic(EUI_EOT)
    try:
        pub = Publisher(mosquitto.port)
        for f_cnt in range(1, 6):
            pub.send(topic, cs(EUI_EOT, f_cnt, report(f_cnt, "eot")))
        assert wait_until(lambda: len(got.fixes()) == 5, 10)
        pub.close()
        mosquitto.restart()
        assert wait_until(lambda: src.connects >= 2 and src.status().connected, 20), src.status()
        pub = Publisher(mosquitto.port)
        # A network server replays its last uplinks after the outage, then goes on.
        for f_cnt in range(3, 11):
            pub.send(topic, cs(EUI_EOT, f_cnt, report(f_cnt, "eot"))).wait_for_publish(5)
        assert wait_until(lambda: len(got.fixes()) == 10 and src.status().duplicates == 3, 10), src.status()
        pub.close()
    finally:
        src.stop()
    assert sorted(f.meta["f_cnt"] for f in got.fixes()) == list(range(1, 11))
    kinds = [getattr(i, "kind", "") for i in got.items]
    assert "disconnected" in kinds and kinds.count("connected") >= 2
