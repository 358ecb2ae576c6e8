"""A sentence is read wherever it starts: after a doubled '$' (gpsd's ST Teseo LIV4F capture writes every
sentence as ``$$GNRMC,…``) or after printable junk, as gpsd reads it."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from console.cli.app import app
from parsers.gnss.nmea import nmea_checksum
from parsers.gnss.stream import parse_stream_files
from parsers.kinds import classify_file
from tests.gpsd_truth import compare_with_gpsd

TESEO = Path(__file__).resolve().parent / "data" / "gpsd" / "st-teseo-liv4f.log"
runner = CliRunner()


def nmea(body: str) -> bytes:
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}".encode("ascii")


RMC = nmea("GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W")
RMC2 = nmea("GPRMC,123520.00,A,4807.040,N,01131.002,E,022.5,084.4,230394,003.1,W")


def test_the_teseo_capture_gives_gpsds_fixes() -> None:
    assert classify_file(TESEO).kind == "nmea"
    fixes, report = parse_stream_files([TESEO])
    report.check()
    counts = compare_with_gpsd(TESEO, fixes)
    assert counts["nmea"] > 0
    assert counts["nmea_matched"] == counts["nmea"], dict(counts)
    assert counts["extra"] == 0, dict(counts)
    # The capture's notes: "One $GPGSV with bad checksum"; nothing else is rejected.
    assert report.rejected == 1, [r.reason for r in report.rejections]
    assert "checksum" in report.rejections[0].reason


def test_gnss_command_reads_the_teseo_capture() -> None:
    result = runner.invoke(app, ["gnss", str(TESEO)])
    assert result.exit_code == 0, result.output
    assert "nothing readable" not in result.output


def test_doubled_start_and_junk_before_a_sentence(tmp_path: Path) -> None:
    path = tmp_path / "rx.log"
    path.write_bytes(b"$" + RMC + b"\n" + b"garbage 12 $" + RMC2 + b"\n")
    fixes, report = parse_stream_files([path])
    report.check()
    assert (report.records, report.rejected) == (2, 0)
    assert len(fixes) == 2 and fixes["valid"].all()
    assert sum(report.skipped.values()) > 0  # the noise is counted, not lost


def test_a_line_with_no_sentence_is_still_rejected(tmp_path: Path) -> None:
    path = tmp_path / "rx.log"
    path.write_bytes(RMC + b"\n$$\nplain words, no sentence\n")
    _, report = parse_stream_files([path])
    report.check()
    assert (report.records, report.rejected) == (1, 2)
