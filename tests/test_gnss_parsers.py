"""GNSS parsers (parsers.gnss.nmea, parsers.gnss.centre) and their rendering (console.sinks.tables.gnss_tables).

Truths: the gpsd regression captures in ../shared/data/nmea (gpsd's own
decoding in each ``.chk``), seed 004's Table 1 as printed, and the device
samples written by sample_logs/make_gnss_samples.py.
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rich.console import Console

from console.sinks.tables.gnss_tables import devices_table, fixes_table, gnss_json
from parsers.gnss.centre import CROSSING_COLUMNS, parse_centre_table, parse_crossing_code
from parsers.gnss.fix_table import FIX_COLUMNS
from parsers.gnss.nmea import KNOT_MPS, DeviceClock, decode_sentence, nmea_checksum
from parsers.gnss.stream import parse_nmea
from parsers.gnss_files import parse_device_stream, parse_gnss, recognise_format
from parsers.sources import InputError
from tests.gpsd_truth import compare_with_gpsd

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
NMEA_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "nmea"
needs_captures = pytest.mark.skipif(
    not NMEA_DATA.is_dir(), reason=f"gpsd captures not found at {NMEA_DATA} (the shared data checkout beside the repo)"
)


def nmea(body: str) -> str:
    """``GPRMC,…`` → ``$GPRMC,…*HH`` with the right checksum."""
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}"


RMC = "GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"
GGA = "GPGGA,123520.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"
VTG = "GPVTG,084.4,T,077.8,M,022.4,N,041.5,K,A"


def write(tmp_path: Path, name: str, lines: list[str] | str, encoding: str = "utf-8") -> Path:
    path = tmp_path / name
    text = lines if isinstance(lines, str) else "\n".join(lines) + "\n"
    path.write_bytes(text.encode(encoding))
    return path


def one_file(tmp_path: Path, lines: list[str], name: str = "rx.log") -> tuple[pd.DataFrame, Any]:
    fixes, report = parse_nmea([write(tmp_path, name, lines)])
    report.check()
    return fixes, report


# ------------------------------------------------------ gpsd acceptance test

# Our valid, dated fixes at a time gpsd reported no fix for (measured; see
# tests/gpsd_truth.py).  Each is a real fix gpsd reported without a time
# (a GLL before gpsd knew the date, which we take from the ZDA after it) or
# an epoch whose cycle gpsd never closed with a report (the capture's last
# epoch; ais-nmea's RMC-VTG-GGA cycles where gpsd's cycle detection skips
# a report).
EXTRA = {
    "ais-nmea.log": 3,
    "bt451.log": 3,
    "firefly-II.log": 0,
    "gp-320fw-2019-04-07-coldboot.log": 1,
    "haicom-305N.log": 1,
    "holux-gm-210.log": 0,
    "nl2008u.log": 0,
    "nmea-fuzzy-cases.log": 0,
}
CAPTURES = sorted(EXTRA)  # listed, not globbed, so that a missing directory skips with its reason


@needs_captures
def test_the_shared_directory_holds_the_eight_captures() -> None:
    assert sorted(p.name for p in NMEA_DATA.glob("*.log")) == CAPTURES


@needs_captures
@pytest.mark.parametrize("capture", CAPTURES)
def test_every_fix_gpsd_decoded_is_one_of_ours(capture: str) -> None:
    """gpsd's TPV reports in the .chk are the truth: lat/lon within 1e-6°, speed within 0.01 m/s, same time."""
    log = NMEA_DATA / capture
    fixes, report = parse_nmea([log])
    report.check()
    counts = compare_with_gpsd(log, fixes)
    assert counts["binary"] == 0  # these captures are NMEA only
    assert counts["nmea_matched"] == counts["nmea"], f"{capture}: {dict(counts)}"
    assert counts["nmea_date_differs"] == 0
    assert counts["extra"] <= EXTRA[capture]


@needs_captures
def test_holux_never_has_a_fix_and_neither_do_we() -> None:
    fixes, _ = parse_nmea([NMEA_DATA / "holux-gm-210.log"])
    assert len(fixes) > 0 and not fixes["valid"].any()
    assert (fixes["fix_quality"] == "no_fix").all()


@needs_captures
@pytest.mark.parametrize("capture", CAPTURES)
def test_every_sentence_gpsd_accepted_is_accepted(capture: str) -> None:
    """The .chk echoes the sentences gpsd took (bad checksums and junk are not echoed)."""
    clock = DeviceClock()
    chk = (NMEA_DATA / (capture + ".chk")).read_bytes().split(b"\n")
    for sentence in (line.rstrip(b"\r") for line in chk if line.startswith((b"$", b"!"))):
        decode_sentence(sentence, clock)  # SentenceError here: we refused what gpsd read


# --------------------------------------------------------------------- NMEA


def test_wrong_checksum_is_rejected_with_its_reason(tmp_path: Path) -> None:
    good = nmea(RMC)
    bad = good[:-2] + ("00" if good[-2:] != "00" else "01")
    fixes, report = one_file(tmp_path, [good, bad])
    assert len(fixes) == 1
    assert report.rejected == 1
    (rejection,) = report.rejections
    assert rejection.line == 2
    assert "checksum mismatch" in rejection.reason
    assert report.rejected_by_reason["checksum"] == 1


def test_sentence_without_checksum_is_accepted(tmp_path: Path) -> None:
    fixes, report = one_file(tmp_path, ["$" + RMC, "$" + GGA])
    assert report.records == 2 and report.rejected == 0
    assert list(fixes["sentence"]) == ["RMC", "GGA"]
    assert fixes["valid"].all()


def test_cut_off_sentence_without_checksum_is_rejected_as_truncated(tmp_path: Path) -> None:
    # holux-gm-210.log ends like this: a partial GGA and no newline.
    fixes, report = one_file(tmp_path, ["$GPGGA,012530.562,4131.7353,N,09336.8150,W,0,00,50."])
    assert fixes.empty
    assert report.rejected_by_reason["truncated"] == 1
    assert "truncated" in report.rejections[0].reason


def test_no_fix_sentences_give_rows_with_valid_false(tmp_path: Path) -> None:
    lines = [
        nmea("GPRMC,012519.563,V,4131.7353,N,09336.8150,W,0.00,,050405,,"),  # status V
        nmea("GPGGA,012520.563,4131.7353,N,09336.8150,W,0,00,50.0,280.2,M,-31.6,M,0.0,0000"),  # quality 0
        nmea("GPRMC,,V,,,,,,,,,,N"),  # nothing at all
    ]
    fixes, report = one_file(tmp_path, lines)
    assert report.records == 3 and report.rejected == 0
    assert not fixes["valid"].any()
    assert fixes["lat"].iloc[0] == pytest.approx(41 + 31.7353 / 60)  # the position printed is kept
    assert math.isnan(fixes["lat"].iloc[2]) and pd.isna(fixes["time"].iloc[2])


def test_ais_proprietary_and_junk_lines_never_crash_and_every_line_is_counted(tmp_path: Path) -> None:
    lines = [
        "# capture header",
        "",
        "!AIVDM,1,1,,B,13aDp<PP000IwSlN?Wm@0?wN2<1T,0*29",
        nmea("GPGSV,3,3,10,28,26,288,31,32,38,065,41"),
        "$PLCS,REV,PLN012054S07,070312,145743",
        nmea(RMC),
        "\x00\x01\x02\xff binary",
        "$GPRMC,000346.03,A,4808\x00\x00\x00",
        "$GP",
        "random text",
        nmea("GPRMC,abc,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"),
        nmea("ZZRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W"),
        nmea("GPRMC,123519.00,A,9907.038,N,01131.000,E,022.4,084.4,230394,003.1,W"),
    ]
    path = tmp_path / "junk.log"
    path.write_bytes("\n".join(lines).encode("latin-1"))
    fixes, report = parse_nmea([path])
    report.check()
    assert report.lines_read == len(lines) == report.records + report.blank + report.rejected
    assert (report.records, report.blank) == (1, 5)  # comment, empty, AIS, GSV, proprietary are blank
    reasons = {r.line: r.reason for r in report.rejections}
    assert "binary data" in reasons[7]
    assert "truncated" in reasons[8]  # the sentence before the NULs is still read, and is cut short
    assert "address field 'GP'" in reasons[9]
    assert "not an NMEA sentence" in reasons[10]
    assert "time field 'abc'" in reasons[11]
    assert "pynmeagps" in reasons[12] and "ZZ" in reasons[12]  # the library's own message
    assert "out of range" in reasons[13]
    assert len(fixes) == 1


_PIECES = st.sampled_from(
    [
        nmea(RMC),
        nmea(GGA),
        nmea(VTG),
        "$GPRMC,,V,,,,,,,,,,N",
        "!AIVDM,1,1,,B,13aD,0*29",
        "head1 ",
        "eot7,",
        "*",
        ",",
        "$",
    ]
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.lists(
        st.one_of(
            st.binary(max_size=60),
            st.lists(_PIECES, max_size=3).map(lambda parts: "".join(parts).encode()),
            st.tuples(_PIECES, st.integers(0, 80)).map(lambda p: p[0].encode()[: p[1]]),  # cut short
        ),
        max_size=12,
    )
)
def test_any_bytes_give_rows_or_reasons_never_an_exception(tmp_path: Path, lines: list[bytes]) -> None:
    path = tmp_path / "fuzz.log"
    # A first line opening like gzip or UTF-16 would be read as such (parsers.sources): keep it plain.
    path.write_bytes(b"# fuzz\n" + b"\n".join(lines))
    fixes, report = parse_nmea([path])
    report.check()
    assert report.lines_read == report.records + report.blank + report.rejected
    assert len(fixes) <= sum(len(line) for line in lines)  # no row from nothing
    assert all(r.reason for r in report.rejections)


@pytest.mark.parametrize("talker", ["GP", "GN", "GL", "GA", "GB", "IN"])
def test_any_talker_is_read(tmp_path: Path, talker: str) -> None:
    fixes, report = one_file(tmp_path, [nmea(talker + RMC[2:]), nmea(talker + GGA[2:]), nmea(talker + VTG[2:])])
    assert report.rejected == 0
    assert list(fixes["sentence"]) == ["RMC", "GGA+VTG"]  # the GGA is a second later; the VTG joins its epoch


def test_rmc_gives_date_time_position_speed_and_course(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(RMC)])
    fix = fixes.iloc[0]
    assert fix["time"] == pd.Timestamp("1994-03-23T12:35:19Z")
    assert fix["lat"] == pytest.approx(48 + 7.038 / 60, abs=1e-9)
    assert fix["lon"] == pytest.approx(11 + 31.0 / 60, abs=1e-9)
    assert fix["course_deg"] == 84.4
    assert fix["valid"] and fix["source"] == "nmea" and fix["device"] == "rx"


def test_south_and_west_are_negative(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea("GPRMC,095305.802,A,2712.6547,S,09345.0335,W,1.93,133.96,080407,,,A")])
    assert fixes["lat"].iloc[0] == pytest.approx(-(27 + 12.6547 / 60))
    assert fixes["lon"].iloc[0] == pytest.approx(-(93 + 45.0335 / 60))


def test_knots_become_metres_per_second_exactly(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(RMC)])
    assert KNOT_MPS == 1852 / 3600
    assert fixes["speed_mps"].iloc[0] == pytest.approx(22.4 * 1852 / 3600, rel=1e-15)  # 11.5236 m/s


def test_a_vtg_joins_the_row_of_its_epoch(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(GGA), nmea(VTG)])
    assert list(fixes["sentence"]) == ["GGA+VTG"]
    assert fixes["speed_mps"].iloc[0] == 22.4 * KNOT_MPS  # knots preferred to km/h; GGA alone has none
    assert fixes["course_deg"].iloc[0] == 84.4


def test_a_vtg_with_no_epoch_to_join_is_its_own_row_without_position(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea("GPVTG,054.7,034.4,,010.8"), nmea(RMC), nmea(VTG), nmea(VTG)])
    assert list(fixes["sentence"]) == ["VTG", "RMC+VTG", "VTG"]
    first = fixes.iloc[0]
    assert not first["valid"] and math.isnan(first["lat"]) and pd.isna(fixes["time"].iloc[0])
    assert first["speed_mps"] == pytest.approx(10.8 / 3.6)  # pre-2.0 form, km/h only
    assert fixes["time"].iloc[2] == fixes["time"].iloc[1]  # a repeated VTG takes the time of the epoch before it


def test_rmc_and_gga_of_one_second_are_one_fix(tmp_path: Path) -> None:
    gga = GGA.replace("123520.00", "123519.00")
    fixes, report = one_file(tmp_path, [nmea(RMC), nmea(gga), nmea(VTG)])
    assert report.records == 3
    (fix,) = fixes.itertuples(index=False)
    assert fix.sentence == "RMC+GGA+VTG" and fix.valid and fix.line == 1
    assert fix.time == pd.Timestamp("1994-03-23T12:35:19Z")
    assert fix.speed_mps == 22.4 * KNOT_MPS and fix.fix_quality == "gnss"


def test_a_gga_before_the_first_rmc_keeps_its_time(tmp_path: Path) -> None:
    early = GGA.replace("123520.00", "123518.00")
    same = GGA.replace("123520.00", "123519.00")
    fixes, _ = one_file(tmp_path, [nmea(early), nmea(same), nmea(RMC), nmea(GGA)])
    assert list(fixes["sentence"]) == ["GGA", "RMC+GGA", "GGA"]
    assert list(fixes["time"].dt.strftime("%H:%M:%S")) == ["12:35:18", "12:35:19", "12:35:20"]
    assert (fixes["time"].dt.date.astype(str) == "1994-03-23").all()  # dated by the RMC after them


def test_a_gga_dated_by_a_later_zda_when_no_rmc_comes(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(GGA), nmea("GPZDA,123521.00,23,03,1994,00,00")])
    assert fixes["time"].iloc[0] == pd.Timestamp("1994-03-23T12:35:20Z")


def test_a_gga_never_dated_has_no_time(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(GGA)])
    assert pd.isna(fixes["time"].iloc[0]) and fixes["valid"].iloc[0]


def test_an_rmc_that_says_no_fix_outweighs_the_gga_of_its_epoch(tmp_path: Path) -> None:
    gga = GGA.replace("123520.00", "123519.00")
    fixes, _ = one_file(tmp_path, [nmea(RMC.replace(",A,", ",V,")), nmea(gga)])
    assert len(fixes) == 1 and not fixes["valid"].iloc[0] and fixes["fix_quality"].iloc[0] == "no_fix"


def test_a_gga_from_zero_satellites_does_not_outweigh_the_rmc_of_its_epoch(tmp_path: Path) -> None:
    # haicom-305N: "GPGGA,095304.802,…,1,00,…" then an RMC with status A; gpsd reports a fix too.
    stale = GGA.replace("123520.00", "123519.00").replace(",1,08,", ",1,00,")
    fixes, _ = one_file(tmp_path, [nmea(stale), nmea(RMC)])
    assert len(fixes) == 1 and fixes["valid"].iloc[0]
    alone, _ = one_file(tmp_path, [nmea(stale)], name="alone.log")
    assert not alone["valid"].iloc[0]


def test_dead_reckoning_is_marked(tmp_path: Path) -> None:
    dr = GGA.replace(",1,08,", ",6,08,")
    rmc_e = RMC + ",E"
    fixes, _ = one_file(tmp_path, [nmea(dr), nmea(rmc_e)])
    assert list(fixes["fix_quality"]) == ["dead_reckoning", "dead_reckoning"]
    assert fixes["valid"].all()


def test_gll_and_gns_are_position_fixes(tmp_path: Path) -> None:
    lines = [
        nmea("GNGLL,4404.14066,N,12118.85481,W,171925.00,A,A"),
        nmea("GNGNS,171926.00,4404.14063,N,12118.85478,W,AN,13,0.9,25.63,11.24,,"),
        nmea("GNGNS,171927.00,4404.14063,N,12118.85478,W,NN,00,,,,,"),
    ]
    fixes, report = one_file(tmp_path, lines)
    assert report.rejected == 0
    assert list(fixes["sentence"]) == ["GLL", "GNS", "GNS"]
    assert list(fixes["valid"]) == [True, True, False]
    assert fixes["lat"].iloc[0] == pytest.approx(44 + 4.14066 / 60)
    assert fixes["lon"].iloc[0] == pytest.approx(-(121 + 18.85481 / 60))


def test_gga_after_midnight_takes_the_next_day(tmp_path: Path) -> None:
    lines = [
        nmea("GPRMC,235959.00,A,4807.038,N,01131.000,E,0.0,0.0,311299,,"),
        nmea("GPGGA,000001.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"),
    ]
    fixes, _ = one_file(tmp_path, lines)
    assert fixes["time"].iloc[1] == pd.Timestamp("2000-01-01T00:00:01Z")


def test_zda_sets_the_date_for_gga(tmp_path: Path) -> None:
    fixes, report = one_file(tmp_path, [nmea("GPZDA,123500.00,23,03,1994,00,00"), nmea(GGA)])
    assert report.blank == 1 and report.records == 1
    assert fixes["time"].iloc[0] == pd.Timestamp("1994-03-23T12:35:20Z")


def test_device_tags_split_an_interleaved_log_and_roles_are_assigned(tmp_path: Path) -> None:
    lines = [
        "head1 " + nmea(RMC),
        "eot7," + nmea(RMC.replace("4807.038", "4806.900")),
        "eot7\t" + nmea(GGA),
        nmea(RMC),  # untagged: the device named by the file
    ]
    path = write(tmp_path, "train.log", lines)
    fixes, report = parse_nmea([path], roles={"head1": "head", "eot7": "eot"})
    assert report.rejected == 0
    assert list(fixes["device"].astype(str)) == ["head1", "eot7", "eot7", "train"]
    assert list(fixes["role"].astype(str)) == ["head", "eot", "eot", ""]
    assert pd.notna(fixes["time"].iloc[2])  # eot7's GGA is dated by eot7's own RMC


def test_an_unknown_role_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="tail"):
        parse_nmea([write(tmp_path, "a.log", [nmea(RMC)])], roles={"a": "tail"})


def test_sentences_run_together_on_one_line_are_both_read(tmp_path: Path) -> None:
    # gp-320fw-2019-04-07-coldboot.log has these: a lost line end, a sentence cut short.
    lines = [
        nmea("GPGSA,A,1,,,,,,,,,,,,,,,") + nmea(RMC),
        "$GPGSV,3,1,11,23,87,270,,13,68,270," + nmea(GGA),
        nmea(RMC) + "$GPGGA,123520.00,48",
    ]
    fixes, report = one_file(tmp_path, lines)
    assert list(fixes["line"]) == [1, 2, 3]
    assert report.records == 2
    assert report.rejections[0].line == 3
    assert report.rejections[0].reason.startswith("sentence 2 of 2 on this line:")


def test_a_gzip_log_reads_like_a_plain_one(tmp_path: Path) -> None:
    import gzip

    path = tmp_path / "rx.log.gz"
    path.write_bytes(gzip.compress((nmea(RMC) + "\n").encode()))
    fixes, report = parse_nmea([path])
    assert len(fixes) == 1 and report.files[0].compressed


def test_a_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError):
        parse_nmea([tmp_path / "nope.log"])


def test_the_fix_table_has_the_documented_columns_and_types(tmp_path: Path) -> None:
    fixes, _ = one_file(tmp_path, [nmea(RMC)])
    assert tuple(fixes.columns) == FIX_COLUMNS
    assert str(fixes["time"].dtype) == "datetime64[ns, UTC]"
    for column in ("device", "role", "source", "sentence", "file"):
        assert isinstance(fixes[column].dtype, pd.CategoricalDtype)
    assert fixes["valid"].dtype == bool and fixes["line"].dtype == "int64"


# -------------------------------------------------- monitoring centre table

TABLE1 = SAMPLES / "co_nhu_van_2026_centre_table.tsv"


def test_table1_parses_to_the_nine_paper_rows_in_time_order() -> None:
    fixes, _, report = parse_centre_table([TABLE1])
    report.check()
    assert (report.records, report.blank, report.rejected) == (9, 1, 0)  # the header is blank
    # Seed 004, Table 1 (Bảng 1), printed newest first.
    times = pd.date_range("2026-01-19 17:05:21", "2026-01-19 17:06:41", freq="10s", tz="UTC")
    assert list(fixes["time"]) == list(times)
    assert list(fixes["line"]) == list(range(10, 1, -1))
    kmh = [55.6, 55.6, 55.6, 55.6, 55.7, 55.3, 55.1, 54.9, 54.6]
    assert list((fixes["speed_mps"] * 3.6).round(9)) == kmh
    assert list(fixes["lat"]) == [20.6] * 6 + [20.7] * 3
    assert (fixes["lon"] == 105.9).all()
    assert set(fixes["device"].astype(str)) == {"VN0001"}
    assert (fixes["role"] == "head").all() and (fixes["source"] == "centre").all()


def test_table1_crossings_11_850_and_11_270_are_both_warning() -> None:
    _, crossings, report = parse_centre_table([TABLE1])
    assert tuple(crossings.columns) == CROSSING_COLUMNS
    assert len(crossings) == 18
    assert set(crossings["crossing"].astype(str)) == {"11+850", "11+270"}
    assert set(crossings["chainage_m"]) == {11850.0, 11270.0}
    assert (crossings["state"] == "warning").all()
    assert set(crossings["state_raw"]) == {"Cảnh báo"}
    assert crossings["time"].is_monotonic_increasing
    assert not report.unknown_labels


def test_centre_table_with_english_headers_semicolons_and_unknown_states(tmp_path: Path) -> None:
    lines = [
        "timestamp;train code;latitude;longitude;speed (km/h);crossing 1 code;crossing 1 state;"
        "crossing 2 code;crossing 2 state;crossing 3 code;crossing 3 state",
        "2026-01-19 17:05:31;SE3;20,61;105,92;36;11+850;normal;Km 11+270;Mất kết nối;;",
        "2026-01-19 17:05:21;SE3;20,60;105,91;36,0;11+850;warning;11+270;testing;12+004;Bình thường",
    ]
    fixes, crossings, report = parse_centre_table([write(tmp_path, "centre.csv", lines)])
    assert report.records == 2 and report.rejected == 0
    assert list(fixes["line"]) == [3, 2]
    assert fixes["speed_mps"].iloc[0] == pytest.approx(10.0)
    assert list(crossings["state"].astype(str)) == ["warning", "testing", "normal", "normal", "disconnected"]
    assert report.unknown_labels == {"crossing state 'testing'": 1}


def test_centre_table_rejects_a_bad_kilometre_post_and_keeps_going(tmp_path: Path) -> None:
    lines = [
        "TIMESTAMP\tMã tàu\tVĩ độ\tKinh độ\tVận tốc (km/h)\tMã đường ngang 1\tTrạng thái kết nối đường ngang 1",
        "2026-01-19 17:06:41\tVN0001\t20,7\t105,9\t54,6\t11850\tCảnh báo",
        "2026-01-19 17:06:31\tVN0001\t20,7\t105,9\t54,9\t11+850\tCảnh báo",
    ]
    fixes, crossings, report = parse_centre_table([write(tmp_path, "t.tsv", lines)])
    assert len(fixes) == 1 and len(crossings) == 1
    assert report.rejections[0].line == 2 and "kilometre post" in report.rejections[0].reason


@pytest.mark.parametrize(
    ("text", "code", "metres"),
    [("11+850", "11+850", 11850.0), ("Km11+270", "11+270", 11270.0), ("0 + 045,5", "0+045.5", 45.5)],
)
def test_crossing_codes_are_kilometre_posts(text: str, code: str, metres: float) -> None:
    assert parse_crossing_code(text) == (code, metres)


@pytest.mark.parametrize("text", ["11850", "11+85", "11-850", "+850", "abc"])
def test_malformed_crossing_codes_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="kilometre post"):
        parse_crossing_code(text)


def test_centre_times_can_be_read_as_local_time() -> None:
    fixes, _, _ = parse_centre_table([TABLE1], utc_offset_h=7)
    assert fixes["time"].iloc[0] == pd.Timestamp("2026-01-19T10:05:21Z")


# ----------------------------------------------------------- device streams


def test_device_csv_and_jsonl_samples_give_the_same_fixes() -> None:
    csv_fixes, csv_report = parse_device_stream([SAMPLES / "gnss_devices.csv"])
    json_fixes, json_report = parse_device_stream([SAMPLES / "gnss_devices.jsonl"])
    assert (csv_report.rejected, json_report.rejected) == (0, 0)
    assert len(csv_fixes) == len(json_fixes) == 182  # 91 fixes from each unit, every 2 s for 3 min
    for column in ("time", "device", "role", "lat", "lon", "course_deg", "valid"):
        assert csv_fixes[column].equals(json_fixes[column]), column
    pd.testing.assert_series_equal(csv_fixes["speed_mps"], json_fixes["speed_mps"], rtol=1e-12)  # m/s vs km/h
    assert csv_fixes.groupby("device", observed=True).size().to_dict() == {"eot1": 91, "head1": 91}
    outage = csv_fixes[~csv_fixes["valid"]]
    assert list(outage["device"].astype(str)) == ["eot1"] and outage["lat"].isna().all()
    assert csv_fixes["time"].iloc[0] == pd.Timestamp("2026-01-19T10:05:00Z")


def test_device_stream_times_with_a_zone_become_utc_and_naive_times_are_utc(tmp_path: Path) -> None:
    lines = [
        "time,device,role,lat,lon,speed_kmh",
        "2026-01-19T17:05:00+07:00,h,head,20.6,105.9,54",
        "2026-01-19 10:05:02,h,head,20.6,105.9,54",
        "2026-01-19T10:05:04.250Z,h,head,20.6,105.9,54",
    ]
    fixes, report = parse_device_stream([write(tmp_path, "h.csv", lines)])
    assert report.rejected == 0
    assert list(fixes["time"]) == [
        pd.Timestamp("2026-01-19T10:05:00Z"),
        pd.Timestamp("2026-01-19T10:05:02Z"),
        pd.Timestamp("2026-01-19T10:05:04.25Z"),
    ]
    assert fixes["speed_mps"].iloc[0] == pytest.approx(15.0)


def test_device_stream_rows_that_do_not_parse_are_rejected_with_reasons(tmp_path: Path) -> None:
    lines = [
        '{"time": "2026-01-19T10:05:00Z", "device": "e", "role": "eot", "lat": 20.6, "lon": 105.9}',
        '{"time": "yesterday", "lat": 20.6, "lon": 105.9}',
        '{"time": "2026-01-19T10:05:02Z", "role": "driver", "lat": 20.6, "lon": 105.9}',
        "[1, 2]",
        '{"time": "2026-01-19T10:05:04Z", "lat": 20.6',
    ]
    fixes, report = parse_device_stream([write(tmp_path, "e.jsonl", lines)])
    report.check()
    assert len(fixes) == 1 and report.rejected == 4
    reasons = [r.reason for r in report.rejections]
    assert "not a date and time" in reasons[0]
    assert "not head or eot" in reasons[1]
    assert "JSON object" in reasons[2]
    assert "not valid JSON" in reasons[3]


# ------------------------------------------------------- format recognition


@pytest.mark.parametrize(
    ("name", "lines", "fmt"),
    [
        ("a.log", ["# header", nmea(RMC)], "nmea"),
        ("b.txt", ["head1 " + nmea(RMC)], "nmea"),
        ("c.txt", ["!AIVDM,1,1,,B,13aDp<PP000IwSlN?Wm@0?wN2<1T,0*29"], "nmea"),
        ("d.txt", ['{"time": "2026-01-19T10:05:00Z", "lat": 1, "lon": 2}'], "jsonl"),
        ("e.txt", ["time;device;lat;lon;speed", "2026-01-19T10:05:00Z;x;1;2;3"], "csv"),
        ("f.txt", ["TIMESTAMP,Mã tàu,Vĩ độ,Kinh độ,Vận tốc (km/h)"], "centre"),
        ("g.txt", ["hello world", "more"], "unknown"),
        ("h.txt", [""], "unknown"),
    ],
)
def test_formats_are_recognised_by_content(tmp_path: Path, name: str, lines: list[str], fmt: str) -> None:
    assert recognise_format(write(tmp_path, name, lines)) == fmt


def test_parse_gnss_merges_every_format_in_time_order(tmp_path: Path) -> None:
    head = write(tmp_path, "head1.nmea", [nmea("GPRMC,170530.00,A,2036.000,N,10554.000,E,30.0,20.0,190126,,")])
    fixes, report, crossings = parse_gnss(
        [TABLE1, head, SAMPLES / "gnss_devices.jsonl", write(tmp_path, "x.bin", ["\x00\x01 junk", "more junk"])],
        roles={"head1": "head"},
    )
    report.check()
    assert len(fixes) == 9 + 1 + 182
    assert fixes["time"].is_monotonic_increasing
    assert set(fixes["source"].astype(str)) == {"centre", "nmea", "jsonl"}
    assert fixes.loc[fixes["device"] == "head1", "role"].iloc[0] == "head"
    assert len(crossings) == 18
    junk = report.files[-1]
    assert junk.rejected == 2 and report.rejected_by_reason["format"] == 2
    assert "unrecognised GNSS format" in report.rejections[0].reason


def test_parse_gnss_keeps_file_order_among_equal_times(tmp_path: Path) -> None:
    a = write(tmp_path, "a.log", [nmea(RMC)])
    b = write(tmp_path, "b.log", [nmea(RMC)])
    fixes, _, _ = parse_gnss([b, a])
    assert list(fixes["device"].astype(str)) == ["b", "a"]


# --------------------------------------------------------------- rendering


def test_gnss_json_gives_utc_times_with_z_and_null_for_missing_values(tmp_path: Path) -> None:
    fixes, report = one_file(tmp_path, [nmea(GGA), nmea(RMC), nmea(VTG)])
    doc = gnss_json(fixes, report)
    json.dumps(doc, allow_nan=False)  # no NaN can reach the JSON
    first, rmc = doc["fixes"]
    assert first["time"] == "1994-03-23T12:35:20.000Z" and first["speed_mps"] is None  # a GGA dated by the RMC after it
    assert rmc["time"] == "1994-03-23T12:35:19.000Z"
    none, _ = one_file(tmp_path, [nmea(VTG)], name="vtg.log")
    vtg = gnss_json(none, report)["fixes"][0]
    assert vtg["lat"] is None and vtg["valid"] is False and vtg["time"] is None
    assert set(rmc) == {
        "time",
        "lat",
        "lon",
        "speed_mps",
        "course_deg",
        "valid",
        "device",
        "role",
        "sentence",
        "file",
        "line",
        "fix_quality",
    }
    assert doc["parse_report"]["records"] == 3


def test_tables_fit_80_columns_and_show_log_text_literally(tmp_path: Path) -> None:
    fixes, _, _ = parse_gnss([TABLE1, write(tmp_path, "[bold]x.log", ["head1 " + nmea(RMC)])])
    console = Console(width=80, record=True, color_system=None)
    console.print(fixes_table(fixes, limit=5))
    console.print(devices_table(fixes))
    text = console.export_text()
    assert max(map(len, text.splitlines())) <= 80
    assert "[bold]x.log" in "".join(line.strip() for line in text.splitlines())  # a file name is not markup
    assert "VN0001" in text and "head1" in text
    assert "first 5 of 10 fixes" in text


def test_the_fixes_table_shows_the_degrees_the_source_carries(tmp_path: Path) -> None:
    """The monitoring centre's table gives 0.1°: shown 20.6, not 20.60000 (a precision it never had); finer
    sources keep up to 5 decimals (about a metre), one format per column."""

    def shown(path: Path) -> str:
        fixes, _report, _crossings = parse_gnss([path])
        con = Console(width=200, record=True, file=io.StringIO())
        con.print(fixes_table(fixes))
        return con.export_text()

    centre = shown(TABLE1)
    assert " 20.6 " in centre and " 105.9 " in centre and "20.60000" not in centre
    fine = tmp_path / "units.csv"
    fine.write_text(
        "time,device,role,lat,lon,speed\n"
        "2026-01-19T10:00:00Z,T1-head,head,20.6,105.9,1.5\n"
        "2026-01-19T10:00:01Z,T1-head,head,20.612345678,105.91,1.5\n",
        "utf-8",
    )
    text = shown(fine)
    assert " 20.60000 " in text and " 20.61235 " in text  # the column's finest value sets its decimals
    assert " 105.90 " in text and " 105.91 " in text
