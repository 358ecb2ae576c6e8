"""The live engine's safety behaviour on live fixes: a unit that goes silent, units whose
clocks are off, and a diagnostic source that stops mid-train (no servers needed)."""

from __future__ import annotations

import itertools
import math
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from console.analysis.geo import TrackProjector
from console.inputs.base import GnssFix, LineBlock
from console.layout import load_layout
from console.live.engine import LiveEngine
from tests.live_fixtures import REPO

NS = 10**9
T0 = 1_800_000_000 * NS
CROSSING_M = 11850.0  # example layout, crossing 11+850
TRAIN_M = 28.6
START_M = 9000.0


class Clock:
    def __init__(self) -> None:
        self.t = T0

    def __call__(self) -> int:
        return self.t


def _engine_on_a_clock() -> tuple[TrackProjector, list[dict[str, Any]], LiveEngine, Clock]:
    """A live engine on the example layout whose console clock the test sets, and what it emits."""
    lay = load_layout("example")
    events: list[dict[str, Any]] = []
    engine = LiveEngine(lay, events.append)
    clock = Clock()
    engine.now_ns = clock  # type: ignore[method-assign]
    return TrackProjector(lay.track), events, engine, clock


def run(
    skews_s: dict[str, float] | None = None,
    silent_eot_after_s: float | None = None,
    speed_mps: float = 15.0,
    seconds: int = 300,
    first_stamped_ns: int | None = None,
) -> tuple[list[dict[str, Any]], LiveEngine]:
    """A train from chainage 9,000 m (before the mapped track: projected along its end) at constant
    speed, head and EOT fixes every 2 s; ``first_stamped_ns``: each unit's first report carries this time."""
    proj, events, engine, clock = _engine_on_a_clock()
    skews = skews_s or {}
    for k in range(0, seconds * 2):
        clock.t = T0 + k * NS // 2
        if k % 4 == 0:
            t_s = k / 2
            head_m = START_M + speed_mps * t_s
            for role, x in (("head", head_m), ("eot", head_m - TRAIN_M)):
                if role == "eot" and silent_eot_after_s is not None and t_s > silent_eot_after_s:
                    continue
                lat, lon = proj.position(x)
                dev = f"unit-{role}"
                engine.handle(
                    GnssFix(
                        "mqtt://test",
                        dev,
                        first_stamped_ns
                        if k == 0 and first_stamped_ns is not None
                        else clock.t + int(skews.get(dev, 0.0) * NS) - NS // 5,  # measured 0.2 s before reception
                        float(lat[0]),
                        float(lon[0]),
                        speed_mps,
                        proj.bearing_deg(x),
                        time.monotonic(),
                        role=role,
                        train="7",
                    )
                )
        engine.tick()
    return [e for e in events if e["type"] == "crossing" and e["crossing"] == "11+850"], engine


def kinds(events: list[dict[str, Any]]) -> list[str]:
    return [e["kind"] for e in events]


def test_a_train_passing_turns_the_warning_on_in_time_and_off_after_its_tail() -> None:
    events, engine = run()
    assert kinds(events) == ["on", "off"]
    on_s = (events[0]["time_ns"] - T0) / NS
    off_s = (events[1]["time_ns"] - T0) / NS
    arrival_s = (CROSSING_M - START_M) / 15.0
    tail_past_s = (CROSSING_M + TRAIN_M - START_M) / 15.0
    warning_time_s = next(c.warning_time_s for c in engine.layout.crossings if c.code == "11+850")  # type: ignore[union-attr]
    assert arrival_s - on_s >= warning_time_s  # never late
    assert off_s >= tail_past_s  # never off before the tail is past


def test_the_warning_going_off_carries_its_lead_as_the_batch_timeline_computes_it() -> None:
    events, engine = run()
    off = events[1]
    # The head reaches the road's near edge (crossing half-width before the centre) this long after T0;
    # its fixes are measured 0.2 s before they arrive, and every 2 s: the interpolation is exact here.
    half = engine.crossings.settings.crossing_half_width_m  # type: ignore[union-attr]
    arrival_s = (CROSSING_M - half - START_M) / 15.0 - 0.2
    lead = arrival_s - (events[0]["time_ns"] - T0) / NS
    assert off["kind"] == "off" and off["lead_s"] == pytest.approx(lead, abs=0.01)
    assert off["late"] is False and off["warning_time_s"] <= off["lead_s"]


def test_a_silent_end_of_train_unit_keeps_the_warning_on() -> None:
    # The EOT falls silent well before the crossing: nothing proves the tail has passed.
    events, engine = run(silent_eot_after_s=40.0)
    assert "on" in kinds(events) and "off" not in kinds(events)
    assert engine.crossings is not None and engine.crossings.warnings_on()["11+850"]
    assert "alarm" in kinds(events)  # and the stale unit is reported


@pytest.mark.parametrize("skew_s", [3600.0, -3600.0, 7.5])
def test_units_with_wrong_clocks_give_the_same_warning(skew_s: float) -> None:
    reference, _ = run()
    skewed, engine = run(skews_s={"unit-head": skew_s, "unit-eot": -skew_s / 2})
    assert kinds(skewed) == kinds(reference)
    for a, b in zip(skewed, reference, strict=True):
        assert abs(a["time_ns"] - b["time_ns"]) <= 2 * NS
    assert engine.crossings is not None and not any(engine.crossings.warnings_on().values())


def test_an_end_of_train_clock_running_ahead_does_not_make_old_positions_fresh() -> None:
    # The EOT's clock is an hour ahead *and* it goes silent: still stale, still on.
    events, _ = run(skews_s={"unit-eot": 3600.0}, silent_eot_after_s=40.0)
    assert "off" not in kinds(events)


@pytest.mark.parametrize("stamp", ["2099-12-31T23:59:59Z", "1970-01-01T00:00:00Z"])
def test_one_report_from_a_broken_clock_does_not_age_the_units_later_fixes(stamp: str) -> None:
    # A receiver without its almanac (1970) or past a week rollover (2099): before, the 2099 report was
    # learnt as the units' clock skew and every later fix placed 73 years old (stale units, alarms).
    from parsers.gnss.lora import parse_time_rfc3339

    reference, _ = run()
    events, engine = run(first_stamped_ns=parse_time_rfc3339(stamp))
    assert kinds(events) == kinds(reference) == ["on", "off"]
    assert engine.summary([])["gnss_fixes_bad_clock"] == 2


def test_a_diagnostic_source_that_stops_mid_train_leaves_the_section_occupied() -> None:
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
    events: list[dict[str, Any]] = []
    engine = LiveEngine(load_layout("example"), events.append)
    # Feed up to the middle of the first train's run over the line, then nothing more.
    first_wheel = next(i for i, ln in enumerate(lines) if b"Radsensor" in ln)
    cut = first_wheel + 40
    engine.handle(LineBlock("file:x", "x", 1, b"".join(lines[:cut]), time.monotonic()))
    for _ in range(3):
        engine.tick()
    states = engine.diag.section_states()
    # The sweep train is inside 1G: counted in, not out. Without more evidence it stays so.
    assert states["1G"][0] != "clear" and states["1G"][1] > 0
    # The section changes went out as events; the engine keeps no growing history of them.
    assert engine.diag.sections is not None and not engine.diag.sections.ledger
    # Whatever was released to the section engine never shows a section clear with axles inside.
    for e in events:
        if e["type"] == "section" and e["state"] == "clear":
            assert e["count"] == 0


def test_speeds_are_finite_or_absent_in_live_passages() -> None:
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes()
    events: list[dict[str, Any]] = []
    engine = LiveEngine(load_layout("example"), events.append)
    engine.handle(LineBlock("file:x", "x", 1, lines, time.monotonic()))
    engine.finish()
    speeds = [e["speed_kmh_whole_train"] for e in events if e["type"] == "passage" and e["axles"]]
    assert speeds and all(s is None or math.isfinite(s) for s in speeds)


def test_followed_input_is_ingested_into_the_archive_once(tmp_path: Path) -> None:
    import json
    import subprocess

    from console.live.archive import LiveArchiver
    from tests.live_fixtures import trackside

    data = (REPO / "sample_logs" / "example_station.log").read_bytes()
    cut = data.index(b"\n", len(data) // 2) + 1
    archive = tmp_path / "arc"
    arch = LiveArchiver(archive)
    engine = LiveEngine(load_layout("example"), lambda ev: None, archiver=arch)
    # Before and after a rotation: two files of one followed source.
    engine.handle(LineBlock("file:x", "x.log", 1, data[:cut], time.monotonic()))
    arch.ingest()
    engine.handle(LineBlock("file:x", "x.log#2", 1, data[cut:], time.monotonic()))
    engine.finish()  # ingests the grown spool: only what is new
    out = subprocess.run(
        trackside("query", "--archive", str(archive), "--format", "json", "SELECT count(*) AS n FROM records"),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert json.loads(out.stdout)[0]["n"] == data.count(b"\n")


def test_a_full_disk_at_the_spools_ingest_is_said_in_the_summary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`follow --archive` on a full disk exited 0 with no word: the spool's ingest failed in silence."""
    import errno

    import pyarrow.parquet as pq

    from console.archive.query import run_query
    from console.cli.commands.follow import _summary_lines
    from console.live.archive import LiveArchiver

    archive = tmp_path / "arc"
    arch = LiveArchiver(archive)
    engine = LiveEngine(load_layout("example"), lambda ev: None, archiver=arch)
    data = (REPO / "sample_logs" / "example_station.log").read_bytes()
    engine.handle(LineBlock("file:x", "x.log", 1, data, time.monotonic()))

    def full(*_a: object, **_k: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pq.ParquetWriter, "write_table", full)
    engine.finish()
    monkeypatch.undo()
    summary = engine.summary([])
    assert summary["archive_errors"] == [f"{archive}: no space left on device: archive unchanged"]
    assert f"  --archive: not ingested: {archive}: no space left on device" in "\n".join(_summary_lines(summary))
    arch.ingest()  # space again: the spool kept it all
    assert arch.ingests == 1
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(data.count(b"\n"),)]


@pytest.fixture(scope="module")
def batch_passages() -> list[dict[str, Any]]:
    from console.analysis.passages.speed_settings import SpeedSettings
    from tests.reads import whole_job

    job = whole_job([REPO / "sample_logs" / "example_station.log"], SpeedSettings())
    return sorted(job.analysis.passages_json(), key=lambda p: (p["start"], p["counting_head"]))


# Property: however the log's lines arrive in blocks, the live engine finds the batch passages.
@settings(max_examples=3, deadline=None)  # about 1.5 s each: the whole sample log
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=12))
def test_passages_do_not_depend_on_how_the_lines_arrive(
    batch_passages: list[dict[str, Any]], cuts: list[float]
) -> None:
    data = (REPO / "sample_logs" / "example_station.log").read_bytes()
    # Block ends at line ends, as the file source hands them over.
    bounds = sorted({0, len(data)} | {data.find(b"\n", int(c * len(data))) + 1 or len(data) for c in cuts})
    events: list[dict[str, Any]] = []
    engine = LiveEngine(None, events.append, include_status=True)
    line = 1
    for a, b in itertools.pairwise(bounds):
        if b > a:
            engine.handle(LineBlock("file:x", "x", line, data[a:b], time.monotonic()))
            line += data[a:b].count(b"\n")
    engine.finish()
    got = sorted(
        ({k: v for k, v in e.items() if k != "type"} for e in events if e["type"] == "passage"),
        key=lambda p: (p["start"], p["counting_head"]),
    )
    assert got == batch_passages


def _shifted(line: bytes, seconds: float) -> bytes:
    import datetime as dt
    import re

    m = re.search(rb"Date:(\S+)\tTime:(\S+)", line)
    assert m is not None
    t = dt.datetime.fromisoformat(f"{m[1].decode()}T{m[2].decode()}") + dt.timedelta(seconds=seconds)
    stamp = f"Date:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S}.{t.microsecond // 1000:03d}".encode()
    return line[: m.start()] + stamp + line[m.end() :]


@pytest.mark.parametrize("skew_s", [0.0, 3600.0, -3600.0])
def test_two_logs_with_skewed_clocks_give_each_logs_own_passages(skew_s: float, tmp_path: Path) -> None:
    """Two boards' logs followed at once, the second's clock ``skew_s`` off, arriving interleaved:
    each log's passages are what ``analyze`` finds in it alone (a log running ahead does not cut
    the other's trains into pieces), and the sections are those of both logs read together."""
    from console.analysis.passages.speed_settings import SpeedSettings
    from tests.reads import whole_job

    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
    arrival = [
        ("a", ln) if b"Trackinfo:WS1\t" in ln or b"Trackinfo:WS2\t" in ln else ("b", _shifted(ln, skew_s))
        for ln in lines
    ]
    logs = {s: b"".join(ln for src, ln in arrival if src == s) for s in "ab"}
    expected = []
    for s, data in logs.items():
        (tmp_path / f"{s}.log").write_bytes(data)
        job = whole_job([tmp_path / f"{s}.log"], SpeedSettings())
        expected += [(p["counting_head"], p["start"], p["axles"]) for p in job.analysis.passages_json()]

    def follow(blocks: list[tuple[str, bytes]]) -> list[dict[str, Any]]:
        events: list[dict[str, Any]] = []
        engine = LiveEngine(load_layout("example"), events.append, include_status=True)
        line = dict.fromkeys("abx", 1)
        for src, data in blocks:
            engine.handle(LineBlock(f"file:{src}", src, line[src], data, time.monotonic()))
            line[src] += data.count(b"\n")
        engine.finish()
        return events

    # Forty lines of one log, then forty of the other...: the second log's block may reach far ahead.
    blocks = []
    for s in "ab":
        mine = [ln for src, ln in arrival if src == s]
        blocks += [(k, s, b"".join(mine[k : k + 40])) for k in range(0, len(mine), 40)]
    events = follow([(s, data) for _, s, data in sorted(blocks, key=lambda b: (b[0], b[1]))])
    got = [(p["counting_head"], p["start"], p["axles"]) for p in events if p["type"] == "passage"]
    assert sorted(got) == sorted(expected)
    together = follow([("x", b"".join(ln for _, ln in arrival))])
    sections = [(e["section"], e["state"], e["count"]) for e in events if e["type"] == "section"]
    assert sections == [(e["section"], e["state"], e["count"]) for e in together if e["type"] == "section"]
    assert all(count == 0 for _, state, count in sections if state == "clear")


def test_the_live_console_wakes_at_the_instant_a_warning_falls_due() -> None:
    # As run_sources does: between its steady ticks the console's clock wakes when next_wake_s says a
    # warning falls due, so the warning comes on at that instant (its earliest arrival exactly the
    # unit's horizon away), not at the next steady tick.
    proj, events, engine, clock = _engine_on_a_clock()
    assert engine.next_wake_s() is None  # nothing heard: nothing due
    assert engine.crossings is not None
    ctl = engine.crossings.controllers["11+850"]
    woken: list[tuple[int, int]] = []  # (instant, the instant the bound said) per wake-up
    for k in range(0, 400):
        step_end = T0 + (k + 1) * NS // 2
        clock.t = T0 + k * NS // 2
        if k % 20 == 0:  # fixes every 10 s
            head_m = START_M + 15.0 * k / 2
            for role, x in (("head", head_m), ("eot", head_m - TRAIN_M)):
                lat, lon = proj.position(x)
                fix = GnssFix(
                    "mqtt://test", f"unit-{role}", clock.t - NS // 5, float(lat[0]), float(lon[0]), 15.0,
                    proj.bearing_deg(x), time.monotonic(), role=role, train="7",
                )  # fmt: skip
                engine.handle(fix)
        engine.tick()
        while (due_s := engine.next_wake_s()) is not None and clock.t + int(due_s * NS) < step_end:
            clock.t += int(due_s * NS)
            bound = ctl.arrival_bound("7", clock.t)
            engine.tick()
            if bound is not None:
                woken.append((clock.t, bound[0].t_arrival_ns - int(ctl.horizon_s * NS)))
    on = [e for e in events if e["type"] == "crossing" and e["crossing"] == "11+850" and e["kind"] == "on"]
    assert len(on) == 1 and str(on[0]["reason"]).startswith("ETA")
    assert (on[0]["time_ns"] - T0) % (NS // 2) != 0  # not on a steady tick
    assert (on[0]["time_ns"], on[0]["time_ns"]) in woken  # at the instant the bound fell due


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    cuts1=st.lists(st.integers(1, 3384), max_size=6),
    cuts2=st.lists(st.integers(1, 3384), max_size=6),
    stop=st.integers(1, 3385),
)
def test_a_log_followed_again_from_its_start_is_not_archived_twice(
    tmp_path_factory: pytest.TempPathFactory, cuts1: list[int], cuts2: list[int], stop: int
) -> None:
    """`follow --from-start --archive` run again on the same log (a restart) spooled it a second time: the
    archive's records held every line twice.  A first run that stopped anywhere (``stop``), a second run
    reading the log from its start in other blocks, then a rewritten log: each line is archived once, and
    the lines read again are counted."""
    from console.archive.query import run_query
    from console.live.archive import LiveArchiver

    tmp_path = tmp_path_factory.mktemp("again")
    archive = tmp_path / "arc"
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)

    def run(upto: int, cuts: list[int], first: int = 1) -> LiveArchiver:
        arch = LiveArchiver(archive)
        at = [0, *sorted({c for c in cuts if c < upto}), upto]
        for a, b in itertools.pairwise(at):
            arch(LineBlock("file:x", "x.log", first + a, b"".join(lines[a:b]), time.monotonic()))
        arch.finish()
        return arch

    run(stop, cuts1)
    again = run(len(lines), cuts2)
    assert again.repeated_lines == stop
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(len(lines),)]
    # The log rewritten (its first line differs): all of it is new.
    lines[0] = lines[0].replace(b"07:55:00", b"07:55:01")
    assert lines[0] != (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)[0]
    rewritten = run(len(lines), cuts1)
    assert rewritten.repeated_lines == 0
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(2 * len(lines),)]


def test_a_restart_after_a_rotation_archives_each_line_once(tmp_path: Path) -> None:
    """A first run follows x.log through a rotation (its new file spooled as the rotation's own, "x.log#2"); the
    restarted run reads the new file from its start as x.log, with its own rotation count.  Its lines were
    compared with the old file's spool, differed, and were stored a second time.  Now a block read from a
    file's first line goes to the spool file of that followed path whose content it repeats: each line once."""
    from console.archive.query import run_query
    from console.live.archive import LiveArchiver

    archive = tmp_path / "arc"
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
    old, new = lines[:1500], lines[1500:]

    def block(name: str, first: int, part: list[bytes]) -> LineBlock:
        return LineBlock("file:x", name, first, b"".join(part), time.monotonic())

    first = LiveArchiver(archive)
    first(block("x.log", 1, old))
    first(block("x.log#2", 1, new[:1000]))  # rotated: the new file, read as it grows
    first.finish()
    again = LiveArchiver(archive)
    again(block("x.log", 1, new[:600]))  # restarted with --from-start: the current file, from its start
    again(block("x.log", 601, new[600:]))
    again(block("x.log#2", 1, old[:10]))  # and rotated once more (a file that happens to repeat the old start)
    again.finish()
    assert again.repeated_lines == 1000 + 10
    assert again.errors == [] and again.spool_errors == []
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(len(lines),)]
    # Lines read from the middle of a file (a run without --from-start) still go to its spool as before.
    late = LiveArchiver(archive)
    late(block("x.log", 200, [line.replace(b"Date:2026-03-02", b"Date:2026-03-03") for line in lines[:5]]))
    late.finish()
    assert late.repeated_lines == 0
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(len(lines) + 5,)]


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_restarts_and_rotations_in_any_order_archive_each_line_once(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    """A log rotated at random points into files, followed by runs that each restart on the current file from its
    start (`follow --from-start --archive`), read it in random blocks through later rotations, and stop anywhere:
    every line any run read is archived exactly once, and the archive passes `verify`."""
    from console.archive.query import run_query
    from console.archive.verify import verify_archive
    from console.live.archive import LiveArchiver

    archive = tmp_path_factory.mktemp("rotations") / "arc"
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
    cuts = sorted(set(data.draw(st.lists(st.integers(1, len(lines) - 1), min_size=1, max_size=4), label="rotations")))
    files = [lines[a:b] for a, b in itertools.pairwise([0, *cuts, len(lines)])]
    starts = list(itertools.accumulate([0, *map(len, files)]))  # each file's first line in the log
    read: set[int] = set()
    at = 0  # the file current when the next run starts
    for _run in range(data.draw(st.integers(1, 4), label="runs")):
        at = data.draw(st.integers(at, len(files) - 1), label="restart on file")
        last = data.draw(st.integers(at, len(files) - 1), label="stop in file")
        arch = LiveArchiver(archive)
        for k in range(at, last + 1):
            name = "x.log" if k == at else f"x.log#{k - at + 1}"  # a run counts rotations from its first file
            upto = len(files[k]) if k < last else data.draw(st.integers(1, len(files[k])), label="stop at line")
            blocks = sorted(set(data.draw(st.lists(st.integers(1, max(1, upto - 1)), max_size=3), label="blocks")))
            for a, b in itertools.pairwise([0, *[c for c in blocks if c < upto], upto]):
                arch(LineBlock("file:x", name, a + 1, b"".join(files[k][a:b]), time.monotonic()))
            read |= set(range(starts[k], starts[k] + upto))
        arch.finish()
        assert arch.errors == [] and arch.spool_errors == []
        at = last
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(len(read),)]
    assert verify_archive(archive).intact


def test_a_spool_file_that_cannot_be_written_takes_nothing_more_and_says_from_where(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk at the spool stopped `follow --archive` with 'cannot write output' (it is not the output);
    now the analysis goes on, the spool file takes nothing more (the archive never holds a log with a gap),
    and the summary says from which line and how many lines were not archived."""
    import errno

    from console.archive.query import run_query
    from console.cli.commands.follow import _summary_lines
    from console.live.archive import LiveArchiver

    archive = tmp_path / "arc"
    arch = LiveArchiver(archive)
    engine = LiveEngine(load_layout("example"), lambda ev: None, archiver=arch)
    lines = (REPO / "sample_logs" / "example_station.log").read_bytes().splitlines(keepends=True)
    engine.handle(LineBlock("file:x", "x.log", 1, b"".join(lines[:1000]), time.monotonic()))
    real_open = Path.open

    def full(self: Path, mode: str = "r", *a: Any, **k: Any) -> Any:
        if "a" in mode and self.parent.name.endswith(".live"):
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_open(self, mode, *a, **k)

    monkeypatch.setattr(Path, "open", full)
    engine.handle(LineBlock("file:x", "x.log", 1001, b"".join(lines[1000:2000]), time.monotonic()))
    monkeypatch.undo()  # space again: still nothing more in this run, the log would have a gap
    engine.handle(LineBlock("file:x", "x.log", 2001, b"".join(lines[2000:]), time.monotonic()))
    engine.finish()
    summary = engine.summary([])
    assert summary["files"][0]["lines_read"] == len(lines)  # analysed all the same
    assert summary["archive_lines_not_spooled"] == len(lines) - 1000
    [error] = summary["archive_spool_errors"]
    assert error.endswith("cannot spool (no space left on device): not archived from line 1001 of the followed file on")
    shown = "\n".join(_summary_lines(summary))
    assert f"--archive: {len(lines) - 1000} lines not archived" in shown
    assert run_query(archive, "SELECT count(*) FROM records")[1] == [(1000,)]
