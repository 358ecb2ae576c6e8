"""A file of the wrong kind is refused with one line naming it and what it looks like (exit 2),
by every command, not read as every line rejected."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from console.cli.app import app

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
runner = CliRunner()

DIAG = SAMPLES / "example_station.log"
WRONG_FOR_DIAG = {
    "gnss device CSV": (SAMPLES / "gnss_devices.csv", "GNSS device CSV"),
    "gnss JSON lines": (SAMPLES / "gnss_devices.jsonl", "JSON lines"),
    "monitoring-centre table": (SAMPLES / "co_nhu_van_2026_centre_table.tsv", "monitoring-centre table"),
    "sensor frames": (SAMPLES / "sensor_frames.txt", "frame log"),
    "voltages": (SAMPLES / "am_thuong_2021-06-06_voltages.csv", "voltage table"),
}
DIAG_COMMANDS = {
    "analyze": [],
    "speeds": [],
    "sections": ["--layout", "example"],
    "health": [],
    "approach": ["--layout", "example"],
}


@pytest.mark.parametrize("command", list(DIAG_COMMANDS))
@pytest.mark.parametrize("kind", list(WRONG_FOR_DIAG))
def test_diag_commands_refuse_another_kind_of_file(command: str, kind: str) -> None:
    path, looks_like = WRONG_FOR_DIAG[kind]
    result = runner.invoke(app, [command, str(path), *DIAG_COMMANDS[command]])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1
    assert path.name in lines[0] and "not an axle-counter diagnostic log" in lines[0]
    assert looks_like in lines[0]


@pytest.mark.parametrize("command", ["gnss", "crossing"])
def test_gnss_commands_refuse_a_diagnostic_log(command: str) -> None:
    extra = ["--layout", "example"] if command == "crossing" else []
    result = runner.invoke(app, [command, str(DIAG), *extra])
    assert result.exit_code == 2, result.output
    assert "nothing readable as GNSS: looks like an axle-counter diagnostic log" in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_a_damaged_diagnostic_log_is_still_read_line_by_line(tmp_path: Path) -> None:
    # Refusal is for files that plainly hold something else; damage is rejected per line.
    damaged = tmp_path / "damaged.log"
    good = DIAG.read_bytes().splitlines(keepends=True)
    damaged.write_bytes(b"".join(good[:200]) + b"\x00\xff garbage line\n" + b"".join(good[200:400]))
    result = runner.invoke(app, ["analyze", str(damaged), "--json"])
    assert result.exit_code == 0, result.output
    assert '"rejected":1' in result.output.replace(" ", "")


# A file with nothing in it readable as what the command reads (an image, a README, notes): one line,
# exit 2, as gnss does; never an empty table with hundreds of rejected "lines".
def _png(path: Path) -> Path:
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    rows = b"".join(b"\x00" + bytes((x * 7 + y * 3) % 256 for x in range(64)) for y in range(64))
    header = struct.pack(">IIBBBBB", 64, 64, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    )
    return path


def _readme(path: Path) -> Path:
    # The project's own README: prose that quotes a Diag_id: record and NMEA, lines of no format.
    path.write_bytes((SAMPLES.parent / "README.md").read_bytes())
    return path


def _notes(path: Path) -> Path:
    path.write_text("shift notes\nWS4 cleaned at 09:00\nno fault found\n")
    return path


NOT_READABLE = {"png": _png, "readme": _readme, "notes": _notes}
DIAG_LOG = "an axle-counter diagnostic log"
ONE_KIND_COMMANDS = {
    **{c: (DIAG_COMMANDS[c], DIAG_LOG) for c in DIAG_COMMANDS},
    "analyze --jsonl": ([], DIAG_LOG),
    "frames": ([], "sensor frames or a CAN log"),
    "health --voltages": ([], "a receiver-voltage table"),
    "gnss": ([], "GNSS"),
    "crossing": (["--layout", "example"], "GNSS"),
}


@pytest.mark.parametrize("command", list(ONE_KIND_COMMANDS))
@pytest.mark.parametrize("kind", list(NOT_READABLE))
def test_a_file_with_nothing_readable_is_refused_in_one_line(tmp_path: Path, command: str, kind: str) -> None:
    path = NOT_READABLE[kind](tmp_path / f"input.{kind}")
    extra, what = ONE_KIND_COMMANDS[command]
    result = runner.invoke(app, [*command.split(), str(path), *extra])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert lines[-1].startswith("trackside: error: ") and path.name in lines[-1]
    assert f"nothing readable as {what}" in lines[-1], lines[-1]
    if command != "analyze --jsonl":  # --jsonl may have streamed rejected lines before the end
        assert len(lines) == 1, result.output


def test_an_empty_log_is_still_zero_records_not_an_error(tmp_path: Path) -> None:
    empty = tmp_path / "empty.log"
    empty.write_bytes(b"")
    result = runner.invoke(app, ["analyze", str(empty), "--json"])
    assert result.exit_code == 0, result.output


def test_an_empty_gnss_export_is_zero_fixes_beside_the_others_not_an_error(tmp_path: Path) -> None:
    """A unit that logged nothing leaves an empty export: gnss and crossing refused it ("nothing readable as
    GNSS: an empty file"), and with it the whole run of a day's files, where analyze, frames and health read
    an empty file as zero records (docs/usage.md; refuse_wrong_kind's own rule)."""
    import json

    from tests.conftest import SAMPLES

    empty = tmp_path / "T2-eot.csv"
    empty.write_bytes(b"")
    csv = str(SAMPLES / "crossing_example.csv")
    alone = runner.invoke(app, ["gnss", str(empty), "--json"])
    assert alone.exit_code == 0, alone.output
    assert json.loads(alone.stdout)["fixes"] == []
    both = runner.invoke(app, ["gnss", csv, str(empty), "--json"])
    assert both.exit_code == 0, both.output
    assert len(json.loads(both.stdout)["fixes"]) == 187
    crossing = runner.invoke(app, ["crossing", csv, str(empty), "--layout", "example", "--json"])
    assert crossing.exit_code == 0, crossing.output
    assert len(json.loads(crossing.stdout)["timelines"]) == 4


def test_records_after_a_banner_or_a_long_preamble_are_recognised(tmp_path: Path) -> None:
    """An export that opens with a banner, 3,000 lines of junk or a 70 kB line: its records are still read,
    and every line before them is rejected with its reason (the totals add up)."""
    import json

    from tests.conftest import SAMPLES

    records = (SAMPLES / "ws4_subsecond.log").read_bytes()
    n = records.count(b"\n")
    for name, preamble, junk in (
        ("banner.log", b"ACS export 2015-10-31\nboard 4083\n", 2),
        ("preamble.log", b"".join(b"junk line %d\n" % i for i in range(3000)), 3000),
        ("longline.log", b"X" * 70_000 + b"\n", 1),
    ):
        log = tmp_path / name
        log.write_bytes(preamble + records)
        res = CliRunner().invoke(app, ["analyze", str(log), "--json"])
        assert res.exit_code == 0, (name, res.output)
        (f,) = json.loads(res.stdout)["parse_report"]["files"]
        assert (f["lines_read"], f["records"], f["rejected"]) == (n + junk, n, junk), name
    # An NMEA capture after 3,000 comment lines is GNSS, not "an empty file".
    nmea = tmp_path / "late.nmea"
    nmea.write_bytes(b"# comment\n" * 3000 + b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\n")
    res = CliRunner().invoke(app, ["gnss", str(nmea), "--json"])
    assert res.exit_code == 0, res.output
    assert len(json.loads(res.stdout)["fixes"]) == 1


@pytest.mark.parametrize("first", ["sep=,", "Fleet export, train VN0001"])
def test_a_device_csv_with_a_title_or_sep_line_is_read_not_refused(tmp_path: Path, first: str) -> None:
    """Excel's 'sep=,' line or a title before the header: the CSV reader rejects that line with its reason and
    reads the rows; the file-kind check does not refuse the whole file before it is read."""
    import json

    sample = (SAMPLES / "crossing_example.csv").read_text(encoding="utf-8")
    path = tmp_path / "export.csv"
    path.write_text(f"{first}\n{sample}", encoding="utf-8")
    res = runner.invoke(app, ["gnss", str(path), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    (f,) = doc["parse_report"]["files"]
    rows = sample.count("\n") - 1  # less the header
    assert (f["lines_read"], f["records"], f["blank"], f["rejected"]) == (rows + 2, rows, 1, 1)
    assert [r["line"] for r in doc["parse_report"]["rejections"]] == [1]
