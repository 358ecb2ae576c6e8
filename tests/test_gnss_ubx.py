"""u-blox UBX and Septentrio SBF read through pyubx2 / pysbf2: every epoch the receiver wrote, one row each.

Truths: gpsd's decoding (``.chk``) of its own u-blox captures, four of them
committed in tests/data/ubx (BSD-2-Clause, README there), all of them when a
directory of gpsd's ``test/daemon`` captures is named by
``TRACKSIDE_GPSD_CAPTURES``; and messages built by the libraries' own
generators (tests/ubx_fixtures.py), so the bytes are a receiver's, not ours.
"""

from __future__ import annotations

import io
import itertools
import os
import random
from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pyrtcm import RTCMMessage
from pyubx2 import ERR_IGNORE, PARSE_NONE, RTCM3_PROTOCOL, UBX_PROTOCOL, UBXReader

from parsers.gnss.binary import UBX_READ
from parsers.gnss.growing import GrowingStream
from parsers.gnss.nmea import nmea_checksum
from parsers.gnss.packets import rtcm3_packet, ubx_packet
from parsers.gnss.stream import parse_stream_files
from parsers.report import FileReport, ParseReport
from tests import ubx_fixtures as ubx
from tests.gpsd_truth import compare_with_gpsd, gpsd_epochs

DATA = Path(__file__).resolve().parent / "data" / "ubx"
COMMITTED = sorted(DATA.glob("*.log"))
T0 = pd.Timestamp("2026-01-19T10:05:01Z")
LAT, LON = 20.7552885, 105.8984998


def stream(tmp_path: Path, data: bytes, name: str = "rx.ubx") -> tuple[pd.DataFrame, ParseReport]:
    path = tmp_path / name
    path.write_bytes(data)
    fixes, report = parse_stream_files([path])
    report.check()
    return fixes, report


def nmea(body: str) -> bytes:
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}".encode("ascii")


def matched(log: Path, fixes: pd.DataFrame, *, any_row: bool) -> tuple[int, int]:
    """(gpsd's epochs with a position, how many of ours match them) — by any row, or by a valid one."""
    if any_row:
        fixes = fixes.assign(valid=True)
    c = compare_with_gpsd(log, fixes)
    return c["nmea"] + c["binary"], c["nmea_matched"] + c["binary_matched"]


# ------------------------------------------------------------- gpsd's captures

# (epochs matched by any row, by a valid row) of gpsd's epochs, per committed capture; why they differ:
# * ublox-aek-4t: gpsd dated its first epoch with its built-in 18 leap seconds before the receiver's
#   NAV-TIMEGPS said 14 (2007): its time is 4 s early (test below);
# * ublox-neo-m8t-s: a surveyed-in timing receiver (fix type 5, "time only"): gpsd reports a 3D fix,
#   we report its position as no fix (a timing receiver's fixed position is no measurement).
COMMITTED_EXPECTED = {
    "ublox-aek-4t.log": ((3, 4), (3, 4)),
    "ublox-f9p-rtcm.log": ((1, 1), (1, 1)),
    "ublox-neo-m8t-s.log": ((29, 29), (0, 29)),
    "ublox-neo-m8u-hnr.log": ((12, 12), (12, 12)),
}


def test_the_committed_captures_are_the_four_with_their_licence() -> None:
    assert [p.name for p in COMMITTED] == sorted(COMMITTED_EXPECTED)
    assert all(p.with_name(p.name + ".chk").is_file() for p in COMMITTED)
    assert "BSD" in (DATA / "COPYING.gpsd").read_text() and "46977faa" in (DATA / "README.md").read_text()


@pytest.mark.parametrize("log", COMMITTED, ids=lambda p: p.name)
def test_every_epoch_gpsd_decodes_from_a_committed_capture_is_ours(log: Path) -> None:
    fixes, report = parse_stream_files([log])
    report.check()
    (any_matched, epochs), (valid_matched, _) = COMMITTED_EXPECTED[log.name]
    assert matched(log, fixes, any_row=True) == (epochs, any_matched)
    assert matched(log, fixes, any_row=False) == (epochs, valid_matched)
    assert set(fixes["source"].astype(str)) == {"ubx"}


def test_gpsd_dated_the_first_antaris_epoch_with_its_default_leap_seconds() -> None:
    log = DATA / "ublox-aek-4t.log"
    fixes, _ = parse_stream_files([log])
    epochs = gpsd_epochs(log)
    first = min(epochs)
    assert first not in set(fixes["time"].astype("int64"))
    # The receiver's own NAV-TIMEUTC for that epoch is 4 s later (GPS - UTC was 14 s in 2007, not 18).
    ours = fixes[fixes["time"] == pd.Timestamp(first, tz="UTC") + pd.Timedelta(seconds=4)].iloc[0]
    lat, lon = epochs[first].positions[0]
    assert abs(ours["lat"] - lat) <= 1e-6 and abs(ours["lon"] - lon) <= 1e-6
    assert ours["sentence"] == "NAV-SOL+NAV-STATUS+NAV-TIMEGPS+NAV-TIMEUTC" and ours["valid"]


def test_a_high_rate_epoch_and_its_late_nav_pvt_are_one_row_with_the_high_rate_position() -> None:
    log = DATA / "ublox-neo-m8u-hnr.log"
    fixes, _ = parse_stream_files([log])
    assert fixes["time"].is_unique and len(fixes) == 12  # 10 Hz HNR-PVT; the NAV-PVT joins its second's row
    whole = fixes[fixes["time"] == pd.Timestamp("2021-06-16T23:46:05Z")].iloc[0]
    assert whole["sentence"] == "NAV-PVT+HNR-PVT+NAV-POSECEF+NAV-VELECEF+NAV-TIMEGPS"
    # The NAV-PVT came after the HNR-PVTs of .1-.3 s; the row keeps the HNR-PVT's position (as gpsd does).
    (lat, lon), *_ = gpsd_epochs(log)[whole["time"].value].positions
    assert (whole["lat"], whole["lon"]) == (lat, lon)
    assert set(fixes["fix_quality"].astype(str)) == {"gnss"}


def test_a_surveyed_in_timing_receiver_is_no_fix() -> None:
    fixes, _ = parse_stream_files([DATA / "ublox-neo-m8t-s.log"])
    assert len(fixes) == 29 and not fixes["valid"].any()
    assert set(fixes["fix_quality"].astype(str)) == {"no_fix"}
    assert set(fixes["sentence"].astype(str)) == {"NAV-SOL+NAV-POSECEF+NAV-VELECEF+NAV-TIMEGPS"}


@pytest.mark.parametrize("log", COMMITTED, ids=lambda p: p.name)
def test_every_packet_pyubx2_finds_in_a_capture_is_read_or_counted(log: Path) -> None:
    """pyubx2 reading the whole file on its own finds the packets we framed line by line: those we do not
    read are counted by kind, and the others each gave or joined a row."""
    found: Counter[str] = Counter()
    for raw, _ in UBXReader(
        io.BytesIO(log.read_bytes()),
        protfilter=UBX_PROTOCOL | RTCM3_PROTOCOL,
        quitonerror=ERR_IGNORE,
        parsing=PARSE_NONE,
    ):
        if raw[:1] == b"\xd3":
            found["RTCM3 packets"] += 1
        elif (raw[2], raw[3]) in UBX_READ:
            found["read"] += 1
        else:
            found["UBX packets"] += 1
    fixes, report = parse_stream_files([log])
    assert report.skipped["RTCM3 packets"] == found["RTCM3 packets"]
    assert report.skipped["UBX packets"] == found["UBX packets"]
    assert sum(len(s.split("+")) for s in fixes["sentence"].astype(str)) == found["read"]


CORPUS = Path(os.environ.get("TRACKSIDE_GPSD_CAPTURES", "/tmp/gpsd_corpus"))
CORPUS_UBLOX = sorted(
    p.name for p in CORPUS.glob("ublox*.log") if p.with_name(p.name + ".chk").is_file() and "sirf" not in p.name
)
# gpsd's epochs we do not match, by capture, and why: gpsd dated the first epoch with its built-in
# leap-second count (18) before the receiver gave its own (14 in 2007, 15 in 2009); the receiver's
# NAV-TIMEUTC for that epoch agrees with our time.
CORPUS_MISSES = {"ublox-aek-4t.log": 1, "ublox-lea-4t.log": 1}


@pytest.mark.skipif(not CORPUS_UBLOX, reason=f"gpsd's captures not found at {CORPUS} (TRACKSIDE_GPSD_CAPTURES)")
@pytest.mark.parametrize("capture", CORPUS_UBLOX or ["none"])
def test_every_ublox_epoch_gpsd_decodes_is_ours(capture: str) -> None:
    log = CORPUS / capture
    fixes, report = parse_stream_files([log])
    report.check()
    epochs, got = matched(log, fixes, any_row=True)
    assert got == epochs - CORPUS_MISSES.get(capture, 0), (capture, got, epochs)


# ------------------------------------------------------------- epochs, merged


def test_nav_sol_posllh_and_velned_of_an_epoch_are_one_row(tmp_path: Path) -> None:
    t = T0
    data = ubx.nav_sol(t, LAT + 1e-4, LON, 3.0, 90.0) + ubx.nav_posllh(t, LAT, LON) + ubx.nav_velned(t, 12.34, 191.8)
    fixes, report = stream(tmp_path, data + b"\n")
    (row,) = fixes.itertuples()
    assert row.sentence == "NAV-SOL+NAV-POSLLH+NAV-VELNED"
    # Latitude/longitude as given beat ECEF converted; a ground speed as given beats one from ECEF.
    assert (row.lat, row.lon, row.speed_mps, row.course_deg) == (LAT, LON, 12.34, 191.8)
    # No leap-second count from the receiver yet: the published one (18 s in 2026).
    assert row.time == t and row.valid and row.fix_quality == "gnss"
    assert report.records == 1 and not report.skipped


def test_a_ublox_6_epoch_is_timed_by_nav_timeutc_and_validated_by_nav_status(tmp_path: Path) -> None:
    epochs = [
        ubx.nav_status(T0) + ubx.nav_posllh(T0, LAT, LON) + ubx.nav_velned(T0, 5.0, 10.0) + ubx.nav_timeutc(T0),
        ubx.nav_posllh(T0 + pd.Timedelta(seconds=1), LAT, LON) + ubx.nav_status(T0 + pd.Timedelta(seconds=1), fix_ok=0),
    ]
    fixes, _ = stream(tmp_path, b"".join(epochs))
    assert list(fixes["sentence"]) == ["NAV-POSLLH+NAV-VELNED+NAV-STATUS+NAV-TIMEUTC", "NAV-POSLLH+NAV-STATUS"]
    assert list(fixes["valid"]) == [True, False] and list(fixes["fix_quality"]) == ["gnss", "no_fix"]
    assert list(fixes["time"]) == [T0, T0 + pd.Timedelta(seconds=1)]


def test_an_epoch_without_a_fix_status_is_no_fix_of_unknown_quality(tmp_path: Path) -> None:
    fixes, _ = stream(tmp_path, ubx.nav_posllh(T0, LAT, LON) + ubx.nav_velned(T0, 5.0, 10.0))
    assert not fixes["valid"].iloc[0] and fixes["fix_quality"].iloc[0] == "" and fixes["lat"].iloc[0] == LAT


def test_dead_reckoning_only_is_a_fix_marked_so(tmp_path: Path) -> None:
    fixes, _ = stream(tmp_path, ubx.nav_sol(T0, LAT, LON, 5.0, 10.0, fix_type=1))
    assert fixes["valid"].iloc[0] and fixes["fix_quality"].iloc[0] == "dead_reckoning"


def test_gps_time_takes_the_leap_seconds_the_receiver_gives_or_last_gave(tmp_path: Path) -> None:
    """A receiver that says 17 s (as one would before 2017-01-01's leap second had been announced to it)."""
    t1, t2 = T0, T0 + pd.Timedelta(seconds=1)
    data = (
        ubx.nav_sol(t1, LAT, LON, 5.0, 10.0, leap_s=17)  # no count yet: the published 18 s, for now
        + ubx.nav_timegps(t1, leap_s=17)  # the same epoch: its row takes the receiver's 17 s
        + ubx.nav_sol(t2, LAT, LON, 5.0, 10.0, leap_s=17)  # no NAV-TIMEGPS: the count it last gave
    )
    fixes, _ = stream(tmp_path, data)
    assert list(fixes["time"]) == [t1, t2]
    assert list(fixes["sentence"]) == ["NAV-SOL+NAV-TIMEGPS", "NAV-SOL"]


def test_a_time_of_week_without_a_week_takes_the_last_week_and_turns_with_it(tmp_path: Path) -> None:
    # Sunday 00:00:00 GPS is a new week: 23:59:42 UTC on Saturday 2026-01-24.
    end = pd.Timestamp("2026-01-24T23:59:41Z")
    times = [end, end + pd.Timedelta(seconds=1), end + pd.Timedelta(seconds=2)]
    data = ubx.nav_sol(times[0], LAT, LON, 5.0, 10.0) + b"".join(
        ubx.nav_posllh(t, LAT, LON) + ubx.nav_status(t) for t in times[1:]
    )
    fixes, _ = stream(tmp_path, data)
    assert list(fixes["time"]) == times
    assert ubx.gps_time(times[2])[0] == ubx.gps_time(times[0])[0] + 1


def test_a_nav_pvt_and_nmea_of_the_same_second_are_one_row(tmp_path: Path) -> None:
    rmc = nmea("GPRMC,100501.00,A,2045.31731,N,10553.90999,E,29.16,191.8,190126,,,A")
    data = rmc + b"\r\n" + ubx.nav_pvt(T0, LAT, LON, 15.0, 191.8) + b"\n"
    fixes, report = stream(tmp_path, data)
    (row,) = fixes.itertuples()
    assert row.sentence == "RMC+NAV-PVT" and row.source == "nmea" and row.valid
    assert row.lat == LAT and report.records == 2


def test_a_logged_fix_retrieved_later_is_a_row_of_its_own(tmp_path: Path) -> None:
    old = pd.Timestamp("2026-01-18T08:00:00Z")
    data = ubx.nav_pvt(T0, LAT, LON, 15.0, 191.8) + ubx.log_retrievepos(old, 21.0, 105.0, 3.0, 45.0)
    fixes, _ = stream(tmp_path, data)
    assert list(fixes["sentence"]) == ["NAV-PVT", "LOG-RETRIEVEPOS"]
    assert fixes["time"].iloc[1] == old and fixes["lat"].iloc[1] == 21.0 and fixes["valid"].iloc[1]


def test_a_nav_pvt_with_impossible_values_is_counted_not_read(tmp_path: Path) -> None:
    bad = bytearray(ubx.nav_pvt(T0, LAT, LON, 15.0, 191.8))
    bad[6 + 28 : 6 + 32] = (950_000_000).to_bytes(4, "little", signed=True)  # latitude 95°
    body = bytes(bad[2:-2])
    fixed = ubx_packet(body[0], body[1], body[4:])
    fixes, report = stream(tmp_path, fixed + b"\n")
    assert fixes.empty and report.skipped == {"UBX packets": 1} and report.blank == report.lines_read


def test_sbf_pvt_blocks_are_fixes(tmp_path: Path) -> None:
    t = T0 + pd.Timedelta(milliseconds=250)
    data = ubx.sbf_pvt_geodetic(t, LAT, LON, 15.0, 191.8) + ubx.sbf_receiver_time(t)
    data += ubx.sbf_pvt_geodetic(t + pd.Timedelta(seconds=1), LAT, LON, 15.0, 191.8, mode=0)
    fixes, _ = stream(tmp_path, data)
    assert list(fixes["source"].astype(str)) == ["sbf", "sbf"]
    assert list(fixes["sentence"]) == ["PVTGeodetic+ReceiverTime", "PVTGeodetic"]
    assert fixes["time"].iloc[0] == t and list(fixes["valid"]) == [True, False]
    assert fixes["lat"].iloc[0] == pytest.approx(LAT, abs=1e-12) and fixes["speed_mps"].iloc[0] == pytest.approx(15.0)


# ------------------------------------------------------------- recovery

RMC = nmea("GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")
GGA = nmea("GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")


@pytest.mark.parametrize(
    "sync",
    [
        b"\xb5\x62\x01\x07\xff\x1f",  # a UBX header claiming 8 KiB
        b"\xb5\x62\x01\x07\x5c\x00",  # a NAV-PVT header, the packet cut off
        b"$@\x00\x00\xa7\x0f\x60\x00",  # an SBF PVTGeodetic header with a wrong CRC
        b"\xd3\x00\x40",  # an RTCM3 header claiming 64 bytes
    ],
    ids=["ubx-long", "ubx-cut", "sbf-crc", "rtcm3"],
)
def test_a_stray_sync_never_swallows_the_sentences_after_it(tmp_path: Path, sync: bytes) -> None:
    fixes, report = stream(tmp_path, sync + RMC + b"\r\n" + GGA + b"\r\n" + RMC + b"\r\n")
    assert list(fixes["sentence"]) == ["RMC+GGA", "RMC"]
    assert report.skipped["unrecognised binary bytes"] == len(sync) and report.rejected == 0


def _nmea_at(second: int) -> bytes:
    return nmea(f"GPRMC,1235{second:02d}.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")


_RTCM = bytes(RTCMMessage(payload=bytes([0x3E, 0xD0]) + bytes(17)).serialize())  # a 1005 station position
_BINARY = st.sampled_from(
    [
        ubx.nav_sol(T0, LAT, LON, 5.0, 10.0) + ubx.nav_timegps(T0),
        ubx.hnr_pvt(T0, LAT, LON, 5.0, 10.0),
        ubx.sbf_pvt_geodetic(T0, LAT, LON, 5.0, 10.0),
        _RTCM,
        rtcm3_packet(b"\n$GPRMC," + bytes(range(30))),
        b"\xb5\x62\x01\x06\xff\x00",
        b"$@\x12\x34",
    ]
)
_JUNK = st.binary(min_size=1, max_size=8).map(lambda b: bytes(x | 0x80 for x in b))
_PIECE = st.one_of(_BINARY, _JUNK, st.sampled_from([b"\n", b"\r\n", b""]))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(st.lists(_PIECE, max_size=4), min_size=1, max_size=10))
def test_sentences_among_binary_epochs_false_syncs_and_junk_are_all_read(
    tmp_path: Path, gaps: list[list[bytes]]
) -> None:
    data = b"".join(b"".join(gap) + _nmea_at(k) for k, gap in enumerate(gaps)) + b"\n"
    fixes, report = stream(tmp_path, data)
    nmea_rows = fixes[fixes["source"] == "nmea"]
    assert list(nmea_rows["time"].dt.second) == list(range(len(gaps)))
    # One row for the binary epoch (all at T0, one device), whatever the packets around it.
    binary = fixes[fixes["source"] != "nmea"]
    assert binary["time"].nunique() <= 1 and len(binary) <= 2  # UBX and SBF rows of T0 (two sources)
    assert report.lines_read == data.count(b"\n") == report.records + report.blank + report.rejected


# ------------------------------------------------------------- read as it grows


def _plain(frame: pd.DataFrame) -> pd.DataFrame:
    """Categories and strings as plain values: a table read in parts has other categories."""
    out = frame.reset_index(drop=True)
    for c in out.columns:
        if isinstance(out[c].dtype, pd.CategoricalDtype) or pd.api.types.is_string_dtype(out[c].dtype):
            out[c] = pd.Series(out[c].astype(str).tolist(), dtype=object)
    return out


@pytest.mark.parametrize("log", COMMITTED, ids=lambda p: p.name)
def test_a_capture_read_as_it_grows_gives_the_batch_rows(log: Path) -> None:
    raw = log.read_bytes()
    lines = [line + b"\n" for line in raw.split(b"\n")[:-1]]
    expected, batch = parse_stream_files([log])
    rng = random.Random(log.name)
    cuts = sorted({0, len(lines), *rng.sample(range(len(lines)), min(15, len(lines)))})
    report = ParseReport()
    fr = FileReport(file=str(log))
    report.files.append(fr)
    grow = GrowingStream(report)
    grow.open_file(fr, log.stem)
    parts, ids = [], []
    for a, b in itertools.pairwise(cuts):
        grow.add(a + 1, b"".join(lines[a:b]))
        rows, row_ids = grow.settle()
        parts.append(rows)
        ids.append(row_ids)
    grow.end_file()
    rows, row_ids = grow.settle(final=True)
    parts.append(rows)
    ids.append(row_ids)
    got = pd.concat(parts, ignore_index=True).iloc[np.argsort(np.concatenate(ids), kind="stable")]
    pd.testing.assert_frame_equal(_plain(got), _plain(expected))
    assert report.skipped == batch.skipped and fr.records == batch.files[0].records
