"""``mqtt://HOST:PORT/TOPIC`` (and ``mqtts://``) — LoRaWAN uplinks as network servers publish them.

paho-mqtt 2.x does the protocol; this module only decides what an uplink
means:

* the message is decoded in one place (:mod:`parsers.gnss.lora`); anything that
  does not decode (bad JSON, bad base64, a wrong length, a value out of
  range) is counted as malformed and shown, never fatal;
* several gateways, a redelivery after a broker restart, or two network
  servers can hand over the same uplink: per device, an uplink already seen
  (same frame counter and payload) is a duplicate, merged, not repeated;
* a jump in a device's frame counter counts the uplinks in between as lost;
  one that turns up late is taken off the lost count again;
* the connection is retried with backoff, and the subscription is renewed
  on every connect (a restarted broker has forgotten it).
"""

from __future__ import annotations

import math
import ssl
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from typing import Any

from console.inputs.base import GnssFix, Source, SourceError
from console.plural import count
from parsers.gnss.lora import PayloadError, decode_payload, parse_uplink

SHOWN_MALFORMED = 20  # shown one by one; after that one note per 1000
SEEN_PER_DEVICE = 256  # frame counters remembered per device, for duplicates and late arrivals
RESET_BACK = 1000  # a counter this far below the last one: the device rejoined (counter reset)


@dataclass
class DeviceLedger:
    last_f_cnt: int | None = None
    seen: OrderedDict[int, bytes] = field(default_factory=OrderedDict)
    missing: set[int] = field(default_factory=set)
    lost: int = 0
    duplicates: int = 0
    uplinks: int = 0
    resets: int = 0


class UplinkLedger:
    """Per device: duplicates, frame-counter gaps (lost uplinks) and late arrivals."""

    def __init__(self) -> None:
        self.devices: dict[str, DeviceLedger] = {}

    def admit(self, dev_eui: str, f_cnt: int, payload: bytes) -> tuple[bool, int]:
        """(new uplink?, change in the lost count) for one received uplink."""
        d = self.devices.setdefault(dev_eui, DeviceLedger())
        prev = d.seen.get(f_cnt)
        if prev is not None and prev == payload:
            d.duplicates += 1
            return False, 0
        delta = 0
        if d.last_f_cnt is None:
            d.last_f_cnt = f_cnt
        elif f_cnt > d.last_f_cnt:
            gap = f_cnt - d.last_f_cnt - 1
            d.missing.update(range(d.last_f_cnt + 1, f_cnt) if gap <= 10_000 else ())
            delta = gap
            d.last_f_cnt = f_cnt
        elif f_cnt in d.missing:
            d.missing.discard(f_cnt)
            delta = -1
        elif d.last_f_cnt - f_cnt >= RESET_BACK or f_cnt == 0 or prev is not None:
            d.resets += 1  # rejoined: the counter starts again
            d.seen.clear()
            d.missing.clear()
            d.last_f_cnt = f_cnt
        d.lost += delta
        d.uplinks += 1
        d.seen[f_cnt] = payload
        while len(d.seen) > SEEN_PER_DEVICE:
            d.seen.popitem(last=False)
        if len(d.missing) > SEEN_PER_DEVICE:
            d.missing = set(sorted(d.missing)[-SEEN_PER_DEVICE:])
        return True, delta


class MqttSource(Source):
    kind = "mqtt"

    def __init__(
        self,
        uri: str,
        host: str,
        port: int,
        topic: str,
        *,
        tls: bool = False,
        ca_file: str | None = None,
        username: str | None = None,
        password: str | None = None,
        client_id: str = "",
    ) -> None:
        super().__init__(uri)
        self.host, self.port, self.topic, self.tls = host, port, topic, tls
        self.ca_file = ca_file
        self.username, self.password = username, password
        self.client_id = client_id
        self.ledger = UplinkLedger()
        self._client: Any = None
        self._malformed_reasons: deque[str] = deque(maxlen=20)
        self.connects = 0

    def check(self) -> None:
        try:
            import paho.mqtt.client  # noqa: F401
        except ImportError:
            raise SourceError("mqtt sources need paho-mqtt (pip install 'paho-mqtt>=2')") from None
        if "\0" in self.topic or ("#" in self.topic and not self.topic.endswith("#")):
            raise SourceError(f"{self.uri}: not a valid MQTT topic filter")
        if self.ca_file is not None:
            try:
                ssl.create_default_context(cafile=self.ca_file)
            except (OSError, ssl.SSLError) as exc:
                raise SourceError(f"{self.uri}: ?ca={self.ca_file}: not a readable PEM CA bundle ({exc})") from None

    def run(self) -> None:
        import paho.mqtt.client as mqtt

        client = mqtt.Client(
            mqtt.CallbackAPIVersion.VERSION2, client_id=self.client_id, protocol=mqtt.MQTTv311, clean_session=True
        )
        if self.username:
            client.username_pw_set(self.username, self.password)
        if self.tls:
            # The broker's certificate is checked (chain and host name): against ?ca=PATH when given.
            client.tls_set(ca_certs=self.ca_file, cert_reqs=ssl.CERT_REQUIRED)
        client.reconnect_delay_set(min_delay=1, max_delay=5)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.on_message = self._on_message
        self._client = client
        while not self.stopping:
            try:
                client.connect(self.host, self.port, keepalive=15)
            except OSError as exc:  # ssl.SSLError too: a certificate that does not verify
                self.set_connected(False, f"cannot connect: {exc.strerror or exc}")
                if self.wait(0.5):
                    return
                continue
            # Reconnects itself (with backoff) until disconnect() from stop().
            client.loop_forever(retry_first_connection=True)
            return

    def interrupt(self) -> None:
        if self._client is not None:
            self._client.disconnect()

    # -- paho callbacks (the client's thread) -------------------------------
    def _on_connect(self, client: Any, _userdata: Any, _flags: Any, reason: Any, _props: Any = None) -> None:
        if getattr(reason, "is_failure", False):
            self.set_connected(False, f"refused: {reason}")
            return
        self.connects += 1
        client.subscribe(self.topic, qos=1)  # renewed on every connect: a restarted broker forgot it
        self.set_connected(True, f"subscribed to {self.topic}")

    def _on_disconnect(self, _client: Any, _userdata: Any, _flags: Any, reason: Any, _props: Any = None) -> None:
        if not self.stopping:
            self.set_connected(False, f"connection lost ({reason}); reconnecting")

    def _on_message(self, _client: Any, _userdata: Any, msg: Any) -> None:
        try:
            self._uplink(msg)
        except Exception as exc:  # whatever a message holds, the subscription goes on
            self._reject(f"topic {msg.topic}: {type(exc).__name__}: {exc}")

    def _uplink(self, msg: Any) -> None:
        try:
            up = parse_uplink(msg.payload)
            unit = decode_payload(up.payload)
        except PayloadError as exc:
            self._reject(f"topic {msg.topic}: {exc}")
            return
        new, lost_delta = self.ledger.admit(up.dev_eui, up.f_cnt, up.payload)
        if not new:
            self.count_duplicate()
            return
        if lost_delta:
            self.count_lost(lost_delta)
            if lost_delta > 0:
                self.note("lost", f"{up.dev_eui}: {count(lost_delta, 'uplink')} lost before fCnt {up.f_cnt}")
        best = max(up.rx, key=lambda r: r.rssi_dbm if r.rssi_dbm is not None else -math.inf, default=None)
        self.emit(
            GnssFix(
                source=self.uri,
                device=up.dev_eui,
                t_fix_ns=unit.time_ns,
                lat_deg=unit.lat_deg if unit.valid else math.nan,
                lon_deg=unit.lon_deg if unit.valid else math.nan,
                speed_mps=unit.speed_mps,
                course_deg=unit.heading_deg,
                received_mono=time.monotonic(),
                role=unit.role if unit.role != "other" else "",
                train=str(unit.train) if unit.train else "",
                battery_pct=unit.battery_pct,
                brake_pipe_bar=unit.brake_pipe_bar,
                emergency=unit.emergency,
                meta={
                    "network": up.network,
                    "f_cnt": up.f_cnt,
                    "received_ns": up.received_ns,
                    "rssi_dbm": best.rssi_dbm if best else None,
                    "snr_db": best.snr_db if best else None,
                    "gateways": len(up.rx),
                    "rx": [(r.gateway, r.rssi_dbm, r.snr_db) for r in up.rx],
                },
            )
        )

    def _reject(self, reason: str) -> None:
        self.count_malformed()
        n = self.status().malformed
        self._malformed_reasons.append(reason)
        if n <= SHOWN_MALFORMED:
            self.note("malformed", reason)
        elif n % 1000 == 0:
            self.note("malformed", f"{n} malformed messages so far; latest: {reason}")
