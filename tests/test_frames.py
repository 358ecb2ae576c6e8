"""Intelligent-sensor frames (seed 002) and CAN count frames (seed 000): parsing and events.

The frame layout, the text format and the CAN payload are ours, documented
in docs/frames.md; these tests are its specification.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import gzip
import time
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
import pandas as pd
import pytest

from console.analysis.events.detection import DOWN, UNKNOWN, UP, DetectionEvent, EventKind
from console.analysis.frame_events import frames_to_events
from parsers.frames.can import count_frames_only, parse_can
from parsers.frames.can_report import CAN_COLUMNS, CanFileReport
from parsers.frames.sensor import frame_line_problem, parse_frames
from parsers.frames.table import FRAME_COLUMNS, check_byte_mask, decode_status, encode_status
from parsers.sources import InputError
from tests.conftest import SAMPLES

T0 = dt.datetime(2021, 6, 6, 10, 15, 0, tzinfo=dt.UTC)
CLEAR = (0x03, 0xA5)  # self-test loop: T = 3 s, check byte

Row = tuple[float, str, int, int]  # (seconds after T0, sensor, byte 1, byte 2)


def ns(seconds: float) -> int:
    return int(pd.Timestamp(T0.replace(tzinfo=None)).value + round(seconds * 1e9))


def line(seconds: float, sensor: str, b1: int, b2: int, *, space: bool = False) -> str:
    t = T0 + dt.timedelta(seconds=seconds)
    sep = " " if space else ""
    return f"{t:%Y-%m-%dT%H:%M:%S}.{t.microsecond // 1000:03d} {sensor} {b1:02X}{sep}{b2:02X}"


def write_frames(path: Path, rows: list[Row]) -> Path:
    path.write_text("".join(line(*r) + "\n" for r in rows), encoding="utf-8")
    return path


def write_raw(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def parse_rows(tmp_path: Path, rows: list[Row]) -> pd.DataFrame:
    frames, report = parse_frames([write_frames(tmp_path / "f.txt", rows)])
    assert report.rejected == 0
    return frames


def events_of(tmp_path: Path, rows: list[Row], **kw: object) -> list[DetectionEvent]:
    return frames_to_events(parse_rows(tmp_path, rows), **kw)  # type: ignore[arg-type]


def kinds(events: list[DetectionEvent]) -> list[str]:
    return [str(e.kind) for e in events]


def can_messages(rows: list[Row], *, node: dict[str, int] | None = None, foreign: bool = True) -> list[can.Message]:
    """Count frames for rows (seq and total consistent), plus foreign traffic."""
    node = node or {"AC07": 7, "AC08": 8}
    seq: dict[str, int] = {}
    total: dict[str, int] = {}
    last: dict[str, int] = {}
    out = []
    for s, sensor, b1, b2 in rows:
        count = 0 if (b2 == 0xA5 and not last.get(sensor, 0) >= 164) else b2
        total[sensor] = total.get(sensor, 500) + max(count - last.get(sensor, count), 0)
        last[sensor] = count
        sq = seq.get(sensor, 0)
        seq[sensor] = (sq + 1) % 256
        data = bytes([b1, b2, total[sensor] & 0xFF, total[sensor] >> 8, sq])
        stamp = (T0 + dt.timedelta(seconds=s)).timestamp()
        out.append(can.Message(timestamp=stamp, arbitration_id=0x180 + node[sensor], data=data, is_extended_id=False))
    if foreign:
        stamp = (T0 + dt.timedelta(seconds=0.05)).timestamp()
        out += [
            can.Message(timestamp=stamp, arbitration_id=0x701, data=b"\x05", is_extended_id=False),
            can.Message(timestamp=stamp, arbitration_id=0x187, data=bytes(5), is_extended_id=True),
            can.Message(timestamp=stamp, arbitration_id=0x187, is_remote_frame=True, dlc=5, is_extended_id=False),
            can.Message(timestamp=stamp, is_error_frame=True),
        ]
    return sorted(out, key=lambda m: m.timestamp)


@pytest.fixture
def utc() -> Iterator[None]:
    """python-can's ASC writer dates the measurement in local time: pin the zone."""
    mp = pytest.MonkeyPatch()
    mp.setenv("TZ", "UTC")
    time.tzset()
    yield
    mp.undo()
    time.tzset()


def write_can(path: Path, msgs: list[can.Message]) -> Path:
    suffix = path.suffix
    writer: can.io.generic.MessageWriter
    if suffix == ".log":
        writer = can.CanutilsLogWriter(path, channel="can0")
    elif suffix == ".asc":
        writer = can.ASCWriter(path)
    else:
        writer = can.BLFWriter(path)
    with writer:
        for m in msgs:
            writer.on_message_received(m)
    return path


TRAIN: list[Row] = [
    (0.0, "AC07", *CLEAR),
    (0.5, "AC08", *CLEAR),
    (2.0, "AC07", 0x00, 1),
    (2.5, "AC07", 0x00, 3),
    (3.0, "AC07", 0x01, 4),
    (3.5, "AC08", 0x00, 1),
    (4.0, "AC08", 0x24, 2),  # SES2 + ERR
    (4.5, "AC08", 0x20, 4),  # SES2
    (5.0, "AC07", *CLEAR),
    (5.5, "AC08", *CLEAR),  # S2 normal again
    (7.0, "AC07", 0x08, 2),  # DER: S3→S1
    (8.0, "AC07", *CLEAR),
    (9.0, "AC08", *CLEAR),
]


# --- the status byte -----------------------------------------------------------------


def test_status_bits_are_read_msb_first() -> None:
    bits = decode_status(np.array([0x80, 0x40, 0x20, 0x10, 0x08, 0x04, 0x03], np.uint8))
    assert bits["sys"].tolist() == [True, False, False, False, False, False, False]
    assert bits["ses1"].tolist() == [False, True, False, False, False, False, False]
    assert bits["ses2"].tolist() == [False, False, True, False, False, False, False]
    assert bits["ses3"].tolist() == [False, False, False, True, False, False, False]
    assert bits["der"].tolist() == [False, False, False, False, True, False, False]
    assert bits["err"].tolist() == [False, False, False, False, False, True, False]
    assert bits["t_since_s"].tolist() == [0, 0, 0, 0, 0, 0, 3]


def test_encode_status_is_the_inverse_of_decode() -> None:
    b = encode_status(sys=True, ses=(False, True, False), der=True, err=True, t_since_s=2)
    assert b == 0b1010_1110
    bits = decode_status(np.array([b], np.uint8))
    assert [bool(bits[k][0]) for k in ("sys", "ses1", "ses2", "ses3", "der", "err")] == [
        True,
        False,
        True,
        False,
        True,
        True,
    ]
    assert int(bits["t_since_s"][0]) == 2


def test_frame_line_decodes_into_the_documented_columns(tmp_path: Path) -> None:
    frames = parse_rows(tmp_path, [(2.125, "AC07", 0x4A, 0x05)])
    assert tuple(frames.columns) == FRAME_COLUMNS
    r = frames.iloc[0]
    assert r["time"] == pd.Timestamp("2021-06-06T10:15:02.125")
    assert (r["sensor"], r["status"], r["byte2"], r["line"]) == ("AC07", 0x4A, 5, 1)
    assert (r["sys"], r["ses1"], r["ses2"], r["ses3"], r["der"], r["err"]) == (False, True, False, False, True, False)
    assert r["t_since_s"] == 2
    assert not r["check"]
    assert str(frames["time"].dtype) == "datetime64[ns]"
    assert frames["sensor"].dtype == "category"


def test_a_space_between_the_two_bytes_is_allowed(tmp_path: Path) -> None:
    path = tmp_path / "f.txt"
    path.write_text(line(0, "AC07", 0x4A, 0x05, space=True) + "\n" + line(1, "AC07", 0x4A, 0x05) + "\n")
    frames, report = parse_frames([path])
    assert report.rejected == 0
    assert frames["status"].tolist() == [0x4A, 0x4A] and frames["byte2"].tolist() == [5, 5]


def test_times_keep_nanoseconds_and_zones_become_utc(tmp_path: Path) -> None:
    path = write_raw(
        tmp_path / "f.txt",
        b"2021-06-06T10:15:02.123456789 AC07 03A5\n"
        b"2021-06-06T12:15:02+02:00 AC07 03A5\n"
        b"2021-06-06T10:15:03Z AC07 03A5\n",
    )
    frames, _ = parse_frames([path])
    assert frames["time"].tolist() == [
        pd.Timestamp("2021-06-06T10:15:02.123456789"),
        pd.Timestamp("2021-06-06T10:15:02"),
        pd.Timestamp("2021-06-06T10:15:03"),
    ]


# --- every line is accounted for ------------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "category"),
    [
        ("2021-06-06T10:15:02 AC07", "fields"),
        ("2021-06-06T10:15:02 AC07 4A 05 FF", "fields"),
        ("10:15:02 AC07 4A05", "time"),
        ("2021-06-06 AC07 4A05", "time"),
        ("2021-02-30T10:15:02 AC07 4A05", "time"),
        ("1066-10-14T10:15:02 AC07 4A05", "time"),
        ("2021-06-06T10:15:02 AC07 4A0", "frame length"),
        ("2021-06-06T10:15:02 AC07 4A0512", "frame length"),
        ("2021-06-06T10:15:02 AC07 4 A05", "frame length"),
        ("2021-06-06T10:15:02 AC07 4G05", "hex"),
        ("2021-06-06T10:15:02 AC07 0x4A", "hex"),
        ("2021-06-06T10:15:02 " + "S" * 33 + " 4A05", "sensor"),
        ("2021-06-06T10:15:02 AC\x1b07 4A05", "sensor"),
    ],
)
def test_a_malformed_line_is_rejected_with_its_reason(tmp_path: Path, text: str, category: str) -> None:
    path = write_raw(tmp_path / "f.txt", (line(0, "AC07", *CLEAR) + "\n" + text + "\n").encode())
    frames, report = parse_frames([path])
    assert len(frames) == 1
    assert dict(report.rejected_by_reason) == {category: 1}
    (rej,) = report.rejections
    assert (rej.file, rej.line) == (str(path), 2)
    assert rej.reason
    assert "\x1b" not in rej.text  # escaped, never raw
    assert frame_line_problem(text) is not None and frame_line_problem(text)[0] == category  # type: ignore[index]


def test_a_check_byte_frame_with_der_set_breaks_the_protocol(tmp_path: Path) -> None:
    path = write_frames(tmp_path / "f.txt", [(0, "AC07", *CLEAR), (1, "AC07", 0x0B, 0xA5), (2, "AC07", *CLEAR)])
    frames, report = parse_frames([path])
    assert len(frames) == 2
    assert dict(report.rejected_by_reason) == {"protocol": 1}
    assert report.rejections[0].line == 2
    assert "DER" in report.rejections[0].reason
    assert report.rejections[0].text.endswith("0BA5")
    report.check()


def test_a5_with_der_set_right_after_164_is_the_count_165_not_a_violation(tmp_path: Path) -> None:
    frames = parse_rows(tmp_path, [(0, "AC07", 0x08, 164), (1, "AC07", 0x08, 0xA5), (2, "AC07", 0x08, 166)])
    assert frames["check"].tolist() == [False, False, False]


def test_comments_and_blank_lines_count_as_blank(tmp_path: Path) -> None:
    path = write_raw(tmp_path / "f.txt", f"# header\n\n   \n  # indented\n{line(0, 'AC07', *CLEAR)}\n".encode())
    _, report = parse_frames([path])
    assert (report.lines_read, report.records, report.blank, report.rejected) == (5, 1, 4, 0)


def test_crlf_line_ends_and_a_utf8_bom_are_read(tmp_path: Path) -> None:
    body = "\r\n".join(line(s, "AC07", *CLEAR) for s in range(3)) + "\r\n"
    frames, report = parse_frames([write_raw(tmp_path / "f.txt", b"\xef\xbb\xbf" + body.encode())])
    assert len(frames) == 3 and report.rejected == 0
    assert report.files[0].encoding == "utf-8-sig"


def test_a_rejected_crlf_line_is_shown_without_its_line_end(tmp_path: Path) -> None:
    # A Windows-written log: the CR belongs to the line end, as the diagnostic and GNSS readers show it.
    frames_file = write_raw(tmp_path / "f.txt", b"2021-06-06 10:15:01 AC07 4A05\r\n")
    can_file = tmp_path / "bus.log"
    can_file.write_bytes(b"(1.0) can0 187#03A5E80300 R\r\n(2.0) can0 187#03A5E803 R\r\nnot a frame\r\n")
    _, frame_report = parse_frames([frames_file])
    _, can_report = parse_can([can_file])
    assert [r.text for r in frame_report.rejections] == ["2021-06-06 10:15:01 AC07 4A05"]
    assert sorted((r.line, r.text) for r in can_report.rejections) == [
        (2, "(2.0) can0 187#03A5E803 R"),
        (3, "not a frame"),
    ]


def test_gzip_input_is_read_by_its_magic_bytes(tmp_path: Path) -> None:
    body = "".join(line(s, "AC07", *CLEAR) + "\n" for s in range(3)).encode()
    frames, report = parse_frames([write_raw(tmp_path / "frames.txt", gzip.compress(body))])
    assert len(frames) == 3 and report.files[0].compressed


def test_binary_junk_is_rejected_as_binary(tmp_path: Path) -> None:
    path = write_raw(tmp_path / "f.txt", line(0, "AC07", *CLEAR).encode() + b"\n\x00\x01\x02\xff\xfe junk\n")
    frames, report = parse_frames([path])
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"binary": 1}
    assert "\\x00" in report.rejections[0].text


def test_a_one_megabyte_line_is_rejected_as_too_long(tmp_path: Path) -> None:
    big = b"A" * (1 << 20)
    path = write_raw(tmp_path / "f.txt", big + b"\n" + line(0, "AC07", *CLEAR).encode() + b"\n")
    frames, report = parse_frames([path])
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"too long": 1}
    assert report.rejections[0].line == 1 and len(report.rejections[0].text) < 200


def test_an_unterminated_last_line_is_parsed_if_whole(tmp_path: Path) -> None:
    frames, report = parse_frames([write_raw(tmp_path / "f.txt", line(0, "AC07", *CLEAR).encode())])
    assert len(frames) == 1 and report.files[0].ends_without_newline


def test_a_cut_off_last_line_is_rejected_as_truncated(tmp_path: Path) -> None:
    path = write_raw(tmp_path / "f.txt", (line(0, "AC07", *CLEAR) + "\n" + line(1, "AC07", *CLEAR)[:-2]).encode())
    frames, report = parse_frames([path])
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"truncated": 1}


def test_line_totals_add_up_over_several_files(tmp_path: Path) -> None:
    a = write_raw(tmp_path / "a.txt", f"# a\n{line(0, 'AC07', *CLEAR)}\nnonsense\n".encode())
    b = write_raw(tmp_path / "b.txt", gzip.compress(f"{line(1, 'AC07', *CLEAR)}\n\n\x00\x00\n".encode()))
    frames, report = parse_frames([a, b])
    assert (report.lines_read, report.records, report.blank, report.rejected) == (6, 2, 2, 2)
    assert report.lines_read == report.records + report.blank + report.rejected
    for f in report.files:
        assert f.lines_read == f.records + f.blank + f.rejected
    assert frames["file"].tolist() == [str(a), str(b)]


def test_a_missing_file_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        parse_frames([tmp_path / "nope.txt"])


# --- check byte or count 165 ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("counts", "check"),
    [
        ([0xA5, 1], [True, False]),  # a log that starts with 0xA5 starts clear
        ([164, 0xA5], [False, False]),  # a train standing at 165 axles
        ([164, 0xA5, 0xA5, 170], [False, False, False, False]),  # counting goes through 165
        ([160, 0xA5, 170], [False, False, False]),  # 165 passed between two frames
        ([160, 0xA5], [False, True]),  # cleared after 160 axles
        ([164, 0xA5, 2], [False, True, False]),  # cleared, a new train counts from 1
        ([170, 0xA5, 3], [False, True, False]),  # above 165: only a clear gives 0xA5
    ],
)
def test_byte2_a5_is_read_as_check_byte_or_count_from_context(counts: list[int], check: list[bool]) -> None:
    n = len(counts)
    got = check_byte_mask(np.zeros(n, np.int64), np.arange(n, dtype=np.int64), np.array(counts, np.uint8))
    assert got.tolist() == check


def test_check_byte_context_is_per_sensor_and_in_time_order() -> None:
    sensor = np.array([0, 1, 0, 1])
    t = np.array([2, 1, 1, 2])  # sensor 0: 164 at t=1, A5 at t=2
    b2 = np.array([0xA5, 164, 164, 0xA5], np.uint8)
    assert check_byte_mask(sensor, t, b2).tolist() == [False, False, False, False]
    assert check_byte_mask(np.array([0, 1]), np.array([1, 2]), np.array([164, 0xA5], np.uint8)).tolist() == [
        False,
        True,
    ]


# --- CAN count frames ---------------------------------------------------------------------


def test_candump_count_frames_decode_status_count_total_and_sequence(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text("(1622974502.125000) can0 187#4A05E80307 R\n")
    frames, report = parse_can([path])
    assert tuple(frames.columns) == CAN_COLUMNS
    r = frames.iloc[0]
    assert r["time"] == pd.Timestamp("2021-06-06T10:15:02.125")
    assert (r["sensor"], r["status"], r["byte2"], r["total"], r["seq"], r["can_id"]) == (
        "AC07",
        0x4A,
        5,
        1000,
        7,
        0x187,
    )
    assert (r["ses1"], r["der"], r["t_since_s"], r["line"]) == (True, True, 2, 1)
    assert report.records == 1


def test_sensor_names_map_can_nodes_to_layout_heads(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text("(1622974502.125000) can0 187#03A5E80307 R\n")
    frames, _ = parse_can([path], sensor_names={7: "WS7"})
    assert frames["sensor"].tolist() == ["WS7"]


def test_foreign_remote_and_error_frames_are_rows_of_their_kind_not_rejected(tmp_path: Path) -> None:
    path = write_can(tmp_path / "bus.log", can_messages([(0, "AC07", *CLEAR)]))
    frames, report = parse_can([path])
    f = report.files[0]
    assert (len(frames), report.rejected) == (5, 0)
    assert isinstance(f, CanFileReport)
    assert (f.messages, f.count_frames, f.foreign, f.remote_frames, f.error_frames) == (5, 1, 2, 1, 1)
    assert (f.lines_read, f.records, f.blank) == (5, 5, 0)
    assert frames["kind"].value_counts().to_dict() == {"foreign": 2, "count": 1, "remote": 1, "error": 1}
    assert frames["sensor"].isna().tolist() == [k != "count" for k in frames["kind"]]
    foreign = frames[frames["kind"] == "foreign"]
    assert sorted(zip(foreign["can_id"], foreign["extended"], foreign["data"], strict=True)) == [
        (0x187, True, "0000000000"),
        (0x701, False, "05"),
    ]
    remote = frames[frames["kind"] == "remote"].iloc[0]
    assert (remote["can_id"], remote["data"], remote["status"]) == (0x187, "", 0)  # no payload, no status
    assert len(count_frames_only(frames)) == 1


def test_a_count_frame_with_the_wrong_dlc_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text("(1.0) can0 187#03A5E80300 R\n(2.0) can0 187#03A5E803 R\n(3.0) can0 188#03A5E8030000000000 R\n")
    frames, report = parse_can([path])
    assert len(frames) == 1
    assert dict(report.rejected_by_reason) == {"dlc": 2}
    assert [r.line for r in report.rejections] == [2, 3]
    assert "expected DLC 5" in report.rejections[0].reason
    assert report.rejections[0].text == "(2.0) can0 187#03A5E803 R"


def test_a_malformed_candump_line_is_rejected_and_reading_goes_on(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_bytes(
        b"(1.0) can0 187#03A5E80300 R\r\nnot a frame\r\n\x00\xff\x1b[31m\r\n\r\n(2.0) can0 187#03A5E80301 R\r\n"
    )
    frames, report = parse_can([path])
    assert frames["seq"].tolist() == [0, 1]
    assert dict(report.rejected_by_reason) == {"format": 2}
    assert [r.line for r in report.rejections] == [2, 3]
    assert "\x1b" not in report.rejections[1].text
    report.check()
    assert (report.lines_read, report.records, report.blank, report.rejected) == (5, 2, 1, 2)


def test_comment_lines_in_a_candump_log_are_blank(tmp_path: Path) -> None:
    # An annotated capture: '#' lines are comments, as in frame files (and as the file-kind check reads them).
    path = tmp_path / "bus.log"
    path.write_text(
        "# depot test, node 7\n(1.0) can0 187#03A5E80300 R\n  # train passes\n(2.0) can0 187#03A5E80301 R\n"
    )
    frames, report = parse_can([path])
    assert frames["seq"].tolist() == [0, 1]
    report.check()
    assert (report.lines_read, report.records, report.blank, report.rejected) == (4, 2, 2, 0)


def test_gzip_candump_is_read(tmp_path: Path) -> None:
    path = tmp_path / "bus.log.gz"
    path.write_bytes(gzip.compress(b"(1.0) can0 187#03A5E80300 R\n"))
    frames, report = parse_can([path])
    assert len(frames) == 1 and report.files[0].compressed


def test_asc_times_are_the_measurement_wall_clock(tmp_path: Path, utc: None) -> None:
    path = write_can(tmp_path / "bus.asc", can_messages([(2.125, "AC07", *CLEAR)], foreign=False))
    frames, _ = parse_can([path])
    assert frames["time"].tolist() == [pd.Timestamp("2021-06-06T10:15:02.125")]


def test_a_malformed_asc_message_line_is_rejected_and_reading_goes_on(tmp_path: Path) -> None:
    path = tmp_path / "bus.asc"
    path.write_text(
        "date Sun Jun 06 10:15:00.000 2021\nbase hex  timestamps absolute\ninternal events logged\n"
        "Begin Triggerblock Sun Jun 06 10:15:00.000 2021\n"
        "   1.000000 1  187             Rx   d 5 03 A5 E8 03 00\n"
        "   2.000000 1  187             Rx   d 5 03 ZZ E8 03 01\n"
        "   3.000000 1  187             Rx   d 5 03 A5 E8 03 02\n"
        "End TriggerBlock\n"
    )
    frames, report = parse_can([path])
    assert frames["seq"].tolist() == [0, 2]
    assert frames["time"].tolist() == [pd.Timestamp("2021-06-06T10:15:01"), pd.Timestamp("2021-06-06T10:15:03")]
    assert [(r.line, report.rejected_by_reason["format"]) for r in report.rejections] == [(6, 1)]
    assert (report.lines_read, report.records, report.blank) == (8, 2, 5)


def test_an_asc_message_right_after_the_header_is_not_lost(tmp_path: Path) -> None:
    # python-can's header scan consumes the first line after the header; it must not vanish.
    path = tmp_path / "bus.asc"
    path.write_text(
        "date Sun Jun 06 10:15:00.000 2021\nbase hex  timestamps absolute\n   1.0 1  187 Rx d 5 03 A5 E8 03 00\n"
    )
    _, report = parse_can([path])
    assert report.records + report.rejected == 1
    report.check()


def test_an_asc_with_relative_timestamps_is_an_input_error(tmp_path: Path) -> None:
    path = tmp_path / "bus.asc"
    path.write_text(
        "date Sun Jun 06 10:15:00.000 2021\nbase hex  timestamps relative\n   1.0 1  187 Rx d 5 03 A5 E8 03 00\n"
    )
    with pytest.raises(InputError, match="relative timestamps"):
        parse_can([path])


def test_an_overlong_can_log_line_is_rejected_as_too_long(tmp_path: Path) -> None:
    path = write_raw(tmp_path / "bus.log", b"(1.0) can0 187#" + b"00" * 4000 + b" R\n(2.0) can0 187#03A5E80300 R\n")
    frames, report = parse_can([path])
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"too long": 1}
    report.check()


def test_blf_written_by_python_can_is_read(tmp_path: Path) -> None:
    path = write_can(tmp_path / "bus.blf", can_messages([(2.125, "AC07", *CLEAR), (3, "AC07", 0, 1)]))
    frames, report = parse_can([path])
    counts = count_frames_only(frames)
    assert counts["time"].tolist() == [pd.Timestamp("2021-06-06T10:15:02.125"), pd.Timestamp("2021-06-06T10:15:03")]
    assert counts["byte2"].tolist() == [0xA5, 1]
    assert report.files[0].foreign == 2  # type: ignore[attr-defined]
    report.check()


def test_a_corrupt_blf_is_an_input_error(tmp_path: Path) -> None:
    good = write_can(tmp_path / "good.blf", can_messages(TRAIN)).read_bytes()
    bad = write_raw(tmp_path / "bad.blf", good[:200] + b"\x00garbage" * 50)
    with pytest.raises(InputError, match="not a readable BLF file") as exc:
        parse_can([bad])
    assert "\n" not in str(exc.value)


def test_an_unknown_can_log_suffix_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="unknown CAN log format"):
        parse_can([write_raw(tmp_path / "bus.pcap", b"x\n")])


# A CAN log saved under another name (a candump kept as .txt, an ASC export saved as .log, no suffix, gzip
# without .gz) is read by its content, as docs/usage.md promises ("a file is told by its content, never by its
# name"); it was refused as "unknown CAN log format '.txt'", or an ASC named .log had every line rejected.
MISNAMED_CAN = [
    ("can_counts.log", "candump.txt", False),
    ("can_counts.asc", "asc_export.log", False),
    ("can_counts.asc", "asc_export", False),
    ("can_counts.trc", "trace.txt", False),
    ("can_counts.log", "candump_gz", True),
]


@pytest.mark.parametrize(("sample", "name", "gz"), MISNAMED_CAN)
def test_a_can_log_is_read_by_its_content_whatever_its_name(tmp_path: Path, sample: str, name: str, gz: bool) -> None:
    data = (SAMPLES / sample).read_bytes()
    misnamed = write_raw(tmp_path / name, gzip.compress(data) if gz else data)
    expected, want = parse_can([SAMPLES / sample])
    frames, report = parse_can([misnamed])
    assert report.rejected == want.rejected == 0
    assert report.files[0].format == want.files[0].format  # type: ignore[attr-defined]
    pd.testing.assert_frame_equal(frames.drop(columns="file"), expected.drop(columns="file"))


@pytest.mark.parametrize(("sample", "name", "gz"), MISNAMED_CAN)
def test_frames_command_reads_a_misnamed_can_log(tmp_path: Path, sample: str, name: str, gz: bool) -> None:
    import json

    from typer.testing import CliRunner

    from console.cli.app import app

    data = (SAMPLES / sample).read_bytes()
    misnamed = write_raw(tmp_path / name, gzip.compress(data) if gz else data)
    res = CliRunner().invoke(app, ["frames", str(misnamed), "--json"])
    assert res.exit_code == 0, res.output
    right = json.loads(CliRunner().invoke(app, ["frames", str(SAMPLES / sample), "--json"]).stdout)
    assert json.loads(res.stdout)["events"] == right["events"]


def test_a_can_check_byte_frame_with_der_set_is_rejected(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text("(1.0) can0 187#03A5E80300 R\n(2.0) can0 187#0BA5E80301 R\n")
    frames, report = parse_can([path])
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"protocol": 1}
    assert report.rejections[0].text == "(2.0) can0 187#0BA5E80301 R"


# --- events ---------------------------------------------------------------------------


def without_source(events: list[DetectionEvent]) -> list[DetectionEvent]:
    return [dataclasses.replace(e, source="") for e in events]


@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf"])
def test_text_and_can_frames_give_the_same_events(tmp_path: Path, utc: None, suffix: str) -> None:
    from_text = events_of(tmp_path, TRAIN)
    frames, report = parse_can([write_can(tmp_path / f"bus{suffix}", can_messages(TRAIN))])
    assert report.rejected == 0
    from_can = frames_to_events(frames)
    assert {e.source for e in from_text} == {"frame"} and {e.source for e in from_can} == {"can"}
    assert without_source(from_can) == without_source(from_text)
    assert kinds(from_text).count("axle") == 4 + 4 + 2


def test_shipped_samples_give_the_same_events_in_all_formats() -> None:
    text, r1 = parse_frames([SAMPLES / "sensor_frames.txt"])
    dump, r2 = parse_can([SAMPLES / "can_counts.log"])
    asc, r3 = parse_can([SAMPLES / "can_counts.asc"])
    assert r1.rejected == r2.rejected == r3.rejected == 0
    expected = without_source(frames_to_events(text))
    assert without_source(frames_to_events(dump)) == expected
    assert without_source(frames_to_events(asc)) == expected


def test_the_shipped_sample_holds_its_documented_truths() -> None:
    # sample_logs/make_can_samples.py: AC07 counts a train of 8 axles up and
    # a trolley of 4 down; AC08 counts the 8 axles with element S2 failing,
    # then loses contact for 19 s.
    frames, report = parse_frames([SAMPLES / "sensor_frames.txt"])
    assert (report.lines_read, report.records, report.blank, report.rejected) == (59, 56, 3, 0)
    events = frames_to_events(frames)
    axles = [(e.head, e.direction) for e in events if e.kind is EventKind.AXLE]
    assert axles.count(("AC07", UP)) == 8 and axles.count(("AC07", DOWN)) == 4
    assert axles.count(("AC08", UP)) == 8 and len(axles) == 20
    others = [(str(e.kind), e.head, e.channel, pd.Timestamp(e.time_ns).strftime("%H:%M:%S.%f")[:-3]) for e in events]
    assert [o for o in others if o[0] != "axle"] == [
        ("head_free", "AC07", None, "10:15:16.000"),
        ("channel_fault", "AC08", 2, "10:15:20.500"),
        ("count_error", "AC08", None, "10:15:20.500"),
        ("channel_ok", "AC08", 2, "10:15:24.000"),
        ("head_free", "AC08", None, "10:15:24.000"),
        ("head_free", "AC07", None, "10:15:33.000"),
        ("power_loss", "AC08", None, "10:15:36.000"),
        ("power_restored", "AC08", None, "10:15:45.250"),
    ]


def test_a_table_without_the_check_column_gets_the_same_reading(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", 0x00, 164), (1, "AC07", 0x00, 0xA5), (2, "AC07", *CLEAR), (3, "AC07", 0x00, 1)]
    frames = parse_rows(tmp_path, rows)
    assert frames_to_events(frames.drop(columns="check")) == frames_to_events(frames)


def test_count_increments_become_axles_in_the_travel_direction(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", *CLEAR), (1, "AC07", 0x00, 2), (2, "AC07", 0x00, 3), (3, "AC07", *CLEAR)]
    rows += [(4, "AC07", 0x08, 1)]
    events = [e for e in events_of(tmp_path, rows) if e.kind is EventKind.AXLE]
    assert [(e.time_ns, e.direction, e.detail) for e in events] == [
        (ns(1), UP, "count 1"),
        (ns(1), UP, "count 2"),
        (ns(2), UP, "count 3"),
        (ns(4), DOWN, "count 1"),
    ]
    assert {e.head for e in events} == {"AC07"} and {e.source for e in events} == {"frame"}


def test_up_can_be_s3_to_s1_per_sensor(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", *CLEAR), (1, "AC07", 0x00, 1), (0, "AC08", *CLEAR), (1, "AC08", 0x00, 1)]
    rows += [(0, "AC09", *CLEAR), (1, "AC09", 0x00, 1)]
    events = events_of(tmp_path, rows, up_is_s1_to_s3={"AC07": True, "AC08": False})
    assert {e.head: e.direction for e in events if e.kind is EventKind.AXLE} == {
        "AC07": UP,
        "AC08": DOWN,
        "AC09": UNKNOWN,  # not in the mapping: direction unknown
    }


def test_the_first_frame_only_sets_the_baseline(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", 0x00, 5), (1, "AC07", 0x00, 6)])
    assert [e.detail for e in events if e.kind is EventKind.AXLE] == ["count 6"]


def test_a_drop_to_the_check_byte_clears_the_head(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", *CLEAR), (1, "AC07", 0x00, 2), (2, "AC07", *CLEAR), (3, "AC07", *CLEAR)])
    free = [e for e in events if e.kind is EventKind.HEAD_FREE]
    assert [(e.time_ns, e.detail) for e in free] == [(ns(2), "section clear: check byte after count 2")]


def test_a_count_going_back_without_a_clear_is_a_count_error(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", 0x00, 5), (1, "AC07", 0x00, 3), (2, "AC07", 0x00, 4)])
    assert kinds(events) == ["count_error", "axle"]
    assert events[0].detail == "count went back from 5 to 3 without a clear"


def test_the_count_byte_wrapping_past_255_keeps_counting(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", 0x00, 254), (1, "AC07", 0x00, 1)])
    assert [e.detail for e in events] == ["count 255", "count 0", "count 1"]


def test_counting_through_165_gives_every_axle(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", 0x00, 160), (1, "AC07", 0x00, 0xA5), (2, "AC07", 0x00, 170)])
    assert kinds(events) == ["axle"] * 10


def test_element_faults_and_recovery_are_channel_events(tmp_path: Path) -> None:
    rows: list[Row] = [
        (0, "AC07", 0x03, 0xA5),
        (1, "AC07", 0x43, 0xA5),
        (2, "AC07", 0x53, 0xA5),
        (3, "AC07", 0x13, 0xA5),
    ]
    rows.append((4, "AC07", 0x03, 0xA5))
    events = events_of(tmp_path, rows)
    assert [(str(e.kind), e.channel, e.time_ns) for e in events] == [
        ("channel_fault", 1, ns(1)),
        ("channel_fault", 3, ns(2)),
        ("channel_ok", 1, ns(3)),
        ("channel_ok", 3, ns(4)),
    ]


def test_sys_fault_is_a_fault_of_the_whole_sensor(tmp_path: Path) -> None:
    events = events_of(tmp_path, [(0, "AC07", 0x83, 0xA5), (1, "AC07", 0x83, 0xA5), (2, "AC07", 0x03, 0xA5)])
    assert [(str(e.kind), e.channel) for e in events] == [("channel_fault", None), ("channel_ok", None)]


def test_err_set_is_one_count_error_until_it_clears(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", 0x00, 1), (1, "AC07", 0x04, 2), (2, "AC07", 0x04, 3), (3, "AC07", 0x00, 3)]
    rows.append((4, "AC07", 0x04, 4))
    errors = [e for e in events_of(tmp_path, rows) if e.kind is EventKind.COUNT_ERROR]
    assert [e.time_ns for e in errors] == [ns(1), ns(4)]
    assert "ERR" in errors[0].detail


def test_a_silence_longer_than_the_timeout_is_a_power_loss(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", *CLEAR), (2, "AC07", *CLEAR), (17, "AC07", *CLEAR), (18, "AC07", *CLEAR)]
    events = events_of(tmp_path, rows, comm_timeout_s=10.0)
    assert [(str(e.kind), e.time_ns, e.detail) for e in events] == [
        ("power_loss", ns(12), "no frames for 10 s"),
        ("power_restored", ns(17), "frames resumed after 15.000 s"),
    ]
    assert events_of(tmp_path, rows, comm_timeout_s=20.0) == []


def test_a_sensor_silent_at_the_end_while_others_report_is_lost(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", *CLEAR), (0, "AC08", *CLEAR)] + [(float(s), "AC08", *CLEAR) for s in range(2, 30, 2)]
    events = events_of(tmp_path, rows)
    assert [(str(e.kind), e.head, e.time_ns) for e in events] == [("power_loss", "AC07", ns(10))]


def test_a_lost_can_sequence_number_is_a_count_error(tmp_path: Path) -> None:
    rows: list[Row] = [(0, "AC07", *CLEAR), (1, "AC07", *CLEAR), (2, "AC07", *CLEAR), (3, "AC07", *CLEAR)]
    msgs = can_messages(rows, foreign=False)
    del msgs[2]  # the third count frame never reached the recorder
    frames, _ = parse_can([write_can(tmp_path / "bus.log", msgs)])
    events = frames_to_events(frames)
    assert [(str(e.kind), e.detail) for e in events] == [("count_error", "1 frame(s) lost (sequence 1 → 3)")]


def test_a_total_that_disagrees_with_the_count_is_a_count_error(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text("(1.0) can0 187#00010A0000 R\n(2.0) can0 187#00020D0001 R\n")  # count +1, total +3
    events = frames_to_events(parse_can([path])[0])
    assert kinds(events) == ["count_error", "axle"]
    assert events[0].detail == "cumulative total advanced by 3 but the count by 1"


def test_no_frames_no_events() -> None:
    empty, _ = parse_frames([])
    assert frames_to_events(empty) == []


# --- PEAK .trc, every version python-can reads -------------------------------------------------

# 2021-06-06 10:15:00 as PEAK writes it: days since 1899-12-30 (the recording PC's wall clock)
TRC_START = ";$STARTTIME=44353.427083333336"
_TRC_COUNT_1 = "03 A5 E8 03 00"  # AC07 clear, total 1000, seq 0
_TRC_COUNT_2 = "00 01 E9 03 01"  # AC07 counts its first axle, total 1001, seq 1
# Hand-written in PEAK's documented layouts ("PCAN-Trace file format"): two count frames of node 7,
# a foreign frame, a remote frame, a bus event and (where the version has them) an error frame.
TRC_SAMPLES = {
    "1.0": (
        ";##########################################################################\n"
        ";   C:\\trace.trc\n;\n;    Start time: 06.06.2021 10:15:00.000\n"
        ";----+- ---+--- ----+--- + -+ -- -- ...\n"
        f"     1)      0  0187  5  {_TRC_COUNT_1}\n"
        "     2)    100  0701  1  05\n"
        f"     3)   2125  0187  5  {_TRC_COUNT_2}\n"
        "     4)   2200  0187  5  RTR\n"
        "     5)   2300  FFFFFFFF  4  00 00 00 08\n"
    ),
    "1.1": (
        f";$FILEVERSION=1.1\n{TRC_START}\n;\n;   Generated by PCAN-View v4.2.1.533\n"
        ";---+--   ----+----  --+--  ----+---  +  -+ -- -- -- -- -- -- --\n"
        f"     1)         0.0  Rx         0187  5  {_TRC_COUNT_1} \n"
        "     2)       100.0  Rx         0701  1  05 \n"
        f"     3)      2125.3  Rx         0187  5  {_TRC_COUNT_2} \n"
        "     4)      2200.0  Rx         0187  5  RTR \n"
        "     5)      2300.0  Warng  FFFFFFFF  4  00 00 00 08  BUSHEAVY \n"
        "     6)      2400.0  Error      0000  5  01 00 00 08 00 \n"
    ),
    "1.3": (
        f";$FILEVERSION=1.3\n{TRC_START}\n;\n"
        f"     1)         0.000 1  Rx         0187 -  5    {_TRC_COUNT_1}\n"
        "     2)       100.000 1  Rx         0701 -  1    05\n"
        f"     3)      2125.300 1  Rx         0187 -  5    {_TRC_COUNT_2}\n"
        "     4)      2200.000 1  Rx         0187 -  5    RTR\n"
        "     5)      2300.000 1  Warng  FFFFFFFF -  4    00 00 00 08 BUSHEAVY\n"
        "     6)      2400.000 1  Error      0000 -  5    01 00 00 08 00\n"
    ),
    "2.0": (
        f";$FILEVERSION=2.0\n{TRC_START}\n;$COLUMNS=N,O,T,I,d,l,D\n;\n"
        f"      1         0.000 DT     0187 Rx 5  {_TRC_COUNT_1}\n"
        "      2       100.000 DT     0701 Rx 1  05\n"
        f"      3      2125.300 DT     0187 Rx 5  {_TRC_COUNT_2}\n"
        "      4      2200.000 RR     0187 Rx 5\n"
        "      5      2300.000 ST          Rx 4  00 00 00 08\n"
        "      6      2400.000 ER          Rx 5  01 00 00 08 00\n"
    ),
    "2.1": (
        f";$FILEVERSION=2.1\r\n{TRC_START}\r\n;$COLUMNS=N,O,T,B,I,d,R,L,D\r\n;\r\n"
        f"      1         0.000 DT 1     0187 Rx -  5    {_TRC_COUNT_1}\r\n"
        "      2       100.000 DT 1     0701 Rx -  1    05\r\n"
        f"      3      2125.300 DT 1     0187 Rx -  5    {_TRC_COUNT_2}\r\n"
        "      4      2200.000 RR 1     0187 Rx -  5\r\n"
        "      5      2300.000 ST 1          Rx -  4    00 00 00 08\r\n"
        "      6      2400.000 ER 1          Rx -  5    01 00 00 08 00\r\n"
    ),
}


@pytest.mark.parametrize("version", sorted(TRC_SAMPLES))
def test_hand_written_trc_of_every_version_python_can_reads(tmp_path: Path, version: str) -> None:
    text = TRC_SAMPLES[version]
    frames, report = parse_can([write_raw(tmp_path / "bus.trc", text.encode())])
    report.check()
    assert report.rejected == 0, report.rejections
    f = report.files[0]
    assert isinstance(f, CanFileReport) and f.format == "trc"
    has_error = version != "1.0"  # 1.0 has no error frames; its FFFFFFFF line is bus information
    assert (f.count_frames, f.foreign, f.remote_frames, f.error_frames) == (2, 1, 1, int(has_error))
    assert f.lines_read == len(text.splitlines()) == f.records + f.blank
    counts = count_frames_only(frames)
    assert counts["sensor"].tolist() == ["AC07", "AC07"] and counts["byte2"].tolist() == [0xA5, 1]
    assert counts["total"].tolist() == [1000, 1001] and counts["seq"].tolist() == [0, 1]
    # 1.0 has no start time: offsets from 1970-01-01 (docs/frames.md)
    start = pd.Timestamp("1970-01-01") if version == "1.0" else pd.Timestamp("2021-06-06T10:15:00")
    step = pd.Timedelta("2125ms") if version == "1.0" else pd.Timedelta("2125.3ms")
    assert (counts["time"] - start).tolist() == [pd.Timedelta(0), step]
    kinds_in_order = frames["kind"].tolist()
    assert kinds_in_order == ["count", "foreign", "count", "remote"] + ["error"] * has_error
    if has_error:
        assert frames["time"].iloc[-1] == start + pd.Timedelta("2400ms")


@pytest.mark.parametrize("version", ["2.1", "1.0"])
def test_trc_written_by_python_can_gives_the_events_of_the_text_frames(tmp_path: Path, utc: None, version: str) -> None:
    from can.io.trc import TRCFileVersion

    path = tmp_path / "bus.trc"
    writer = can.TRCWriter(path)
    if version == "1.0":
        writer.file_version = TRCFileVersion.V1_0
    with writer:
        for m in can_messages(TRAIN):
            writer.on_message_received(m)  # python-can writes neither remote nor error frames
    frames, report = parse_can([path])
    report.check()
    assert report.rejected == 0 and report.files[0].foreign == 2  # type: ignore[attr-defined]
    from_text = without_source(events_of(tmp_path, TRAIN))
    from_trc = without_source(frames_to_events(frames))
    if version == "1.0":  # no start time and whole milliseconds: compare the sequence, not the clock
        assert [(e.kind, e.head, e.direction) for e in from_trc] == [(e.kind, e.head, e.direction) for e in from_text]
    else:
        assert from_trc == from_text


def test_trc_versions_python_can_would_misread_are_refused(tmp_path: Path) -> None:
    v12 = ";$FILEVERSION=1.2\n;$STARTTIME=44353.4\n     1)  0.000 1  Rx  0187  5  03 A5 E8 03 00\n"
    with pytest.raises(InputError, match=r"TRC file version .1\.2. is not read"):
        parse_can([write_raw(tmp_path / "a.trc", v12.encode())])
    no_columns = ";$FILEVERSION=2.1\n;$STARTTIME=44353.4\n      1  0.000 DT 1  0187 Rx -  5  03 A5 E8 03 00\n"
    with pytest.raises(InputError, match="without a ;\\$COLUMNS"):
        parse_can([write_raw(tmp_path / "b.trc", no_columns.encode())])
    bad_start = ";$FILEVERSION=1.1\n;$STARTTIME=1e308\n"
    with pytest.raises(InputError, match="STARTTIME: expected a day number") as exc:
        parse_can([write_raw(tmp_path / "c.trc", bad_start.encode())])
    assert "\n" not in str(exc.value)


def test_trc_lines_python_can_drops_or_chokes_on_are_rejected_and_reading_goes_on(tmp_path: Path) -> None:
    text = TRC_SAMPLES["1.1"].replace(
        "     2)       100.0  Rx         0701  1  05 \n",
        "     2)       100.0  Rx         0701  1  ZZ \n"  # bad hex: python-can raises, its reader stops
        "     2b)      150.0  Rx         0701  4  05 \n"  # fewer bytes than the DLC: python-can drops it silently
        "     2c)      160.0  Bogus      0701  1  05 \n",  # a type python-can skips as unsupported
    )
    frames, report = parse_can([write_raw(tmp_path / "bus.trc", text.encode())])
    report.check()
    assert [r.line for r in report.rejections] == [7, 8, 9]
    assert dict(report.rejected_by_reason) == {"format": 3}
    assert "ValueError" in report.rejections[0].reason
    assert len(count_frames_only(frames)) == 2  # the frames after the bad line are still read


def test_the_shipped_trc_sample_matches_its_truth() -> None:
    # sample_logs/README.md: 88 lines, 56 count frames, 11 foreign, 1 remote, 1 error, 19 without a frame
    frames, report = parse_can([SAMPLES / "can_counts.trc"])
    f = report.files[0]
    assert isinstance(f, CanFileReport)
    assert (f.lines_read, f.count_frames, f.foreign, f.remote_frames, f.error_frames) == (88, 56, 11, 1, 1)
    assert (f.blank, f.rejected) == (19, 0)
    text, _ = parse_frames([SAMPLES / "sensor_frames.txt"])
    assert without_source(frames_to_events(frames)) == without_source(frames_to_events(text))


# --- hostile CAN content: rejected per row, never an internal error --------------------------------


def test_a_can_timestamp_beyond_64_bits_is_rejected_per_row_naming_the_time(tmp_path: Path) -> None:
    path = tmp_path / "bus.log"
    path.write_text(
        "(1622974500.000000) can0 187#03A5E80300 R\n"
        "(123456789012345678901234567890.000000) can0 187#03A5E80301 R\n"
        "(1e400) can0 187#03A5E80302 R\n"
        "(-99999999999999999999) can0 701#05 R\n"
        "(1622974502.000000) can0 187#03A5E80303 R\n"
    )
    frames, report = parse_can([path])
    report.check()
    assert frames["seq"].tolist() == [0, 3]
    assert dict(report.rejected_by_reason) == {"time": 3}
    assert all(r.reason.startswith("time: ") for r in report.rejections)


def test_a_blf_frame_out_of_range_is_rejected_not_fatal(tmp_path: Path) -> None:
    msgs = can_messages([(0, "AC07", *CLEAR)], foreign=False)
    msgs.append(can.Message(timestamp=1e10, arbitration_id=0x187, data=bytes(5), is_extended_id=False))
    frames, report = parse_can([write_can(tmp_path / "bus.blf", msgs)])
    report.check()
    assert len(frames) == 1 and dict(report.rejected_by_reason) == {"time": 1}


def test_a_candump_socketcan_error_class_frame_is_an_error_frame(tmp_path: Path) -> None:
    # CAN_ERR_FLAG 0x20000000 with a controller-problem class (0x04): python-can reads it as data
    path = tmp_path / "bus.log"
    path.write_text("(1.0) can0 187#03A5E80300 R\n(1.5) can0 20000004#0004000000000000 R\n")
    frames, report = parse_can([path])
    assert frames["kind"].tolist() == ["count", "error"]
    assert report.files[0].error_frames == 1  # type: ignore[attr-defined]


def test_frames_command_reads_trc_and_lists_every_frame_with_its_kind() -> None:
    import json

    from typer.testing import CliRunner

    from console.cli.app import app

    runner = CliRunner()
    res = runner.invoke(app, ["frames", str(SAMPLES / "can_counts.trc"), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    kinds_seen = [row["kind"] for row in doc["frames"]]
    assert {k: kinds_seen.count(k) for k in set(kinds_seen)} == {"count": 56, "foreign": 11, "remote": 1, "error": 1}
    other = [row for row in doc["frames"] if row["kind"] != "count"]
    assert all(row["sensor"] is None and row["status"] is None and row["can_id"] is not None for row in other)
    (f,) = doc["parse_reports"][0]["files"]
    assert f["lines_read"] == f["count_frames"] + f["foreign"] + f["remote_frames"] + f["error_frames"] + f["blank"]
    text = runner.invoke(app, ["frames", str(SAMPLES / "can_counts.trc")], env={"COLUMNS": "100"})
    assert text.exit_code == 0
    assert "CAN traffic" in text.output and "remote" in text.output and "18FEF100x" in text.output


def test_axles_of_a_sensor_the_layout_does_not_orient_are_neither_up_nor_down() -> None:
    """frames --layout: AC07/AC08 are not heads of the example line: their axles go in '?', and it is said."""
    from typer.testing import CliRunner

    from console.cli.app import app

    path = str(SAMPLES / "sensor_frames.txt")
    plain = CliRunner().invoke(app, ["frames", path])
    oriented = CliRunner().invoke(app, ["frames", path, "--layout", "example"])
    assert plain.exit_code == oriented.exit_code == 0, oriented.output

    def row(out: str, sensor: str) -> list[str]:
        return next(line.split() for line in out.splitlines() if line.split()[:1] == [sensor])

    # Sensor Frames From To Up Down [?] Fault Err Lost
    assert row(plain.stdout, "AC07")[4:6] == ["8", "4"]
    assert row(oriented.stdout, "AC07")[4:7] == ["0", "0", "12"]
    assert row(oriented.stdout, "AC08")[4:7] == ["0", "0", "8"]
    assert "AC07, AC08: not heads of" in oriented.stderr


def test_one_capture_in_two_formats_counts_each_axle_once(tmp_path: Path) -> None:
    """sensor_frames.txt and can_counts.log hold one frame sequence (sample_logs/README.md); the CAN logger's
    clock may run a little apart from the sensor's: here 37 ms late."""
    import json
    import re

    from typer.testing import CliRunner

    from console.cli.app import app

    skewed = tmp_path / "can_skewed.log"
    skewed.write_text(
        re.sub(
            r"^\((\d+\.\d+)\)",
            lambda m: f"({float(m.group(1)) + 0.037:.6f})",
            (SAMPLES / "can_counts.log").read_text(encoding="utf-8"),
            flags=re.M,
        ),
        encoding="utf-8",
    )

    def frames(*paths: Path) -> dict:
        res = CliRunner().invoke(app, ["frames", *map(str, paths), "--json"])
        assert res.exit_code == 0, res.output
        return json.loads(res.stdout)

    def axles(doc: dict) -> list[tuple[str, int]]:
        return sorted((e["sensor"], e["direction"]) for e in doc["events"] if e["kind"] == "axle")

    alone = frames(SAMPLES / "sensor_frames.txt")
    for second in (SAMPLES / "can_counts.log", skewed):
        both = frames(SAMPLES / "sensor_frames.txt", second)
        assert axles(both) == axles(alone) and len(axles(alone)) == 20
        assert len(both["events"]) == len(alone["events"])
        assert both["events_repeated"] == {str(second): len(alone["events"])}
