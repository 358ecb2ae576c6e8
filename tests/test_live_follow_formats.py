"""file:PATH for every text format trackside reads: a followed file is read as the batch commands read it.

NMEA (real receiver captures from gpsd's regression suite, and the same with
binary packets and junk between sentences), gpsd JSON, device CSV and JSON
lines give the fixes ``trackside gnss`` gives; candump, ASC and TRC logs and
sensor frame logs give the frames ``trackside frames`` reads and, through
the frame follower, its section changes.  Written in random pieces (lines
cut anywhere, packets cut across writes), read by the real follower thread.
"""

from __future__ import annotations

import itertools
import json
import random
import signal
import subprocess
import tempfile
import threading
import time
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.analysis.frame_events import frames_to_events
from console.analysis.sections.engine import run_sections
from console.analysis.sections.state import SectionState
from console.inputs.base import FrameRows, GnssFix, Item, LineBlock, SourceNote
from console.inputs.follow import FileSource
from console.layout import Layout, layout_from_dict, load_layout
from console.live.frames import FrameFollow
from parsers.frames.can import parse_can
from parsers.frames.sensor import parse_frames
from parsers.gnss.growing import GrowingStream
from parsers.gnss.stream import parse_stream_files
from parsers.gnss_files import parse_device_stream
from parsers.report import FileReport, ParseReport
from tests.gpsd_truth import compare_with_gpsd
from tests.live_fixtures import NMEA_DIR, REPO, read_jsonl, trackside, wait_until
from tests.test_gnss_realworld import RTCM, SIRF, UBX, _nav_pvt

pytestmark = pytest.mark.timeout(120)

SAMPLES = REPO / "sample_logs"
DATA = REPO / "tests" / "data" / "gnss"
CAPTURES = sorted(NMEA_DIR.glob("*.log"))
SLOW = settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
CAN_LAYOUT = """
[line]
name = "two CAN sensors"
[[heads]]
id = "AC07"
device_id = 7
chainage_m = 1000
spacing_m = 0.13
up = "sys1_to_sys2"
[[heads]]
id = "AC08"
device_id = 8
chainage_m = 2000
spacing_m = 0.13
up = "sys1_to_sys2"
[[sections]]
id = "B1"
bounds = [{ head = "AC07", sign = 1 }, { head = "AC08", sign = -1 }]
"""


def with_binary(data: bytes, seed: int) -> bytes:
    """A capture as a u-blox port gives it: UBX (NAV-PVT among them), RTCM3 and SiRF packets before
    sentences on their lines (some with LF and '$' inside), and lines of junk bytes."""
    rng = random.Random(seed)
    out = []
    for line in data.splitlines(keepends=True):
        r = rng.random()
        if r < 0.15:
            out.append(rng.choice([UBX, RTCM, SIRF, _nav_pvt(), _nav_pvt(fix_type=0)]))
        elif r < 0.2:
            out.append(bytes(rng.randrange(128, 256) for _ in range(rng.randint(1, 20))) + b"\n")
        out.append(line)
    return b"".join(out)


def gpsd_json(capture: Path) -> bytes:
    """What ``gpspipe -w`` writes for a capture: gpsd's JSON reports (from its .chk)."""
    chk = capture.with_name(capture.name + ".chk").read_bytes()
    return b"".join(line + b"\n" for line in chk.splitlines() if line.startswith(b"{"))


# -- the batch parser's rows, read a block of lines at a time ----------------------------------


def plain(frame: pd.DataFrame) -> pd.DataFrame:
    """Categories as plain values: a table read in parts has them in another order (or, where the parts'
    categories differ, as strings: the sentence names of binary messages are categories only where used)."""
    out = frame.copy()
    for c in out.columns:
        if isinstance(out[c].dtype, pd.CategoricalDtype) or pd.api.types.is_string_dtype(out[c].dtype):
            out[c] = pd.Series(out[c].astype(str).tolist(), index=out.index, dtype=object)
    return out.reset_index(drop=True)


def stream_inputs() -> list[tuple[str, bytes]]:
    inputs = [(p.name, p.read_bytes()) for p in CAPTURES]
    inputs += [(f"binary-{p.name}", with_binary(p.read_bytes(), k)) for k, p in enumerate(CAPTURES[:4])]
    inputs += [(f"gpsd-{p.name}", gpsd_json(p)) for p in CAPTURES[:3]]
    return inputs


STREAMS = stream_inputs()


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_stream_rows_read_in_blocks_of_lines_are_the_batch_rows(data: st.DataObject) -> None:
    name, raw = STREAMS[data.draw(st.integers(0, len(STREAMS) - 1), label="input")]
    lines = [line + b"\n" for line in raw.split(b"\n")[:-1]]  # LF only ends a line (not CR, VT, FF…)
    cuts = sorted(data.draw(st.sets(st.integers(0, len(lines)), max_size=12), label="cuts") | {0, len(lines)})
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / name
        path.write_bytes(raw)
        expected, batch_report = parse_stream_files([path])
        report = ParseReport()
        fr = FileReport(file=str(path))
        report.files.append(fr)
        grow = GrowingStream(report)
        grow.open_file(fr, path.stem)
        parts, ids = [], []
        for a, b in itertools.pairwise(cuts):
            grow.add(a + 1, b"".join(lines[a:b]))
            rows, row_ids = grow.settle()
            parts.append(rows)
            ids.append(row_ids)
            # Memory holds the open epochs (one or two rows a device), not the file.
            assert len(grow.parser.rows) <= 2 * max(1, len(grow.parser.clocks))
        grow.end_file()
        rows, row_ids = grow.settle(final=True)
        parts.append(rows)
        ids.append(row_ids)
    order = np.argsort(np.concatenate(ids), kind="stable")
    assert (np.sort(np.concatenate(ids)) == np.arange(len(expected))).all()
    got = pd.concat(parts, ignore_index=True).iloc[order]
    pd.testing.assert_frame_equal(plain(got), plain(expected))
    b = batch_report.files[0]
    assert (fr.lines_read, fr.records, fr.blank, fr.rejected) == (b.lines_read, b.records, b.blank, b.rejected)
    assert report.rejections == batch_report.rejections
    assert report.skipped == batch_report.skipped


# -- the real follower, a file written in random pieces ----------------------------------------


class Collector:
    def __init__(self) -> None:
        self.items: list[Item] = []
        self.lock = threading.Lock()

    def __call__(self, item: Item) -> None:
        with self.lock:
            self.items.append(item)

    def of(self, kind: type) -> list[Any]:
        with self.lock:
            return [i for i in self.items if isinstance(i, kind)]

    def notes(self, kind: str) -> list[str]:
        return [n.detail for n in self.of(SourceNote) if n.kind == kind]


def follow_pieces(data: bytes, dest: Path, cuts: list[int], **kw: bool) -> tuple[FileSource, Collector]:
    """Follow ``dest`` while ``data`` is written into it in pieces ending at ``cuts`` (anywhere in a line),
    each read by the follower before the next is written; then stop following."""
    if not dest.exists():
        dest.write_bytes(b"")
    src = FileSource(f"file:{dest}", dest, force_polling=True, **{"from_start": True, **kw})
    got = Collector()
    src.start(got)
    try:
        assert wait_until(lambda: src.status().connected, 5)
        with dest.open("ab") as f:
            done = dest.stat().st_size
            for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True):
                if b <= a:
                    continue
                f.write(data[a:b])
                f.flush()
                done += b - a
                assert wait_until(lambda n=done: src.bytes_read == n, 5)  # type: ignore[misc]
    finally:
        src.stop()
    return src, got


def fix_table(columns: dict[str, Any]) -> pd.DataFrame:
    dtypes = {"device": object, "time_ns": np.int64, "line": np.int64, "role": object}
    frame = pd.DataFrame({k: np.asarray(v, dtype=dtypes.get(k, np.float64)) for k, v in columns.items()})
    return frame.sort_values(["line", "device"], kind="stable").reset_index(drop=True)


def fix_tuples(fixes: list[GnssFix]) -> pd.DataFrame:
    return fix_table(
        {
            "device": [f.device for f in fixes],
            "time_ns": [f.t_fix_ns for f in fixes],
            "lat": [f.lat_deg for f in fixes],
            "lon": [f.lon_deg for f in fixes],
            "speed_mps": [f.speed_mps for f in fixes],
            "course_deg": [f.course_deg for f in fixes],
            "line": [f.meta["line"] for f in fixes],
            "role": [f.role for f in fixes],
        }
    )


def usable(fixes: pd.DataFrame) -> pd.DataFrame:
    """The batch rows that are fixes for the crossing units: valid, with a time and a position."""
    ok = fixes["valid"] & fixes["time"].notna() & fixes["lat"].notna() & fixes["lon"].notna()
    f = fixes[ok]
    return fix_table(
        {
            "device": f["device"].astype(str).tolist(),
            "time_ns": f["time"].astype("int64").tolist(),
            "lat": f["lat"].tolist(),
            "lon": f["lon"].tolist(),
            "speed_mps": f["speed_mps"].tolist(),
            "course_deg": f["course_deg"].tolist(),
            "line": f["line"].tolist(),
            "role": f["role"].astype(str).tolist(),
        }
    )


def gnss_inputs() -> list[tuple[str, bytes]]:
    files = [SAMPLES / "gnss_devices.csv", SAMPLES / "gnss_devices.jsonl", DATA / "ublox_export.csv"]
    files += [DATA / "operator_positions.csv", SAMPLES / "crossing_example.csv"]
    picked = [STREAMS[k] for k in (0, 2, 5, len(CAPTURES), len(CAPTURES) + 1, len(STREAMS) - 1)]
    return picked + [(p.name, p.read_bytes()) for p in files]


GNSS_INPUTS = gnss_inputs()


@SLOW
@given(data=st.data())
def test_a_gnss_file_written_in_pieces_gives_the_batch_fixes(data: st.DataObject, simulated: Path) -> None:
    inputs = GNSS_INPUTS + [(p.name, p.read_bytes()) for p in sorted((simulated / "nmea").glob("*.nmea"))]
    name, raw = inputs[data.draw(st.integers(0, len(inputs) - 1), label="input")]
    cuts = sorted(data.draw(st.sets(st.integers(1, len(raw) - 1), max_size=10), label="cuts"))
    with tempfile.TemporaryDirectory() as tmp:
        whole, dest = Path(tmp) / "whole" / name, Path(tmp) / name
        whole.parent.mkdir()
        whole.write_bytes(raw)
        dest.write_bytes(b"")
        if name.endswith(".csv") or name.endswith(".jsonl"):
            expected, report = parse_device_stream([whole])
        else:
            expected, report = parse_stream_files([whole])
        src, got = follow_pieces(raw, dest, cuts)
    pd.testing.assert_frame_equal(fix_tuples(got.of(GnssFix)), usable(expected))
    # Rejected lines are counted in the source's status and shown (the first twenty) as notes.
    assert src.status().malformed == report.rejected
    assert len(got.notes("malformed")) == min(report.rejected, 20)
    (summary,) = src.file_reports()
    b = report.files[0]
    assert (summary["lines_read"], summary["records"], summary["blank"], summary["rejected"]) == (
        b.lines_read,
        b.records,
        b.blank,
        b.rejected,
    )
    assert not got.of(LineBlock) and len(got.notes("info")) == 1


@pytest.mark.skipif(not CAPTURES, reason=f"gpsd captures not found at {NMEA_DIR}")
@pytest.mark.parametrize("capture", [p.name for p in CAPTURES])
def test_a_receiver_capture_followed_in_pieces_matches_gpsds_own_decoding(capture: str, tmp_path: Path) -> None:
    log = NMEA_DIR / capture
    raw = log.read_bytes()
    cuts = sorted(random.Random(capture).sample(range(1, len(raw)), 7))
    _, got = follow_pieces(raw, tmp_path / capture, cuts)
    fixes = got.of(GnssFix)
    live = pd.DataFrame(
        {
            "valid": np.ones(len(fixes), bool),
            "time": pd.to_datetime([f.t_fix_ns for f in fixes], unit="ns", utc=True),
            "lat": [f.lat_deg for f in fixes],
            "lon": [f.lon_deg for f in fixes],
            "speed_mps": [f.speed_mps for f in fixes],
        }
    )
    batch, _ = parse_stream_files([log])
    counts, batch_counts = compare_with_gpsd(log, live), compare_with_gpsd(log, batch)
    assert counts == batch_counts
    assert counts["nmea_matched"] == counts["nmea"], dict(counts)  # every epoch gpsd reports, read live


# -- CAN logs and sensor frame logs ----------------------------------------------------------------


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    run = tmp_path_factory.mktemp("sim")
    subprocess.run(
        trackside("simulate", "-o", str(run), "--duration", "10m", "--trains-per-hour", "12"),
        capture_output=True,
        check=True,
        timeout=120,
    )
    return run


FRAME_INPUTS = ["can_counts.log", "can_counts.asc", "can_counts.trc", "sensor_frames.txt", "sim:sensor_frames.txt"]


def batch_frames(path: Path, kind: str) -> pd.DataFrame:
    if kind == "can":
        table, _ = parse_can([path])
        table = table[table["kind"] == "count"]
    else:
        table, _ = parse_frames([path])
    cols = ["time", "sensor", "status", "byte2", "line", *(["total", "seq"] if kind == "can" else [])]
    return plain(table[cols].assign(time=table["time"].astype("int64")))


def rows_frame(rows: list[FrameRows]) -> pd.DataFrame:
    can = rows[0].kind == "can"
    frame = pd.DataFrame(
        {
            "time": np.concatenate([r.time_ns for r in rows]),
            "sensor": np.concatenate([r.sensor for r in rows]).astype(str),
            "status": np.concatenate([r.status for r in rows]),
            "byte2": np.concatenate([r.byte2 for r in rows]),
            "line": np.concatenate([r.line for r in rows]),
            **({"total": np.concatenate([r.total for r in rows])} if can else {}),  # type: ignore[misc]
            **({"seq": np.concatenate([r.seq for r in rows])} if can else {}),  # type: ignore[misc]
        }
    )
    return frame


def section_changes(events: list[dict[str, Any]]) -> list[tuple[int, str, str, int]]:
    return [(e["time_ns"], e["section"], e["state"], e["count"]) for e in events if e["type"] == "section"]


@SLOW
@given(data=st.data())
def test_a_can_or_frame_log_written_in_pieces_gives_the_batch_frames_and_section_changes(
    data: st.DataObject, simulated: Path
) -> None:
    name = data.draw(st.sampled_from(FRAME_INPUTS), label="input")
    path = simulated / "sensor_frames.txt" if name.startswith("sim:") else SAMPLES / name
    raw = path.read_bytes()
    cuts = sorted(data.draw(st.sets(st.integers(1, len(raw) - 1), max_size=10), label="cuts"))
    kind = "frame" if name.endswith(".txt") else "can"
    lay = load_layout(str(simulated / "layout.toml")) if name.startswith("sim:") else can_layout()
    with tempfile.TemporaryDirectory() as tmp:
        dest = Path(tmp) / path.name
        dest.write_bytes(b"")
        src, got = follow_pieces(raw, dest, cuts)
    rows = got.of(FrameRows)
    assert {r.kind for r in rows} == {kind}
    expected = batch_frames(path, kind)
    pd.testing.assert_frame_equal(rows_frame(rows), expected, check_dtype=False)
    # Through the frame follower: the section changes and the events of the batch path.
    table = parse_can([path])[0] if kind == "can" else parse_frames([path])[0]
    if kind == "can":
        table = table[table["kind"] == "count"]
    up = {h.id: h.up_is_first_channel_first for h in lay.heads}
    events = frames_to_events(table, up_is_s1_to_s3=up)
    timeline = run_sections(lay, events, initial=SectionState.PREPARATORY).timeline
    batch_changes = list(
        zip(
            timeline["time_ns"].tolist(),
            timeline["section"].tolist(),
            timeline["state"].astype(str).tolist(),
            timeline["count"].tolist(),
            strict=True,
        )
    )
    out: list[dict[str, Any]] = []
    ff = FrameFollow(lay, out.append)
    for r in rows:
        ff.add_rows(r)
    ff.finish()
    assert section_changes(out) == batch_changes
    assert ff.stats.events == len(events)
    assert src.status().malformed == 0


def can_layout() -> Layout:
    return layout_from_dict(tomllib.loads(CAN_LAYOUT), "two CAN sensors")


# -- recognition: what a file is, from its first lines --------------------------------------------


@pytest.fixture
def follower(tmp_path: Path) -> Iterator[tuple[Path, Any]]:
    started: list[FileSource] = []

    def start(path: Path, **kw: bool) -> tuple[FileSource, Collector]:
        src = FileSource(f"file:{path}", path, **{"from_start": True, **kw})
        got = Collector()
        src.start(got)
        started.append(src)
        assert wait_until(lambda: src.status().connected, 5)
        return src, got

    yield tmp_path, start
    for s in started:
        s.stop()


def test_a_file_waits_while_its_first_lines_do_not_tell_what_it_is(follower: tuple[Path, Any]) -> None:
    tmp_path, start = follower
    log = tmp_path / "rx.nmea"
    log.write_bytes(b"")
    src, got = start(log)
    rmc = (NMEA_DIR / "haicom-305N.log").read_bytes().split(b"\n")
    sentences = [line + b"\n" for line in rmc if line.startswith(b"$GPRMC") and b",A," in line]  # fixes
    with log.open("ab") as f:
        f.write(sentences[0][:20])  # one partial line: nothing to tell from yet
        f.flush()
        time.sleep(0.5)
        assert not got.notes("info") and not got.notes("unrecognised")
        f.write(sentences[0][20:] + sentences[1] + sentences[2])
        f.flush()
        assert wait_until(lambda: len(got.of(GnssFix)) == 2, 5)  # the third epoch is still open
    assert "read as a GNSS receiver stream" in got.notes("info")[0]
    assert "GNSS receiver stream" in src.status().detail


def test_a_file_of_no_format_we_read_is_one_note_not_a_flood_of_rejections(follower: tuple[Path, Any]) -> None:
    tmp_path, start = follower
    log = tmp_path / "notes.txt"
    log.write_bytes(b"")
    src, got = start(log)
    with log.open("ab") as f:
        for i in range(200):
            f.write(f"free text, line {i}\n".encode())
        f.flush()
    assert wait_until(lambda: src.status().messages == 200, 5)
    time.sleep(0.2)
    (note,) = got.notes("unrecognised")
    assert "no format trackside reads" in note and "file: follows diagnostic logs" in note
    assert src.status().malformed == 0 and not got.notes("malformed")
    assert not got.of(LineBlock) and not got.of(GnssFix)


def test_a_gpx_track_is_named_and_not_read(follower: tuple[Path, Any]) -> None:
    tmp_path, start = follower
    log = tmp_path / "t.gpx"
    log.write_bytes((DATA / "track_gpx11_garmin.gpx").read_bytes())
    _, got = start(log)
    assert wait_until(lambda: len(got.notes("unrecognised")) == 1, 5)
    assert "a GPX track" in got.notes("unrecognised")[0]


def test_a_rotated_file_may_change_format_and_the_note_says_so(follower: tuple[Path, Any]) -> None:
    tmp_path, start = follower
    log = tmp_path / "unit-head.log"
    log.write_bytes(b"")
    src, got = start(log)
    capture = (NMEA_DIR / "haicom-305N.log").read_bytes()
    with log.open("ab") as f:
        f.write(capture)
    assert wait_until(lambda: src.bytes_read == len(capture), 5)
    log.rename(tmp_path / "unit-head.log.1")
    csv = (SAMPLES / "gnss_devices.csv").read_bytes()
    log.write_bytes(csv)
    assert wait_until(lambda: src.rotations == 1 and src.bytes_read == len(csv), 5)
    src.stop()
    info = got.notes("info")
    assert len(info) == 2 and "the file before it was a GNSS receiver stream" in info[1]
    nmea, _ = parse_stream_files([NMEA_DIR / "haicom-305N.log"])
    devices, _ = parse_device_stream([SAMPLES / "gnss_devices.csv"])
    files = {str(f.meta["file"]) for f in got.of(GnssFix)}
    assert files == {str(log), f"{log}#2"}
    assert len(got.of(GnssFix)) == len(usable(nmea)) + len(usable(devices))


def test_following_from_the_end_reads_a_csv_header_and_an_asc_header_from_the_head(tmp_path: Path) -> None:
    for name, kind in (("gnss_devices.csv", GnssFix), ("can_counts.asc", FrameRows)):
        data = (SAMPLES / name).read_bytes()
        lines = data.splitlines(keepends=True)
        half = len(lines) // 2
        log = tmp_path / name
        log.write_bytes(b"".join(lines[:half]))
        src, got = follow_pieces(b"".join(lines[half:]), log, [], from_start=False)
        items = got.of(kind)
        if kind is GnssFix:
            expected = usable(parse_device_stream([SAMPLES / name])[0])
            pd.testing.assert_frame_equal(fix_tuples(items), expected[expected["line"] > half].reset_index(drop=True))
        else:
            expected_rows = batch_frames(SAMPLES / name, "can")
            tail = expected_rows[expected_rows["line"] > half].reset_index(drop=True)
            # The times too: the ASC header's date, read from the head.
            pd.testing.assert_frame_equal(rows_frame(items), tail, check_dtype=False)
        assert src.status().malformed == 0


# -- follow --archive, and the CLI on a growing NMEA file near a crossing ----------------------------


def query(archive: Path, sql: str) -> list[dict[str, Any]]:
    out = subprocess.run(
        trackside("query", "--archive", str(archive), "--format", "json", sql),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return list(json.loads(out.stdout))


def test_fixes_and_frames_of_followed_files_are_archived(tmp_path: Path) -> None:
    nmea, can_log, frame_log = tmp_path / "unit-head.nmea", tmp_path / "bus.log", tmp_path / "sensors.txt"
    nmea.write_bytes((NMEA_DIR / "bt451.log").read_bytes())
    can_log.write_bytes((SAMPLES / "can_counts.log").read_bytes())
    frame_log.write_bytes((SAMPLES / "sensor_frames.txt").read_bytes())
    archive = tmp_path / "arc"
    out = subprocess.run(
        trackside(
            "follow",
            *map(str, (nmea, can_log, frame_log)),
            "--from-start",
            "--jsonl",
            "--idle-exit",
            "1",
            "--archive",
            str(archive),
        ),
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert out.returncode == 0, out.stderr
    fixes, _ = parse_stream_files([NMEA_DIR / "bt451.log"])
    frames, _ = parse_can([SAMPLES / "can_counts.log"])
    assert query(archive, "SELECT count(*) AS n FROM fixes")[0]["n"] == len(usable(fixes))
    text_frames, _ = parse_frames([SAMPLES / "sensor_frames.txt"])
    n_count = int((frames["kind"] == "count").sum())
    assert query(archive, "SELECT count(*) AS n FROM frames")[0]["n"] == n_count + len(text_frames)
    sql = "SELECT sensor, count(*) AS n, min(time) AS first FROM frames WHERE kind = 'count' GROUP BY sensor"
    counts = frames[frames["kind"] == "count"].groupby("sensor", observed=True)["time"].agg(["count", "min"])
    assert {r["sensor"]: r["n"] for r in query(archive, sql)} == counts["count"].to_dict()
    # Times as the batch reads them from the log (to the microsecond).
    firsts = {r["sensor"]: pd.Timestamp(r["first"]).tz_localize(None) for r in query(archive, sql)}
    assert firsts == {k: pd.Timestamp(v) for k, v in counts["min"].items()}


def test_follow_jsonl_on_a_growing_nmea_file_shows_the_crossing_warning(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "nmea").mkdir(parents=True)  # follow waits for files that are not there yet, in a directory that is
    head, eot = run / "nmea" / "T1-head.nmea", run / "nmea" / "T1-eot.nmea"
    # --from-start: a file the simulator creates before the follower watches would otherwise be
    # followed from its end (a race the machine's load decides: lines lost even before binary input).
    follow = subprocess.Popen(
        trackside("follow", str(head), str(eot), "--layout", "example", "--jsonl", "--from-start"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        sim = subprocess.run(
            trackside(
                "simulate",
                "-o",
                str(run),
                "--layout",
                "example",
                "--live",
                "--speed",
                "120",
                "--duration",
                "8m",
                "--trains-per-hour",
                "12",
                "--json",
            ),
            capture_output=True,
            text=True,
            timeout=90,
        )
        assert sim.returncode == 0, sim.stderr
        time.sleep(1.5)  # the follower reads the last lines, then Ctrl-C ends it with its summary
        follow.send_signal(signal.SIGINT)
        out, err = follow.communicate(timeout=60)
    finally:
        if follow.poll() is None:
            follow.kill()
    assert follow.returncode == 130, err  # Ctrl-C: the summary, then 130
    events = read_jsonl(out)
    crossings = [e for e in events if e["type"] == "crossing"]
    assert {"on", "off"} <= {e["kind"] for e in crossings}, events[-1]
    # On before off at each crossing the train passed, and every fix of the finished files was read.
    for code in {e["crossing"] for e in crossings}:
        kinds = [e["kind"] for e in crossings if e["crossing"] == code]
        assert kinds.index("on") < kinds.index("off")
    summary = events[-1]
    batch, report = parse_stream_files([head, eot])
    assert [(f["lines_read"], f["rejected"]) for f in summary["files"]] == [
        (f.lines_read, f.rejected) for f in report.files
    ]
    assert 0 < summary["gnss_fixes"] <= len(usable(batch))


def test_a_big_file_read_here_is_handed_on_in_pieces_while_it_is_read(tmp_path: Path) -> None:
    from console.sim.writers import nmea_sentences

    # Five hours of 1 Hz fixes (2.7 MB), read from the start: 1 MiB reads, each about 0.6 s of
    # parsing.  Lines are counted and fixes handed on a piece (64 KiB) at a time, so the engine
    # (and --idle-exit, which counts lines read) sees the file arrive while it is read.
    t0_ns = 1_772_438_400 * 10**9
    log = tmp_path / "unit-head.nmea"
    with log.open("w") as f:
        for k in range(5 * 3600):
            f.write("\r\n".join(nmea_sentences(t0_ns + k * 10**9, 20.75 - k * 1e-6, 105.89, 20.0, 164.9)) + "\r\n")
    src = FileSource(f"file:{log}", log, from_start=True)
    seen: list[int] = []  # lines counted when each fix arrived

    def sink(item: Item) -> None:
        if isinstance(item, GnssFix):
            seen.append(src.message_count)

    src.start(sink)
    try:
        assert wait_until(lambda: len(seen) == 5 * 3600 - 1, 60)  # the last epoch is open until the end
    finally:
        src.stop()
    assert len(seen) == 5 * 3600
    size = log.stat().st_size
    assert len(set(seen)) >= size // (64 << 10)  # one count per piece, not one per 1 MiB read
    assert src.message_count == 2 * 5 * 3600


def test_follow_counts_a_runaway_line_as_one_line_as_a_batch_read_does(tmp_path: Path) -> None:
    """A 9 MB line (over the 4 MB a line may be) among records: one rejected line in follow, as in analyze."""
    good = (SAMPLES / "ws4_subsecond.log").read_bytes().splitlines(keepends=True)
    log = tmp_path / "runaway.log"
    log.write_bytes(b"".join(good[:3]) + b"A" * (9 << 20) + b"\n" + b"BADLINE\n" + b"".join(good[3:6]))
    out = subprocess.run(
        trackside("follow", f"file:{log}", "--from-start", "--jsonl", "--idle-exit", "1"),
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert out.returncode == 0, out.stderr
    (f,) = json.loads(out.stdout.splitlines()[-1])["files"]
    assert (f["lines_read"], f["records"], f["rejected"]) == (8, 6, 2)
