"""The LoRa payload codec (docs/lora-payload.md) and the network servers' uplink JSON."""

from __future__ import annotations

import base64
import json
import math
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from console.inputs.mqtt import UplinkLedger
from parsers.gnss.lora import (
    PAYLOAD_BYTES,
    PAYLOAD_BYTES_BRAKE,
    PayloadError,
    UnitReport,
    chirpstack_uplink,
    decode_payload,
    encode_payload,
    parse_uplink,
)

# The worked example of docs/lora-payload.md, byte for byte.
DOC_HEX = "16 04 d2 0c 82 be 2f 3f 17 37 a0 05 76 35 7c b4 69 a5 3e 40 19"
DOC_REPORT = UnitReport(
    role="eot",
    train=1234,
    lat_deg=20.9894959,
    lon_deg=105.8486176,
    speed_mps=13.98,
    heading_deg=136.92,
    battery_pct=90.0,
    time_ns=1772437056 * 10**9 + 250_000_000,
    valid=True,
)


def test_the_documented_example_encodes_and_decodes() -> None:
    raw = bytes.fromhex(DOC_HEX)
    assert len(raw) == PAYLOAD_BYTES
    assert encode_payload(DOC_REPORT) == raw
    assert decode_payload(raw) == DOC_REPORT


# Version 2 (docs/lora-payload.md, "Version 2: the brake pipe"): the EOT unit's emergency status
# and the head unit's periodic report with the front pressure.
DOC_V2_EOT_HEX = "27 04 d2 0c 82 be 2f 3f 17 37 a0 05 76 35 7c b4 69 a5 3e 40 19 54"
DOC_V2_EOT = replace(DOC_REPORT, version=2, brake_pipe_bar=4.2, emergency=True)
DOC_V2_HEAD_HEX = "22 04 d2 0c 83 1d 74 3f 16 dd f5 05 76 35 7c be 69 a5 3e 40 3c 64"
DOC_V2_HEAD = replace(
    DOC_REPORT,
    role="head",
    lat_deg=20.9919348,
    lon_deg=105.8463221,
    battery_pct=95.0,
    time_ns=1772437056 * 10**9 + 600_000_000,
    version=2,
    brake_pipe_bar=5.0,
)


def test_the_documented_version_2_examples_encode_and_decode() -> None:
    for hex_, report, b64 in (
        (DOC_V2_EOT_HEX, DOC_V2_EOT, "JwTSDIK+Lz8XN6AFdjV8tGmlPkAZVA=="),
        (DOC_V2_HEAD_HEX, DOC_V2_HEAD, "IgTSDIMddD8W3fUFdjV8vmmlPkA8ZA=="),
    ):
        raw = bytes.fromhex(hex_)
        assert len(raw) == PAYLOAD_BYTES_BRAKE
        assert encode_payload(report) == raw
        assert decode_payload(raw) == report
        assert base64.b64encode(raw).decode() == b64


def test_version_1_is_decoded_as_before_no_pressure_no_emergency() -> None:
    r = decode_payload(bytes.fromhex(DOC_HEX))
    assert r.version == 1 and math.isnan(r.brake_pipe_bar) and not r.emergency
    # Its reserved bit stays refused; version 1 cannot carry a pressure.
    with pytest.raises(PayloadError, match="reserved bit 0"):
        decode_payload(bytes([0x17]) + bytes.fromhex(DOC_HEX)[1:])
    with pytest.raises(PayloadError, match="version 2"):
        encode_payload(replace(DOC_REPORT, brake_pipe_bar=5.0))


@pytest.mark.parametrize(
    ("patch", "reason"),
    [
        (lambda b: b[:-1], "expected 22 bytes for version 2"),
        (lambda b: b + b"\x00", "expected 22 bytes for version 2"),
        (lambda b: b[:21] + bytes([251]), "brake pipe: 12.55 bar"),
        (lambda b: bytes([0x37]) + b[1:], "version: expected 1 or 2"),
    ],
)
def test_version_2_faults_are_named(patch: object, reason: str) -> None:
    raw = bytes.fromhex(DOC_V2_EOT_HEX)
    with pytest.raises(PayloadError, match=reason):
        decode_payload(patch(raw))  # type: ignore[operator]


def test_an_unknown_pressure_is_0xff() -> None:
    r = replace(DOC_V2_HEAD, brake_pipe_bar=math.nan)
    raw = encode_payload(r)
    assert raw[-1] == 0xFF and math.isnan(decode_payload(raw).brake_pipe_bar)


reports = st.builds(
    UnitReport,
    role=st.sampled_from(["head", "eot", "other"]),
    train=st.integers(0, 65535),
    lat_deg=st.integers(-900_000_000, 900_000_000).map(lambda v: v / 1e7),
    lon_deg=st.integers(-1_800_000_000, 1_800_000_000).map(lambda v: v / 1e7),
    speed_mps=st.one_of(st.just(math.nan), st.integers(0, 60000).map(lambda v: v / 100)),
    heading_deg=st.one_of(st.just(math.nan), st.integers(0, 35999).map(lambda v: v / 100)),
    battery_pct=st.one_of(st.none(), st.integers(0, 200).map(lambda v: v / 2)),
    time_ns=st.tuples(st.integers(0, 2**32 - 1), st.integers(0, 99)).map(lambda sc: sc[0] * 10**9 + sc[1] * 10**7),
    valid=st.booleans(),
)
reports_v2 = st.builds(
    replace,
    reports,
    version=st.just(2),
    brake_pipe_bar=st.one_of(st.just(math.nan), st.integers(0, 250).map(lambda v: v / 20)),
    emergency=st.booleans(),
)


@settings(max_examples=100, deadline=None)
@given(st.one_of(reports, reports_v2))
def test_any_report_on_the_field_grid_survives_a_round_trip(r: UnitReport) -> None:
    back = decode_payload(encode_payload(r))
    for name in ("role", "train", "lat_deg", "lon_deg", "battery_pct", "time_ns", "valid", "version", "emergency"):
        assert getattr(back, name) == getattr(r, name)
    for name in ("speed_mps", "heading_deg", "brake_pipe_bar"):
        a, b = getattr(back, name), getattr(r, name)
        assert (math.isnan(a) and math.isnan(b)) or a == b


@settings(max_examples=150, deadline=None)
@given(st.binary(min_size=0, max_size=40))
def test_any_bytes_decode_or_are_rejected_with_a_reason(data: bytes) -> None:
    try:
        r = decode_payload(data)
    except PayloadError as exc:
        assert str(exc)
    else:
        assert len(data) == (PAYLOAD_BYTES if r.version == 1 else PAYLOAD_BYTES_BRAKE)
        assert -90 <= r.lat_deg <= 90 and -180 <= r.lon_deg <= 180


@pytest.mark.parametrize(
    ("patch", "reason"),
    [
        (lambda b: b[:-1], "expected 21 bytes"),
        (lambda b: bytes([0x26]) + b[1:], "version"),
        (lambda b: bytes([0x1C]) + b[1:], "role"),
        (lambda b: b[:3] + (1_000_000_000).to_bytes(4, "big") + b[7:], "latitude"),
        (lambda b: b[:13] + (36000).to_bytes(2, "big") + b[15:], "heading"),
        (lambda b: b[:15] + bytes([201]) + b[16:], "battery"),
        (lambda b: b[:20] + bytes([100]), "hundredths"),
    ],
)
def test_out_of_range_fields_are_named(patch: object, reason: str) -> None:
    raw = bytes.fromhex(DOC_HEX)
    with pytest.raises(PayloadError, match=reason):
        decode_payload(patch(raw))  # type: ignore[operator]


def test_chirpstack_v4_uplink_is_read() -> None:
    doc = chirpstack_uplink("0011223344556677", 42, bytes.fromhex(DOC_HEX), 1772437057 * 10**9)
    doc["rxInfo"].append({"gatewayId": "gw-2", "rssi": -110, "snr": -3.5})
    up = parse_uplink(json.dumps(doc))
    assert (up.network, up.dev_eui, up.f_cnt) == ("chirpstack", "0011223344556677", 42)
    assert decode_payload(up.payload) == DOC_REPORT
    assert [(r.gateway, r.rssi_dbm, r.snr_db) for r in up.rx] == [("gw-1", -97.0, 7.5), ("gw-2", -110.0, -3.5)]
    assert up.received_ns == 1772437057 * 10**9


def test_the_things_stack_v3_uplink_is_read_and_a_missing_fcnt_is_zero() -> None:
    # Shaped as TTS v3 publishes on v3/{app}@{tenant}/devices/{device}/up (zero fields omitted).
    doc = {
        "end_device_ids": {
            "device_id": "eot-1234",
            "application_ids": {"application_id": "trackside"},
            "dev_eui": "70B3D57ED0000001",
            "dev_addr": "260B1234",
        },
        "correlation_ids": ["as:up:01H"],
        "received_at": "2026-03-02T07:37:37.123456789Z",
        "uplink_message": {
            "session_key_id": "AYZ=",
            "f_port": 1,
            "frm_payload": base64.b64encode(bytes.fromhex(DOC_HEX)).decode(),
            "rx_metadata": [
                {"gateway_ids": {"gateway_id": "tts-gw", "eui": "B827EBFFFE000001"}, "rssi": -88, "snr": 9.25}
            ],
            "settings": {"data_rate": {"lora": {"bandwidth": 125000, "spreading_factor": 7}}},
            "received_at": "2026-03-02T07:37:37.120000000Z",
        },
    }
    up = parse_uplink(json.dumps(doc).encode())
    assert (up.network, up.dev_eui, up.f_cnt, up.device_name) == ("tts", "70b3d57ed0000001", 0, "eot-1234")
    assert up.rx[0].gateway == "tts-gw" and up.rx[0].rssi_dbm == -88
    assert up.received_ns == 1772437057 * 10**9 + 120_000_000


@pytest.mark.parametrize(
    "message",
    [
        b"{not json",
        b"[]",
        b'{"deviceInfo": {"devEui": "xyz"}}',
        b'{"deviceInfo": {"devEui": "0011223344556677"}, "fCnt": -1, "data": ""}',
        b'{"deviceInfo": {"devEui": "0011223344556677"}, "fCnt": 1, "data": "@@@"}',
        b'{"deviceInfo": {"devEui": "0011223344556677"}, "fCnt": 1, "data": "AA==", "time": "yesterday"}',
        b'{"end_device_ids": {"dev_eui": "0011223344556677"}}',
        b"\xff\xfe",
    ],
)
def test_malformed_messages_are_payload_errors(message: bytes) -> None:
    with pytest.raises(PayloadError):
        parse_uplink(message)


def test_the_ledger_counts_gaps_merges_duplicates_and_takes_back_late_arrivals() -> None:
    led = UplinkLedger()
    assert led.admit("a", 10, b"x") == (True, 0)
    assert led.admit("a", 10, b"x") == (False, 0)  # a second gateway's copy
    assert led.admit("a", 14, b"y") == (True, 3)  # 11, 12, 13 lost
    assert led.admit("a", 12, b"z") == (True, -1)  # 12 was late, not lost
    assert led.admit("b", 1, b"q") == (True, 0)  # per device
    assert led.devices["a"].lost == 2 and led.devices["a"].duplicates == 1
    assert led.admit("a", 0, b"r") == (True, 0)  # rejoined: the counter restarts
    assert led.devices["a"].resets == 1
