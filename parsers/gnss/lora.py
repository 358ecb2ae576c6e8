"""LoRaWAN uplinks of the head-of-train and end-of-train units: the one place
their payload is encoded and decoded, and the network servers' JSON read.

Payload (version 1: 21 bytes, version 2: 22 bytes, big-endian; ``docs/lora-payload.md`` is the
reference)::

    0      header   bits 7-4 version (1 or 2), bits 3-2 role (0 head, 1 eot, 2 other),
                    bit 1 fix valid, bit 0: version 1 reserved (0); version 2 emergency status
                    (the unit's brake pipe venting: sent at once, not on the report period)
    1-2    train    uint16, 0 = not assigned
    3-6    lat      int32, 1e-7 degree, ±90°
    7-10   lon      int32, 1e-7 degree, ±180°
    11-12  speed    uint16, 0.01 m/s, 0xFFFF = unknown (max 600 m/s)
    13-14  heading  uint16, 0.01 degree from north, 0-35999, 0xFFFF = unknown
    15     battery  uint8, 0.5 %, 0-200, 0xFF = unknown
    16-19  time     uint32, seconds since 1970-01-01 UTC (the unit's clock)
    20     time     uint8, hundredths of a second, 0-99
    21     brake    (version 2) uint8, brake-pipe pressure in 0.05 bar, 0-250, 0xFF = unknown

Network servers publish each uplink on MQTT as JSON: ChirpStack v4
(``deviceInfo.devEui``, ``fCnt``, base64 ``data``, ``rxInfo[]``, ``time``)
and The Things Stack v3 (``end_device_ids.dev_eui``,
``uplink_message.f_cnt``, ``uplink_message.frm_payload``,
``uplink_message.rx_metadata[]``, ``received_at``).  Both omit zero-valued
fields (protobuf JSON), so a missing frame counter is 0.
"""

from __future__ import annotations

import base64
import binascii
import datetime as dt
import json
import math
import re
import struct
from dataclasses import dataclass, field
from typing import Any

PAYLOAD_VERSION = 1
PAYLOAD_BYTES = 21
PAYLOAD_VERSION_BRAKE = 2  # version 1 and a brake-pipe byte, header bit 0 the emergency status
PAYLOAD_BYTES_BRAKE = 22
BYTES_OF_VERSION = {PAYLOAD_VERSION: PAYLOAD_BYTES, PAYLOAD_VERSION_BRAKE: PAYLOAD_BYTES_BRAKE}
BRAKE_STEPS_PER_BAR = 20  # 0.05 bar
MAX_BRAKE_BAR = 12.5
ROLES = ("head", "eot", "other")
_STRUCT = struct.Struct(">BHiiHHBIB")
UNKNOWN_U16 = 0xFFFF
UNKNOWN_U8 = 0xFF
_B64 = re.compile(r"[A-Za-z0-9+/]*={0,2}")
_EUI = re.compile(r"[0-9A-Fa-f]{16}")
MAX_SPEED_MPS = 600.0


class PayloadError(ValueError):
    """A payload or message that breaks the layout; the message says which field and why."""


@dataclass(frozen=True)
class UnitReport:
    """What a train unit reports in one uplink."""

    role: str  # head | eot | other
    train: int  # 0 = not assigned
    lat_deg: float
    lon_deg: float
    speed_mps: float  # NaN: unknown
    heading_deg: float  # NaN: unknown
    battery_pct: float | None
    time_ns: int  # the unit's clock, UTC
    valid: bool = True
    version: int = PAYLOAD_VERSION  # 2: with the brake pipe
    brake_pipe_bar: float = math.nan  # version 2: the unit's end of the brake pipe; NaN: unknown
    emergency: bool = False  # version 2: sent at once, the unit's brake pipe venting


def encode_payload(r: UnitReport) -> bytes:
    """The payload bytes of a report (21 in version 1, 22 in version 2; rounded to the field
    resolutions)."""
    if r.role not in ROLES:
        raise PayloadError(f"role: expected one of {', '.join(ROLES)}, found {r.role!r}")
    if r.version not in BYTES_OF_VERSION:
        raise PayloadError(f"version: expected 1 or 2, found {r.version}")
    if r.version == PAYLOAD_VERSION and (r.emergency or not math.isnan(r.brake_pipe_bar)):
        raise PayloadError("version 1 carries no brake pipe: encode it as version 2")
    header = (r.version << 4) | (ROLES.index(r.role) << 2) | (0b10 if r.valid else 0) | int(r.emergency)
    speed = UNKNOWN_U16 if math.isnan(r.speed_mps) else round(r.speed_mps * 100)
    heading = UNKNOWN_U16 if math.isnan(r.heading_deg) else round((r.heading_deg % 360.0) * 100) % 36000
    battery = UNKNOWN_U8 if r.battery_pct is None else round(r.battery_pct * 2)
    seconds, rest = divmod(r.time_ns, 1_000_000_000)
    values = (
        header,
        r.train,
        round(r.lat_deg * 1e7),
        round(r.lon_deg * 1e7),
        speed,
        heading,
        battery,
        seconds,
        rest // 10_000_000,
    )
    _check_ranges(*values)
    data = _STRUCT.pack(*values)
    if r.version == PAYLOAD_VERSION_BRAKE:
        brake = UNKNOWN_U8 if math.isnan(r.brake_pipe_bar) else round(r.brake_pipe_bar * BRAKE_STEPS_PER_BAR)
        _check_brake(brake)
        data += bytes([brake])
    return data


def _check_brake(brake: int) -> None:
    if brake != UNKNOWN_U8 and not 0 <= brake <= round(MAX_BRAKE_BAR * BRAKE_STEPS_PER_BAR):
        raise PayloadError(f"brake pipe: {brake / BRAKE_STEPS_PER_BAR:.2f} bar out of 0-{MAX_BRAKE_BAR:g} bar")


def _check_ranges(
    header: int, train: int, lat: int, lon: int, speed: int, heading: int, battery: int, seconds: int, cs: int
) -> None:
    if header >> 4 not in BYTES_OF_VERSION:
        raise PayloadError(f"version: expected 1 or 2, found {header >> 4}")
    if (header >> 2) & 0b11 >= len(ROLES):
        raise PayloadError(f"role: code {(header >> 2) & 0b11} is not defined")
    if header >> 4 == PAYLOAD_VERSION and header & 1:
        raise PayloadError("header: reserved bit 0 is set")
    if not 0 <= train <= 0xFFFF:
        raise PayloadError(f"train: {train} out of 0-65535")
    if not -900_000_000 <= lat <= 900_000_000:
        raise PayloadError(f"latitude: {lat / 1e7:.7f}° out of ±90°")
    if not -1_800_000_000 <= lon <= 1_800_000_000:
        raise PayloadError(f"longitude: {lon / 1e7:.7f}° out of ±180°")
    if speed != UNKNOWN_U16 and not 0 <= speed <= MAX_SPEED_MPS * 100:
        raise PayloadError(f"speed: {speed / 100:.2f} m/s out of 0-{MAX_SPEED_MPS:g} m/s")
    if heading != UNKNOWN_U16 and not 0 <= heading < 36000:
        raise PayloadError(f"heading: {heading / 100:.2f}° out of 0-359.99°")
    if battery != UNKNOWN_U8 and not 0 <= battery <= 200:
        raise PayloadError(f"battery: {battery / 2:.1f} % out of 0-100 %")
    if not 0 <= seconds <= 0xFFFFFFFF:
        raise PayloadError(f"time: {seconds} s out of the uint32 range")
    if not 0 <= cs <= 99:
        raise PayloadError(f"time: {cs} hundredths of a second out of 0-99")


def decode_payload(data: bytes) -> UnitReport:
    """The report in the payload bytes (version 1: 21, version 2: 22); :class:`PayloadError` if they
    break the layout."""
    version = data[0] >> 4 if data else None
    if version not in BYTES_OF_VERSION:
        if len(data) not in (PAYLOAD_BYTES, PAYLOAD_BYTES_BRAKE):
            raise PayloadError(f"payload: expected {PAYLOAD_BYTES} or {PAYLOAD_BYTES_BRAKE} bytes, found {len(data)}")
        raise PayloadError(f"version: expected 1 or 2, found {version}")
    if len(data) != BYTES_OF_VERSION[version]:
        raise PayloadError(
            f"payload: expected {BYTES_OF_VERSION[version]} bytes for version {version}, found {len(data)}"
        )
    header, train, lat, lon, speed, heading, battery, seconds, cs = _STRUCT.unpack(data[:PAYLOAD_BYTES])
    _check_ranges(header, train, lat, lon, speed, heading, battery, seconds, cs)
    brake = math.nan
    if version == PAYLOAD_VERSION_BRAKE:
        _check_brake(data[PAYLOAD_BYTES])
        brake = math.nan if data[PAYLOAD_BYTES] == UNKNOWN_U8 else data[PAYLOAD_BYTES] / BRAKE_STEPS_PER_BAR
    return UnitReport(
        role=ROLES[(header >> 2) & 0b11],
        train=train,
        lat_deg=lat / 1e7,
        lon_deg=lon / 1e7,
        speed_mps=math.nan if speed == UNKNOWN_U16 else speed / 100,
        heading_deg=math.nan if heading == UNKNOWN_U16 else heading / 100,
        battery_pct=None if battery == UNKNOWN_U8 else battery / 2,
        time_ns=seconds * 1_000_000_000 + cs * 10_000_000,
        valid=bool(header & 0b10),
        version=version,
        brake_pipe_bar=brake,
        emergency=version == PAYLOAD_VERSION_BRAKE and bool(header & 1),
    )


# -- network-server messages -----------------------------------------------------


@dataclass(frozen=True)
class Reception:
    gateway: str
    rssi_dbm: float | None
    snr_db: float | None


@dataclass(frozen=True)
class Uplink:
    """One uplink as a network server published it."""

    network: str  # chirpstack | tts
    dev_eui: str  # 16 hex digits, lower case
    f_cnt: int
    f_port: int | None
    payload: bytes
    received_ns: int | None  # the network server's time of reception
    rx: tuple[Reception, ...] = field(default_factory=tuple)
    device_name: str = ""


def parse_time_rfc3339(text: Any) -> int | None:
    """RFC 3339 with up to nanoseconds (``2026-03-02T07:55:00.123456789Z``) → ns, None if absent."""
    if text is None:
        return None
    if not isinstance(text, str):
        raise PayloadError(f"time: expected an RFC 3339 string, found {type(text).__name__}")
    m = re.fullmatch(r"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d)(?:\.(\d{1,9}))?(Z|[+-]\d\d:\d\d)", text.strip())
    if not m:
        raise PayloadError(f"time: not RFC 3339: {text[:40]!r}")
    zone = "+00:00" if m.group(3) == "Z" else m.group(3)
    try:
        base = dt.datetime.fromisoformat(m.group(1) + zone)
    except ValueError as exc:
        raise PayloadError(f"time: {exc}") from None
    frac = int((m.group(2) or "0").ljust(9, "0"))
    return int(base.timestamp()) * 1_000_000_000 + frac


def _b64(text: Any, key: str) -> bytes:
    if text is None:
        return b""
    if not isinstance(text, str) or not _B64.fullmatch(text) or len(text) % 4:
        raise PayloadError(f"{key}: not base64")
    try:
        return base64.b64decode(text, validate=True)
    except (binascii.Error, ValueError):
        raise PayloadError(f"{key}: not base64") from None


def _int(value: Any, key: str, default: int | None = None) -> int:
    if value is None and default is not None:
        return default
    if isinstance(value, bool) or not isinstance(value, int):
        raise PayloadError(f"{key}: expected an integer, found {type(value).__name__}")
    if not 0 <= value <= 0xFFFFFFFF:
        raise PayloadError(f"{key}: {value} out of 0-4294967295")
    return value


def _num(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else None


def _eui(value: Any, key: str) -> str:
    if not isinstance(value, str) or not _EUI.fullmatch(value):
        raise PayloadError(f"{key}: expected 16 hex digits")
    return value.lower()


def _obj(doc: Any, key: str) -> dict[str, Any]:
    value = doc.get(key) if isinstance(doc, dict) else None
    if not isinstance(value, dict):
        raise PayloadError(f"{key}: missing or not an object")
    return value


def _rx(items: Any, gateway_key: str) -> tuple[Reception, ...]:
    if items is None:
        return ()
    if not isinstance(items, list):
        raise PayloadError("rx metadata: expected a list")
    out = []
    for r in items:
        if not isinstance(r, dict):
            raise PayloadError("rx metadata: expected objects")
        gw = r.get(gateway_key)
        if isinstance(gw, dict):  # TTS: gateway_ids.gateway_id
            gw = gw.get("gateway_id") or gw.get("eui")
        out.append(Reception(str(gw or ""), _num(r.get("rssi")), _num(r.get("snr"))))
    return tuple(out)


def parse_uplink(message: bytes | str) -> Uplink:
    """A network server's uplink message (ChirpStack v4 or The Things Stack v3) → :class:`Uplink`."""
    try:
        doc = json.loads(message)
    except (ValueError, UnicodeDecodeError) as exc:
        raise PayloadError(f"not JSON ({str(exc)[:60]})") from None
    if not isinstance(doc, dict):
        raise PayloadError("not a JSON object")
    if "deviceInfo" in doc:
        info = _obj(doc, "deviceInfo")
        return Uplink(
            network="chirpstack",
            dev_eui=_eui(info.get("devEui"), "deviceInfo.devEui"),
            f_cnt=_int(doc.get("fCnt"), "fCnt", default=0),
            f_port=_int(doc.get("fPort"), "fPort", default=0),
            payload=_b64(doc.get("data"), "data"),
            received_ns=parse_time_rfc3339(doc.get("time")),
            rx=_rx(doc.get("rxInfo"), "gatewayId"),
            device_name=str(info.get("deviceName") or ""),
        )
    if "end_device_ids" in doc:
        ids = _obj(doc, "end_device_ids")
        up = _obj(doc, "uplink_message")
        return Uplink(
            network="tts",
            dev_eui=_eui(ids.get("dev_eui"), "end_device_ids.dev_eui"),
            f_cnt=_int(up.get("f_cnt"), "uplink_message.f_cnt", default=0),
            f_port=_int(up.get("f_port"), "uplink_message.f_port", default=0),
            payload=_b64(up.get("frm_payload"), "uplink_message.frm_payload"),
            received_ns=parse_time_rfc3339(up.get("received_at") or doc.get("received_at")),
            rx=_rx(up.get("rx_metadata"), "gateway_ids"),
            device_name=str(ids.get("device_id") or ""),
        )
    raise PayloadError("neither a ChirpStack v4 (deviceInfo) nor a The Things Stack v3 (end_device_ids) uplink")


def chirpstack_uplink(
    dev_eui: str,
    f_cnt: int,
    payload: bytes,
    time_ns: int,
    *,
    application_id: str = "trackside",
    device_name: str = "",
    gateways: tuple[tuple[str, float, float], ...] = (("gw-1", -97.0, 7.5),),
) -> dict[str, Any]:
    """An uplink as ChirpStack v4 publishes it on ``application/{app}/device/{devEui}/event/up``."""
    t = dt.datetime.fromtimestamp(time_ns / 1e9, dt.UTC).strftime("%Y-%m-%dT%H:%M:%S.%f") + "Z"
    return {
        "deduplicationId": f"{dev_eui}-{f_cnt}",
        "time": t,
        "deviceInfo": {
            "tenantId": "trackside",
            "tenantName": "trackside",
            "applicationId": application_id,
            "applicationName": application_id,
            "deviceProfileName": "train-unit",
            "deviceName": device_name or dev_eui,
            "devEui": dev_eui,
        },
        "devAddr": dev_eui[-8:],
        "adr": True,
        "dr": 5,
        "fCnt": f_cnt,
        "fPort": 1,
        "confirmed": False,
        "data": base64.b64encode(payload).decode("ascii"),
        "rxInfo": [
            {"gatewayId": gw, "uplinkId": 1000 + k, "rssi": rssi, "snr": snr, "context": "AAAAAA=="}
            for k, (gw, rssi, snr) in enumerate(gateways)
        ],
        "txInfo": {"frequency": 868100000, "modulation": {"lora": {"bandwidth": 125000, "spreadingFactor": 7}}},
    }


def chirpstack_topic(dev_eui: str, application_id: str = "trackside") -> str:
    return f"application/{application_id}/device/{dev_eui}/event/up"
