"""GNSS as receivers and devices really write it (issue "Real data first" §2, and "Hostile input").

Inputs are built in the world's shapes: NMEA with binary UBX / RTCM3 / SiRF
packets between and before sentences on one line, ``#`` headers, gpsd JSON
followed by NMEA, device CSV exports (tests/data/gnss), GPX 1.0 / 1.1,
UTF-16 with and without BOM, CR-only line ends, NULs and stray CRs inside
fields, hostile JSON.  The gpsd regression corpus, when present (gpsd's
test/daemon captures with their .chk decoding, in the directory
TRACKSIDE_GPSD_CAPTURES names, else /tmp/gpsd_corpus; not shipped with this
repository), is compared capture by capture; without it
that test skips and the eight captures in ../shared/data/nmea are compared
in test_gnss_parsers.py.
"""

from __future__ import annotations

import json
import math
import os
import struct
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.cli.app import app
from parsers.gnss.centre import parse_centre_table
from parsers.gnss.nmea import nmea_checksum
from parsers.gnss.packets import rtcm3_packet, sirf_packet, ubx_packet
from parsers.gnss.stream import parse_stream_files
from parsers.gnss_files import parse_device_stream, parse_gnss
from parsers.kinds import classify_file, not_gnss_reason
from parsers.report import ParseReport
from tests.gpsd_truth import compare_with_gpsd

DATA = Path(__file__).resolve().parent / "data" / "gnss"
SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
CORPUS = Path(os.environ.get("TRACKSIDE_GPSD_CAPTURES", "/tmp/gpsd_corpus"))
runner = CliRunner()


def nmea(body: str) -> bytes:
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}".encode("ascii")


RMC = nmea("GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")
GGA = nmea("GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
RMC2 = nmea("GPRMC,123520.00,A,4807.040,N,01131.002,E,022.5,084.4,230394,003.1,W")
# Payloads holding the bytes that break naive line readers: LF, CR, '$'.
UBX = ubx_packet(0x02, 0x15, bytes(range(92)) + b"\n$GPRMC,\r\n")  # RXM-RAWX: skipped, not read
RTCM = rtcm3_packet(bytes([0x43, 0x50]) + b"\n" * 5 + b"$" + bytes(range(20)))
SIRF = sirf_packet(bytes([0x29]) + b"\n\r$" + bytes(range(40)))


def write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


def stream(tmp_path: Path, data: bytes, name: str = "rx.log") -> tuple[pd.DataFrame, ParseReport]:
    fixes, report = parse_stream_files([write(tmp_path, name, data)])
    report.check()
    return fixes, report


# ------------------------------------------------- NMEA among binary packets


def test_sentences_after_binary_packets_on_the_same_line_are_read(tmp_path: Path) -> None:
    data = b"# u-blox M8 port capture\n" + UBX + RTCM + RMC + SIRF + b"\r\n" + SIRF + GGA + b"\r\n" + UBX + RMC2 + b"\n"
    fixes, report = stream(tmp_path, data)
    assert list(fixes["sentence"]) == ["RMC+GGA", "RMC"]  # one row per epoch
    assert fixes["valid"].all()
    assert report.skipped == {"UBX packets": 2, "RTCM3 packets": 1, "SiRF packets": 2}
    assert report.rejected == 0
    assert report.lines_read == data.count(b"\n") == report.records + report.blank


def test_a_packet_spanning_line_ends_is_skipped_whole(tmp_path: Path) -> None:
    data = RMC + b"\r\n" + UBX + UBX + RTCM + GGA + b"\r\n"  # the packets hold 3 + 3 + 5 LFs
    fixes, report = stream(tmp_path, data)
    assert list(fixes["sentence"]) == ["RMC+GGA"]
    assert report.skipped["UBX packets"] == 2 and report.skipped["RTCM3 packets"] == 1
    assert report.rejected == 0
    assert fixes["line"].iloc[0] == 1
    assert report.lines_read == data.count(b"\n")


def test_a_false_sync_byte_does_not_swallow_the_sentence_after_it(tmp_path: Path) -> None:
    data = b"\xd3\x00\x40\xb5\x62\x01\x07\xff\x00" + RMC + b"\n"  # claims of an RTCM3 and a UBX packet, bad CRCs
    fixes, report = stream(tmp_path, data)
    assert len(fixes) == 1 and report.records == 1
    assert report.skipped["unrecognised binary bytes"] == 9


def test_binary_of_no_known_kind_alone_on_a_line_is_rejected_with_the_byte(tmp_path: Path) -> None:
    data = RMC + b"\n" + b"\x10\x8f\xab\x01\x10\x03\n"  # a Trimble TSIP packet
    fixes, report = stream(tmp_path, data)
    assert len(fixes) == 1
    (rejection,) = report.rejections
    assert rejection.line == 2 and "byte 0x10 at column 1" in rejection.reason


def _nav_pvt(
    *, fix_type: int = 3, fix_ok: bool = True, nano: int = -100_231, lat_e7: int = 481173000, second: int = 1
) -> bytes:
    payload = bytearray(92)
    # iTOW, 2026-01-19 10:05:0x UTC, valid date+time, tAcc, nano, fixType, flags, flags2, numSV, lon, lat.
    # iTOW: GPS time of week, 18 s ahead of UTC; Monday 10:05:19 is 122 719 s into the week.
    itow_ms = (122_718 + second) * 1000 + round(nano / 1e6)
    struct.pack_into(
        "<IHBBBBBBIiBBBBii",
        payload,
        0,
        itow_ms,
        2026,
        1,
        19,
        10,
        5,
        second,
        0x07,
        30,
        nano,
        fix_type,
        int(fix_ok),
        0,
        9,
        115166667,
        lat_e7,
    )
    struct.pack_into("<ii", payload, 60, 15_250, 2_050_000)  # gSpeed 15.25 m/s, headMot 20.5°
    return ubx_packet(0x01, 0x07, bytes(payload))


def test_a_ubx_nav_pvt_is_a_fix(tmp_path: Path) -> None:
    pvts = _nav_pvt(), _nav_pvt(fix_type=5, nano=200_000_000), _nav_pvt(fix_type=1, second=2)
    data = pvts[0] + UBX + b"\n" + pvts[1] + b"\n" + pvts[2] + b"\n"
    fixes, report = stream(tmp_path, data)
    assert list(fixes["source"].astype(str)) == ["ubx", "ubx", "ubx"]
    first = fixes.iloc[0]
    # 10:05:01 - 100 231 ns: the epoch's nominal time is the millisecond it rounds to (as gpsd reports it).
    assert fixes["time"].iloc[0] == pd.Timestamp("2026-01-19T10:05:01Z")
    assert first["lat"] == pytest.approx(48.1173, abs=1e-9) and first["speed_mps"] == 15.25
    assert first["course_deg"] == pytest.approx(20.5) and first["sentence"] == "NAV-PVT"
    assert not fixes["valid"].iloc[1]  # fix type 5: time only
    assert fixes["valid"].iloc[2] and fixes["fix_quality"].iloc[2] == "dead_reckoning"  # fix type 1
    assert report.skipped == {"UBX packets": 1} and report.records == 3


def test_a_nav_pvt_outside_the_receivers_accuracy_mask_is_no_fix(tmp_path: Path) -> None:
    fixes, _ = stream(tmp_path, _nav_pvt(fix_ok=False) + b"\n")
    assert not fixes["valid"].iloc[0] and fixes["fix_quality"].iloc[0] == "no_fix"


def test_two_sentences_on_one_line_are_both_read(tmp_path: Path) -> None:
    fixes, report = stream(tmp_path, RMC + RMC2 + b"\n")
    assert len(fixes) == 2 and report.records == 1 and report.rejected == 0


def _rmc_at(second: int) -> bytes:
    return nmea(f"GPRMC,1235{second:02d}.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")


_JUNK = st.binary(min_size=1, max_size=12).map(lambda b: bytes(x | 0x80 for x in b))  # never ASCII, never a LF
_PIECE = st.one_of(st.just(UBX), st.just(RTCM), st.just(SIRF), _JUNK, st.sampled_from([b"\n", b"\r\n", b""]))


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(_PIECE, max_size=4), min_size=1, max_size=12))
def test_every_sentence_among_random_packets_and_junk_is_read(tmp_path: Path, gaps: list[list[bytes]]) -> None:
    """Sentences at distinct seconds, separated by any mix of packets, binary junk and line ends: all read."""
    data = b"".join(b"".join(gap) + _rmc_at(k) for k, gap in enumerate(gaps)) + b"\n"
    fixes, report = stream(tmp_path, data)
    assert list(fixes["time"].dt.second) == list(range(len(gaps)))
    assert fixes["valid"].all()
    assert report.lines_read == data.count(b"\n") == report.records + report.blank + report.rejected


# ----------------------------------------------------------------- gpsd JSON

TPV = {
    "class": "TPV",
    "device": "/dev/ttyACM0",
    "mode": 3,
    "time": "1994-03-23T12:35:19.000Z",
    "lat": 48.1173,
    "lon": 11.516666667,
    "speed": 11.523,
    "track": 84.4,
}


def test_gpsd_json_then_nmea_gives_fixes_from_both(tmp_path: Path) -> None:
    lines = [
        b"# gpspipe -w -r",
        json.dumps({"class": "VERSION", "release": "3.25"}).encode(),
        json.dumps(TPV).encode(),
        json.dumps({"class": "SKY", "nSat": 9}).encode(),
        json.dumps({**TPV, "time": "1994-03-23T12:35:21.000Z", "mode": 1}).encode(),
        RMC2,
    ]
    fixes, report = stream(tmp_path, b"\n".join(lines) + b"\n")
    assert list(fixes["source"].astype(str)) == ["gpsd", "gpsd", "nmea"]
    assert list(fixes["valid"]) == [True, False, True]
    first = fixes.iloc[0]
    assert first["speed_mps"] == 11.523 and first["course_deg"] == 84.4 and first["sentence"] == "TPV"
    assert report.skipped == {"gpsd VERSION reports": 1, "gpsd SKY reports": 1}
    assert report.records == 3 and report.blank == 3


def test_a_tpv_and_the_nmea_of_its_epoch_are_one_fix(tmp_path: Path) -> None:
    fixes, _ = stream(tmp_path, RMC + b"\n" + json.dumps(TPV).encode() + b"\n")
    assert list(fixes["sentence"]) == ["RMC+TPV"]


def test_gpsd_dead_reckoning_status_is_marked(tmp_path: Path) -> None:
    fixes, _ = stream(tmp_path, json.dumps({**TPV, "status": 6}).encode() + b"\n")
    assert fixes["fix_quality"].iloc[0] == "dead_reckoning" and fixes["valid"].iloc[0]


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        ("18446744073709551616", "field 'lat': an integer of 20 digits is out of range"),  # 2^64
        ("9" * 5000, "field 'lat': an integer of 5000 digits is out of range"),
        ("1e999", "field 'lat': expected a finite number"),
        ('"\\ud800"', "field 'lat': expected a number"),
    ],
)
def test_hostile_numbers_in_a_tpv_reject_that_row_naming_the_field(tmp_path: Path, value: str, reason: str) -> None:
    bad = json.dumps(TPV).replace('"lat": 48.1173', f'"lat": {value}').encode()
    fixes, report = stream(tmp_path, bad + b"\n" + json.dumps(TPV).encode() + b"\n")
    assert len(fixes) == 1 and report.rejected == 1
    assert reason in report.rejections[0].reason and report.rejections[0].line == 1


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        ('{"a":' * 1000 + "1" + "}" * 1000, "nested more than"),
        ('{"class": "TPV", "device": "\\ud800", "mode": 3}', "lone surrogate"),
        ('{"class": "TPV", "mode": 3, "big": ' + "7" * 5000 + "}", ""),  # a field we do not read: no harm
    ],
)
def test_hostile_json_lines_are_rejected_alone(tmp_path: Path, line: str, reason: str) -> None:
    fixes, report = stream(tmp_path, line.encode() + b"\n" + RMC + b"\n")
    assert report.lines_read == 2
    assert (fixes["sentence"] == "RMC").sum() == 1
    if reason:
        assert report.rejected == 1 and reason in report.rejections[0].reason
    else:
        assert report.rejected == 0


def test_hostile_json_in_device_streams_is_rejected_per_row(tmp_path: Path) -> None:
    good = '{"time": "2026-01-19T10:05:00Z", "device": "h", "lat": 20.6, "lon": 105.9, "speed_kmh": 54}'
    lines = [
        good,
        good.replace("54", "18446744073709551616"),
        good.replace("20.6", "9" * 5000),
        good.replace('"h"', '"\\ud800"'),
        "[" * 1000 + "]" * 1000,
        '{"time": "2026-01-19T10:05:00Z", "lat": 1, "lon": 2, "x": ' + "[" * 1000 + "]" * 1000 + "}",
    ]
    fixes, report = parse_device_stream([write(tmp_path, "h.jsonl", "\n".join(lines).encode())])
    report.check()
    assert len(fixes) == 1 and report.rejected == 5
    reasons = [r.reason for r in report.rejections]
    assert "speed" in reasons[0] and "20 digits" in reasons[0]
    assert "lat" in reasons[1] and "5000 digits" in reasons[1]
    assert "lone surrogate" in reasons[2]
    assert "nested" in reasons[3] and "nested" in reasons[4]


def test_a_centre_table_row_with_a_huge_number_is_rejected_naming_the_field(tmp_path: Path) -> None:
    header = "TIMESTAMP\tMã tàu\tVĩ độ\tKinh độ\tVận tốc (km/h)"
    rows = ["2026-01-19 17:06:41\tVN0001\t20,7\t105,9\t" + "9" * 5000, "2026-01-19 17:06:31\tVN0001\t20,7\t105,9\t54,9"]
    fixes, _, report = parse_centre_table([write(tmp_path, "t.tsv", "\n".join([header, *rows]).encode())])
    assert len(fixes) == 1 and report.rejected == 1
    assert "speed (km/h)" in report.rejections[0].reason and "out of range" in report.rejections[0].reason


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        (nmea("GPZDA,123500.00,23,03,9999,00,00"), "ZDA year 9999"),
        (nmea("GPGGA,123520.00,4807.038,N,01131.000,E,1," + "9" * 5000 + ",0.9,545.4,M,46.9,M,,"), "satellites-used"),
        (nmea("GPGGA,123520.00,4807.038,N,01131.000,E," + "1" * 30 + ",08,0.9,545.4,M,46.9,M,,"), "quality field"),
    ],
)
def test_sentences_with_numbers_beyond_any_range_are_rejected_alone(tmp_path: Path, line: bytes, reason: str) -> None:
    fixes, report = stream(tmp_path, line + b"\n" + RMC + b"\n")
    assert len(fixes) == 1 and report.rejected == 1 and reason in report.rejections[0].reason


GSV = nmea("GPGSV,1,1,04,05,40,083,46,07,23,062,42,13,63,124,46,20,14,245,38")
VTG2 = nmea("GPVTG,084.4,T,081.3,M,022.5,N,041.7,K,A")
NINES = "9" * 400  # float() of it is inf


def _receiver_log(bad: bytes) -> bytes:
    """A receiver's log as captured: a header, an epoch, the bad sentence at line 4, noise before the next
    epoch's RMC, a sentence without a fix and a blank line."""
    return b"\n".join([b"# rx-logger 2.1, COM4 9600 8N1", RMC, GGA, bad, b"rx> " + RMC2, VTG2, GSV, b""]) + b"\n"


def _read_around(tmp_path: Path, bad: bytes) -> tuple[pd.DataFrame, ParseReport]:
    """The log around ``bad``: both epochs read, every line counted, the bad one rejected alone at line 4."""
    fixes, report = stream(tmp_path, _receiver_log(bad))  # stream() checks that every line is counted
    assert (report.lines_read, report.records, report.blank, report.rejected) == (8, 4, 3, 1)
    assert [r.line for r in report.rejections] == [4]
    assert list(fixes["sentence"]) == ["RMC+GGA", "RMC+VTG"]
    assert list(fixes["time"]) == [pd.Timestamp("1994-03-23T12:35:19Z"), pd.Timestamp("1994-03-23T12:35:20Z")]
    assert fixes[["speed_mps", "course_deg"]].map(math.isfinite).all().all()
    return fixes, report


@pytest.mark.parametrize(
    ("bad", "reason"),
    [
        # 2^31: dt.date raised OverflowError, which escaped as an internal error
        (nmea("GPZDA,123519.50,23,03,2147483648,00,00"), "ZDA year 2147483648 is outside 1980-2200"),
        (nmea("GPZDA,123519.50,2147483648,03,1994,00,00"), "ZDA date '2147483648/03/1994' is not a date"),
        (nmea("GPZDA,123519.50,23,99999999999999999999,1994,00,00"), "is not a date"),
        (nmea("GPZDA,123519.50,23,03,1" + "0" * 5000 + ",00,00"), "ZDA year 100000000000 is outside"),
    ],
    ids=["year-2^31", "day-2^31", "month-10^20", "year-of-5001-digits"],
)
def test_a_zda_with_a_huge_year_day_or_month_is_rejected_and_the_log_read_on(
    tmp_path: Path, bad: bytes, reason: str
) -> None:
    _, report = _read_around(tmp_path, bad)
    assert reason in report.rejections[0].reason
    assert report.rejected_by_reason == {"field": 1}


@pytest.mark.parametrize(
    ("bad", "field"),
    [
        (nmea(f"GPRMC,123519.50,A,4807.038,N,01131.000,E,{NINES},084.4,230394,003.1,W"), "speed (knots)"),
        (nmea(f"GPRMC,123519.50,A,4807.038,N,01131.000,E,022.4,{NINES}.5,230394,003.1,W"), "course"),
        (nmea(f"GPVTG,084.4,T,081.3,M,{NINES},N,041.7,K,A"), "speed (knots)"),
        (nmea(f"GPVTG,084.4,T,081.3,M,,N,{NINES},K,A"), "speed (km/h)"),
        (nmea(f"GPVTG,{NINES},T,081.3,M,022.5,N,041.7,K,A"), "course (true)"),
    ],
    ids=["rmc-speed", "rmc-course", "vtg-knots", "vtg-kmh", "vtg-course"],
)
def test_a_speed_or_course_of_hundreds_of_digits_is_rejected_not_read_as_infinity(
    tmp_path: Path, bad: bytes, field: str
) -> None:
    _, report = _read_around(tmp_path, bad)
    reason = report.rejections[0].reason
    assert reason.startswith(f"{field} field '999999999999") and reason.endswith("characters: expected a finite number")


@pytest.mark.parametrize(
    "bad",
    [
        nmea("GPRMC,123519.50,A,nan07.038,N,01131.000,E,022.4,084.4,230394,003.1,W"),
        nmea("GPGGA,123519.50,4807.038,N,nan31.000,E,1,08,0.9,545.4,M,46.9,M,,"),
    ],
    ids=["rmc-lat", "gga-lon"],
)
def test_a_nan_coordinate_is_rejected_not_read_as_a_missing_position(tmp_path: Path, bad: bytes) -> None:
    _, report = _read_around(tmp_path, bad)
    assert "field 'nan" in report.rejections[0].reason and "is not (d)ddmm.mmmm" in report.rejections[0].reason


def _strict_json(text: str) -> dict:
    def refuse(name: str) -> None:
        raise AssertionError(f"{name} in the JSON output")

    doc = json.loads(text, parse_constant=refuse)
    assert isinstance(doc, dict)
    return doc


@pytest.mark.parametrize(
    "bad",
    [nmea("GPZDA,123519.50,23,03,2147483648,00,00"), nmea(f"GPVTG,084.4,T,081.3,M,{NINES},N,041.7,K,A")],
    ids=["zda-year-2^31", "vtg-knots-inf"],
)
@pytest.mark.parametrize("command", [["gnss"], ["crossing", "--layout", "example"]])
def test_gnss_commands_reject_the_sentence_and_print_valid_json(tmp_path: Path, bad: bytes, command: list[str]) -> None:
    res = runner.invoke(app, [*command, "--json", str(write(tmp_path, "head1.log", _receiver_log(bad)))])
    assert res.exit_code == 0, res.output
    report = _strict_json(res.stdout)["parse_report"]
    assert (report["lines_read"], report["records"], report["blank"], report["rejected"]) == (8, 4, 3, 1)
    assert [r["line"] for r in report["rejections"]] == [4]


def test_a_device_row_dated_beyond_the_timestamp_range_is_rejected_alone(tmp_path: Path) -> None:
    data = b"time,lat,lon\n9999-01-19T10:05:00Z,20.6,105.9\n2026-01-19T10:05:00Z,20.6,105.9\n"
    fixes, report = parse_device_stream([write(tmp_path, "d.csv", data)])
    assert len(fixes) == 1 and "year 9999" in report.rejections[0].reason


# ------------------------------------------------------- device CSV exports


def test_a_ublox_export_with_scaled_integers_split_time_and_fix_types() -> None:
    fixes, report = parse_device_stream([DATA / "ublox_export.csv"])
    assert report.rejected == 0 and report.records == 5
    assert fixes["lat"].iloc[0] == pytest.approx(20.6, abs=1e-9)  # lat_e7 = 206000000
    assert fixes["speed_mps"].iloc[0] == pytest.approx(15.25)  # gSpeed [mm/s] = 15250
    assert fixes["course_deg"].iloc[0] == pytest.approx(20.5)  # headMot [deg*1e5]
    assert fixes["time"].iloc[1] == pd.Timestamp("2026-01-19T10:05:01Z")  # Date + Time columns
    assert list(fixes["fix_quality"].astype(str)) == ["gnss", "gnss", "dead_reckoning", "no_fix", "gnss"]
    assert list(fixes["valid"]) == [True, True, True, False, True]
    assert set(report.skipped) == {
        f"CSV column '{c}' (not read)" for c in ("iTOW", "numSV", "height_mm", "hAcc_mm", "carrSoln")
    }


def test_an_operator_export_with_unit_headers_and_no_speed() -> None:
    fixes, report = parse_device_stream([DATA / "operator_positions.csv"])
    assert report.rejected == 0
    assert set(fixes["device"].astype(str)) == {"EOT-7"}
    assert fixes["lat"].iloc[0] == 20.599 and fixes["lon"].iloc[0] == 105.8995  # Latitude [deg], decimal commas
    assert fixes["speed_mps"].isna().all()  # no speed column: NaN, never 0
    assert list(fixes["fix_quality"].astype(str)) == ["gnss", "gnss", "dead_reckoning", "no_fix"]
    assert "CSV column 'HDOP' (not read)" in report.skipped


def test_a_gpsbabel_unicsv_export_with_slashed_dates_is_read(tmp_path: Path) -> None:
    """GPSBabel's unicsv (and spreadsheets) write the date year first with slashes, beside a time column; speed in
    m/s (https://www.gpsbabel.org/htmldoc-development/fmt_unicsv.html).  A date mixing - and / is refused."""
    data = (
        b"No,Latitude,Longitude,Altitude,Speed,Course,Date,Time\n"
        b"1,36.620100,127.325000,45.0,20.5,90.0,2026/03/02,08:00:00\n"
        b"2,36.620100,127.325230,45.0,20.6,90.0,2026/03/02,08:00:01.5\n"
        b"3,36.620100,127.325460,45.1,20.7,90.0,2026/03-02,08:00:02\n"
    )
    fixes, report = parse_device_stream([write(tmp_path, "unicsv.csv", data)])
    assert list(fixes["time"]) == [pd.Timestamp("2026-03-02T08:00:00Z"), pd.Timestamp("2026-03-02T08:00:01.5Z")]
    assert list(fixes["speed_mps"]) == [20.5, 20.6]
    assert report.rejected == 1 and report.rejections[0].line == 4
    assert "2026/03-02 08:00:02" in report.rejections[0].reason


def test_gpsd_gpscsv_output_is_read_in_each_of_its_shapes(tmp_path: Path) -> None:
    """gpsd's gpscsv (clients/gpscsv.py): the header as field names (default), after '# ' (--header 2) or absent
    (--header 0, refused: no column names); times ISO or seconds since 1970 (--cvt-isotime); TPV keys by -f, mode
    0-3 (1 no fix, 2 2D, 3 3D).  Each shape gives the fixes of the ISO one."""
    iso = ["2026-03-02T08:00:00.000Z", "2026-03-02T08:00:01.000Z", "2026-03-02T08:00:02.500Z"]
    unix = ["1772438400.0", "1772438401.0", "1772438402.5"]
    rows = [
        "36.620100,127.325000,45.000,20.5,90.0,3",
        "36.620100,127.325230,45.000,20.6,90.0,1",
        "36.6201,127.32546,45.1,20.7,90.0,2",
    ]
    fields = "time,lat,lon,altHAE,speed,track,mode"

    def fixes_of(header: str, times: list[str]) -> pd.DataFrame:
        body = "".join(f"{t},{r}\n" for t, r in zip(times, rows, strict=True))
        path = write(tmp_path, "gpscsv.csv", (header + body).encode())
        assert classify_file(path).kind == "gnss-csv"
        fixes, report = parse_device_stream([path])
        assert report.rejected == 0 and report.records == 3, report.rejections
        return fixes.drop(columns=["file"])

    plain = fixes_of(fields + "\n", iso)
    assert list(plain["valid"]) == [True, False, True]  # mode 1: no fix
    assert list(plain["speed_mps"]) == [20.5, 20.6, 20.7] and list(plain["course_deg"]) == [90.0] * 3
    assert plain["time"].iloc[2] == pd.Timestamp("2026-03-02T08:00:02.5Z")
    pd.testing.assert_frame_equal(fixes_of(f"# {fields}\n", iso), plain)
    pd.testing.assert_frame_equal(fixes_of(f"# {fields}\n", unix), plain)
    pd.testing.assert_frame_equal(fixes_of(fields + "\n", unix), plain)


def test_json_lines_with_times_in_seconds_since_1970(tmp_path: Path) -> None:
    rows = [{"time": 1772438400.25, "lat": 36.62, "lon": 127.325}, {"time": 1772438401, "lat": 36.62, "lon": 127.3252}]
    path = write(tmp_path, "epoch.jsonl", "".join(json.dumps(r) + "\n" for r in rows).encode())
    fixes, report = parse_device_stream([path])
    assert report.rejected == 0
    assert list(fixes["time"]) == [pd.Timestamp("2026-03-02T08:00:00.25Z"), pd.Timestamp("2026-03-02T08:00:01Z")]


@pytest.mark.parametrize(
    ("header", "row", "speed_mps"),
    [
        ("time,LAT,LON,Speed (km/h)", "2026-01-19T10:05:00Z,20.6,105.9,54", 15.0),
        ("Time,Latitude,Longitude,speed_knots", "2026-01-19T10:05:00Z,20.6,105.9,10", 10 * 1852 / 3600),
        ("timestamp;lat (°);lon (°);SOG [m/s]", "2026-01-19T10:05:00Z;20,6;105,9;3,5", 3.5),
        ("utc date,utc time,lat,lon,speed_mm_s", "2026-01-19,10:05:00,20.6,105.9,1500", 1.5),
    ],
)
def test_column_names_are_matched_whatever_their_case_and_unit(
    tmp_path: Path, header: str, row: str, speed_mps: float
) -> None:
    fixes, report = parse_device_stream([write(tmp_path, "d.csv", f"{header}\n{row}\n".encode())])
    assert report.rejected == 0, report.rejections
    assert fixes["speed_mps"].iloc[0] == pytest.approx(speed_mps)
    assert fixes["time"].iloc[0] == pd.Timestamp("2026-01-19T10:05:00Z")


def test_an_unknown_unit_on_a_column_we_read_is_refused_not_guessed(tmp_path: Path) -> None:
    _, report = parse_device_stream([write(tmp_path, "d.csv", b"time,lat,lon,speed [furlong/fortnight]\n")])
    assert report.rejected == 1 and "furlong" in report.rejections[0].reason


def test_a_numeric_status_without_a_convention_is_refused_per_row(tmp_path: Path) -> None:
    data = b"time,lat,lon,status\n2026-01-19T10:05:00Z,20.6,105.9,3\n2026-01-19T10:05:01Z,20.6,105.9,3D\n"
    fixes, report = parse_device_stream([write(tmp_path, "d.csv", data)])
    assert len(fixes) == 1 and "fix type" in report.rejections[0].reason


_CELLS = {
    "time": [
        "2026-01-19T10:05:00Z",
        "2026-01-19 10:05:01",
        "2026-01-19T17:05:02+07:00",
        "2026-01-19T10:05:03.25Z",
        "19/01/2026 10:05:04",
        "2026/01/19 10:05:04.5",
        "2026/01-19 10:05:04",
        "1768817106",
        "1768817106.25",
        "345600.5",
        "2026-01-19T10:05:05,5Z",
        "2026-01-19T10:05:60Z",
        "9999-01-01T00:00:00Z",
        "2026-02-30T10:00:00Z",
        "",
        "yesterday",
        " 2026-01-19T10:05:06Z",
    ],
    "device": ["h1", "e7", "", " h1", "d-1.x"],
    "role": ["head", "EOT", "", "tail", "driver", "Locomotive"],
    "lat": ["20.6", "20,61", "-20.6", "+20.6", "", "91", "1e1", "−20.6", "20.", "9" * 50],
    "lon": ["105.9", "105,91", "", "181", "abc"],
    "speed": ["15", "15.5", "", "-1", "0", "1" * 25],
    "quality": ["3D", "no fix", "DR", "", "3", "weird", "RTK fixed"],
}


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(
        st.fixed_dictionaries({k: st.sampled_from(v) for k, v in _CELLS.items()}).map(
            lambda r: ",".join(r[k] for k in _CELLS)
        )
        | st.sampled_from(["", "# note", "2026-01-19T10:05:00Z,h1,head,20.6", "a,b,c,d,e,f,g,h"]),
        min_size=64,
        max_size=120,
    )
)
def test_the_vectorized_csv_path_reads_exactly_what_the_per_row_path_reads(tmp_path: Path, lines: list[str]) -> None:
    import parsers.gnss.csv as gnss_csv

    path = write(tmp_path, "d.csv", ("time,device,role,lat,lon,speed,fix quality\n" + "\n".join(lines) + "\n").encode())
    fast, fast_report = parse_device_stream([path])
    gnss_csv.FAST_PATH = False
    try:
        slow, slow_report = parse_device_stream([path])
    finally:
        gnss_csv.FAST_PATH = True
    pd.testing.assert_frame_equal(fast, slow)
    assert fast_report.to_dict() == slow_report.to_dict()


# ---------------------------------------------------------------------- GPX


def test_gpx_1_0_track_with_speed_course_and_fix() -> None:
    fixes, report, _ = parse_gnss([DATA / "track_gpx10.gpx"])
    report.check()
    assert list(fixes["speed_mps"].iloc[:2]) == [15.25, 15.5] and list(fixes["course_deg"].iloc[:2]) == [20.5, 21.0]
    assert list(fixes["valid"]) == [True, True, False]  # <fix>none</fix>
    assert (fixes["source"] == "gpx").all()
    assert report.rejected == 1 and "out of range" in report.rejections[0].reason  # lat 91.5
    assert report.skipped == {"GPX wpt (not a track point)": 1}


def test_gpx_1_1_with_garmin_speed_extensions() -> None:
    fixes, report, _ = parse_gnss([DATA / "track_gpx11_garmin.gpx"], roles={"track_gpx11_garmin": "eot"})
    assert report.rejected == 0
    assert list(fixes["speed_mps"]) == [14.8, 15.1]
    assert fixes["course_deg"].iloc[0] == 19.9 and math.isnan(fixes["course_deg"].iloc[1])
    assert (fixes["role"] == "eot").all()
    assert fixes["time"].iloc[0] == pd.Timestamp("2026-01-19T10:05:00Z")


def test_gpx_without_speed_keeps_speed_nan_and_a_point_without_time_nat() -> None:
    fixes, report, _ = parse_gnss([DATA / "phone_gpx11_no_speed.gpx"])
    assert report.records == 3 and fixes["speed_mps"].isna().all()
    assert fixes["time"].isna().sum() == 1


def test_gpx_with_a_doctype_is_refused_and_every_line_is_counted(tmp_path: Path) -> None:
    bomb = (
        b'<?xml version="1.0"?>\n<!DOCTYPE gpx [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;">]>\n'
        b'<gpx version="1.1"><trk><trkseg><trkpt lat="1" lon="2"><time>&b;</time></trkpt></trkseg></trk></gpx>\n'
    )
    fixes, report, _ = parse_gnss([write(tmp_path, "bomb.gpx", bomb)])
    report.check()
    assert fixes.empty and report.lines_read == 3
    assert "document type declaration" in report.rejections[0].reason


def test_broken_gpx_keeps_the_points_before_the_error(tmp_path: Path) -> None:
    text = (DATA / "phone_gpx11_no_speed.gpx").read_bytes().replace(b'</trkpt>\n<trkpt lat="48.1175"', b"<oops")
    fixes, report, _ = parse_gnss([write(tmp_path, "cut.gpx", text)])
    report.check()
    assert len(fixes) >= 1
    assert report.rejected >= 1 and "XML" in report.rejections[0].reason


# ------------------------------------------------- encodings and line ends

CSV_TEXT = "time,device,lat,lon,speed\n2026-01-19T10:05:00Z,h,20.6,105.9,15\n2026-01-19T10:05:02Z,h,20.6,105.9,16\n"
NMEA_TEXT = (RMC + b"\r\n" + RMC2 + b"\r\n").decode()


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be"])
@pytest.mark.parametrize("text", [CSV_TEXT, NMEA_TEXT], ids=["csv", "nmea"])
def test_utf16_with_and_without_bom_is_read(tmp_path: Path, encoding: str, text: str) -> None:
    fixes, report, _ = parse_gnss([write(tmp_path, "u16.txt", text.encode(encoding))])
    report.check()
    assert len(fixes) == 2 and report.rejected == 0
    assert "utf-16" in report.files[0].encoding


@pytest.mark.parametrize("text", [CSV_TEXT, NMEA_TEXT], ids=["csv", "nmea"])
def test_cr_only_line_ends_are_read(tmp_path: Path, text: str) -> None:
    data = text.replace("\r\n", "\n").replace("\n", "\r").encode()
    fixes, report, _ = parse_gnss([write(tmp_path, "mac.txt", data)])
    report.check()
    assert len(fixes) == 2 and report.rejected == 0 and report.lines_read == text.count("\n")


@pytest.mark.parametrize("poison", ["\x00", "\r"], ids=["nul", "stray-cr"])
def test_a_nul_or_stray_cr_inside_a_field_rejects_that_row_alone(tmp_path: Path, poison: str) -> None:
    lines = CSV_TEXT.splitlines()
    lines.insert(2, f"2026-01-19T10:05:01Z,h,20.{poison}6,105.9,15")
    fixes, report, _ = parse_gnss([write(tmp_path, "d.csv", ("\n".join(lines) + "\n").encode())])
    report.check()
    assert len(fixes) == 2 and report.rejected == 1 and report.rejections[0].line == 3


# ----------------------------------------------------------- file kinds


@pytest.mark.parametrize(
    ("path", "kind"),
    [
        (SAMPLES / "ws4_health.log", "diag"),
        (SAMPLES / "sensor_frames.txt", "frames"),
        (SAMPLES / "can_counts.log", "can"),
        (SAMPLES / "can_counts.asc", "can"),
        (SAMPLES / "am_thuong_2021-06-06_voltages.csv", "voltages"),
        (SAMPLES / "co_nhu_van_2026_centre_table.tsv", "centre"),
        (SAMPLES / "gnss_devices.csv", "gnss-csv"),
        (SAMPLES / "gnss_devices.jsonl", "jsonl"),
        (DATA / "track_gpx10.gpx", "gpx"),
        (DATA / "ublox_export.csv", "gnss-csv"),
    ],
)
def test_files_are_classified_by_content(path: Path, kind: str) -> None:
    assert classify_file(path).kind == kind


def test_a_binary_first_capture_is_a_receiver_stream(tmp_path: Path) -> None:
    assert classify_file(write(tmp_path, "b.bin", UBX * 3 + RMC + b"\n")).kind == "nmea"
    assert not_gnss_reason(write(tmp_path, "c.bin", UBX * 3)) is None


def test_gnss_on_a_diagnostic_log_exits_2_with_one_line() -> None:
    res = runner.invoke(app, ["gnss", str(SAMPLES / "ws4_health.log")])
    assert res.exit_code == 2
    assert res.output.strip().endswith(
        "ws4_health.log: nothing readable as GNSS: looks like an axle-counter diagnostic log"
    )
    assert len(res.output.strip().splitlines()) == 1


def test_gnss_on_a_file_whose_every_line_is_rejected_exits_2(tmp_path: Path) -> None:
    bad = RMC[:-2] + b"00\n"
    res = runner.invoke(app, ["gnss", str(write(tmp_path, "bad.nmea", bad))])
    assert res.exit_code == 2 and "nothing readable as GNSS" in res.output and "checksum" in res.output


def test_gnss_json_lists_skipped_packets(tmp_path: Path) -> None:
    res = runner.invoke(app, ["gnss", "--json", str(write(tmp_path, "mix.log", UBX + RMC + b"\n"))])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["parse_report"]["skipped"] == {"UBX packets": 1}
    assert doc["fixes"][0]["fix_quality"] == "gnss"


# ------------------------------------------------------------ memory


def test_many_distinct_devices_cost_a_small_multiple_of_their_input(tmp_path: Path) -> None:
    """Per-device state is flat: the memory a row adds (one new device each) is a few times its input bytes.

    Measured as the growth of the traced peak from 2 000 to 10 000 devices, so
    that the fixed cost (read buffers, pandas) does not count.  A million
    devices in 52 MB: see docs/gnss.md for the measured whole-process figure.
    """
    import tracemalloc

    peaks, sizes = [], []
    for n in (2_000, 10_000):
        text = "time,device,lat,lon\n" + "".join(f"2026-01-19T10:05:00Z,d{i},20.6,105.9\n" for i in range(n))
        path = write(tmp_path, f"many{n}.csv", text.encode())
        tracemalloc.start()
        fixes, _ = parse_device_stream([path])
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        sizes.append(len(text))
        assert fixes["device"].nunique() == n
    per_input_byte = (peaks[1] - peaks[0]) / (sizes[1] - sizes[0])
    assert per_input_byte < 10, f"{per_input_byte:.1f} bytes of memory per byte of input"


# ------------------------------------------------------- gpsd's own corpus

# Captures where gpsd's epochs from NMEA and ours differ, measured; why:
# bundg_zeus_9 is a boat's NMEA multiplexer whose RMC, GGA and GLL of one
# second carry different positions, and gpsd's reports lag a second behind.
KNOWN_NMEA_MISSES = {"bundg_zeus_9.log": 49, "humminbird-M37.log": 1}
# Epochs gpsd decoded from UBX that we read too, as valid fixes (measured).
# The rest of the binary epochs come from protocols we skip (SiRF, TSIP,
# GREIS, Oncore …), are epochs we call no fix on purpose (gnssFixOK clear,
# fix type 5 "time only"), where gpsd reports a fix, or (aek-4t, lea-4t)
# the first epoch, which gpsd dated with its own leap-second count
# (tests/test_gnss_ubx.py matches the u-blox ones epoch by epoch).
BINARY_MATCHED = {
    "navisys-gr8013.log": 35,
    "ublox-8-time.log": 89,
    "ublox-aek-4t.log": 3,
    "ublox-f9p-rtcm.log": 1,
    "ublox-glo.log": 16,
    "ublox-lea-4t.log": 1,
    "ublox-neo-f9v.log": 3,
    "ublox-neo-m8l.log": 189,
    "ublox-neo-m8n.log": 22,
    "ublox-neo-m8p.log": 58,
    "ublox-neo-m8t.log": 39,
    "ublox-neo-m8u-hnr.log": 12,
    "ublox-neo-m8u.log": 2,
    "ublox-zed-f9p-hp.log": 28,
    "ublox-zed-f9p-rtk.log": 9,
    "ublox-zed-f9p-sfrbx.log": 18,
    "ublox8-uniqid-monhw.log": 3,
}
CORPUS_LOGS = sorted(p.name for p in CORPUS.glob("*.log") if p.with_name(p.name + ".chk").exists())


@pytest.mark.skipif(not CORPUS_LOGS, reason=f"gpsd's test corpus not found at {CORPUS}")
@pytest.mark.parametrize("capture", CORPUS_LOGS or ["none"])
def test_gpsd_corpus_fixes_are_ours(capture: str) -> None:
    log = CORPUS / capture
    fixes, report = parse_stream_files([log])
    report.check()
    counts = compare_with_gpsd(log, fixes)
    missed = counts["nmea"] - counts["nmea_matched"]
    assert missed <= KNOWN_NMEA_MISSES.get(capture, 0), dict(counts)
    assert counts["binary_matched"] >= BINARY_MATCHED.get(capture, 0), dict(counts)


def test_the_fix_table_marks_dead_reckoned_fixes() -> None:
    res = runner.invoke(app, ["gnss", str(DATA / "ublox_export.csv")], env={"COLUMNS": "100"})
    assert res.exit_code == 0, res.output
    row = next(line for line in res.output.splitlines() if line.startswith("10:05:02"))
    assert " DR " in row


def test_gnss_tables_list_the_skipped_packets(tmp_path: Path) -> None:
    res = runner.invoke(app, ["gnss", str(write(tmp_path, "mix.log", UBX + RTCM + RMC + b"\n"))])
    assert res.exit_code == 0, res.output
    assert "Skipped, not read" in res.output
    assert any(line.split() == ["RTCM3", "packets", "1"] for line in res.output.splitlines())


def test_report_reads_two_sentences_on_one_line(tmp_path: Path) -> None:
    """Hostile input: two NMEA sentences on one line once crashed `report`."""
    path = write(tmp_path, "two.nmea", RMC + RMC2 + b"\n")
    res = runner.invoke(app, ["report", str(path), "--layout", "example", "--format", "json"])
    assert res.exit_code == 0, res.output
    assert "internal error" not in res.output
