"""A head's records going back in time within one file are told, with head, file, line and size.

Found on a hand-made case (2026-11-29): the example log with WS5's clock stepped back 40 s at 09:47 (an NTP
correction) was read without a word, and 2G was shown clear at 09:47:37 while the train stood in it until
09:48:17. The analysis still sorts by time (a file out of order is read right that way), but the step is said.

Since then a step is doubt: the sections the head bounds are disturbed from the first record after it (a
property over simulated hours with a head's clock stepped back at random, for every step the records show).

The truths: steps made by hand at known lines; no step in logs written the way devices and exports write
them (boards interleaved at µs, ms and whole-second resolution, the simulator's logs, the shipped samples),
and the same steps whatever the chunks a file is read in.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages.clock_steps import ClockSteps
from console.cli.app import app
from console.layout import load_layout
from parsers.diag.read import DiagReader
from tests.conftest import SAMPLES

TRACKSIDE = str(Path(sys.executable).parent / "trackside")
NS = 1_000_000_000
SLACK_NS = 2 * NS
_STAMP = re.compile(r"Date:(\S+)\tTime:(\S+)")


def _steps(path: Path, chunk_bytes: int | None = None) -> ClockSteps:
    """The steps of a log read through the reader (in chunks of about ``chunk_bytes``)."""
    from console.analysis.passages.registers import RegisterTables

    reader = DiagReader([path], chunk_bytes=chunk_bytes) if chunk_bytes else DiagReader([path])
    tables = RegisterTables(reader.registry)
    steps = ClockSteps(SLACK_NS)
    for chunk in reader.chunks():
        steps.feed(chunk.file_id, tables.update().head_of(chunk.register_id), chunk.time_ns, chunk.line)
    return steps


def _stepped(src: Path, dst: Path, head: str, from_time: str, back_s: float) -> int:
    """``src`` with ``head``'s records from ``from_time`` on stamped ``back_s`` earlier; the first such line."""
    first = 0
    out = []
    for i, line in enumerate(src.read_text("utf-8").splitlines(keepends=True), start=1):
        m = _STAMP.search(line)
        if m and f"Trackinfo:{head}\t" in line and m[2] >= from_time:
            t = dt.datetime.fromisoformat(f"{m[1]} {m[2]}") - dt.timedelta(seconds=back_s)
            line = line.replace(m[0], f"Date:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S.%f}"[:-3])
            first = first or i
        out.append(line)
    dst.write_text("".join(out), "utf-8")
    return first


def test_a_clock_stepped_back_is_told_in_one_line_with_where(tmp_path: Path) -> None:
    log = tmp_path / "stepped.log"
    line = _stepped(SAMPLES / "example_station.log", log, "WS5", "09:47:05", 40.0)
    p = subprocess.run([TRACKSIDE, "sections", str(log), "--layout", "example"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    told = [w for w in p.stderr.splitlines() if "go back" in w]
    # WS5's heartbeat before the step was at 09:47:00; the one after it, 09:47:20, now reads 09:46:40.
    assert told == [
        f"trackside: warning: WS5: its records go back 20.0 s at {log} line {line:,} (the device's clock stepped "
        "back, or the file is not in time order): sections it bounds are disturbed from 2026-03-02 09:46:40, the "
        "time of that line"
    ]
    # 2G (WS4 → WS5) held a train then: it is disturbed from the step, never shown clear early.
    doc = json.loads(
        subprocess.run(
            [TRACKSIDE, "sections", str(log), "--layout", "example", "--json"], capture_output=True, text=True
        ).stdout
    )
    rows = [r for r in doc["timeline"] if r["section"] == "2G" and r["time"] >= "2026-03-02T09:46"]
    assert [(r["state"], r["count"], r["time"]) for r in rows[:2]] == [
        ("occupied", 0, "2026-03-02T09:46:33.750Z"),
        ("disturbed", 8, "2026-03-02T09:46:40.000Z"),
    ]
    assert rows[1]["reason"] == "records of WS5 went back in time: counts after it may be out of order"
    # The report carries it too: a report made overnight is read when its stderr is long gone.
    md = tmp_path / "r.md"
    r = subprocess.run([TRACKSIDE, "report", str(log), "--layout", "example", "--format", "md", "-o", str(md)])
    assert r.returncode == 0
    text = md.read_text("utf-8").replace("\\", "")  # Markdown's escapes in the path
    assert f"- WS5: its records go back 20.0 s at {log} line {line:,}" in text
    clean = subprocess.run(
        [TRACKSIDE, "sections", str(SAMPLES / "example_station.log"), "--layout", "example"],
        capture_output=True,
        text=True,
    )
    assert clean.returncode == 0 and "go back" not in clean.stderr


def test_a_file_written_newest_first_is_told_once_per_head_with_how_often(tmp_path: Path) -> None:
    lines = (SAMPLES / "example_station.log").read_text("utf-8").splitlines(keepends=True)
    log = tmp_path / "newest_first.log"
    log.write_text("".join(reversed(lines)), "utf-8")
    steps = _steps(log)
    assert sorted({s.head_key for s in steps.steps}) == list(range(len(steps.steps)))  # one per head
    assert sum(steps.counts) == steps.count > 10 * len(steps.steps)
    p = subprocess.run([TRACKSIDE, "analyze", str(log)], capture_output=True, text=True)
    told = [w for w in p.stderr.splitlines() if "go back" in w]
    assert len(told) == 5 and all("more times in that file" in w for w in told)


def test_logs_as_devices_and_exports_write_them_have_no_step(tmp_path: Path) -> None:
    real = tmp_path / "real.log"
    generate(60_000, real, boards=12, resolution="mixed", seed=7, interleave_seed=3)
    for path in (real, *sorted(SAMPLES.glob("*.log"))):
        steps = _steps(path)
        assert steps.count == 0, (path.name, steps.steps[:3])
    # Several files given newest first are each in time order: no step (a step is within one file).
    day = tmp_path / "day"
    day.mkdir()
    lines = (SAMPLES / "example_station.log").read_text("utf-8").splitlines(keepends=True)
    half = len(lines) // 2
    (day / "a.log").write_text("".join(lines[:half]), "utf-8")
    (day / "b.log").write_text("".join(lines[half:]), "utf-8")
    p = subprocess.run([TRACKSIDE, "analyze", str(day / "b.log"), str(day / "a.log")], capture_output=True, text=True)
    assert p.returncode == 0 and "go back" not in p.stderr


@st.composite
def _heads_in_read_order(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, int | None, int]:
    """Several heads' records interleaved in read order, each head's times non-decreasing but for jitter under
    the slack; maybe one step back of more than the slack at a random record (its index)."""
    n = draw(st.integers(2, 400))
    heads = np.array(draw(st.lists(st.integers(0, 5), min_size=n, max_size=n)), np.int64)
    t = np.zeros(n, np.int64)
    clock = {h: 10**18 for h in range(6)}
    for i, h in enumerate(heads.tolist()):
        clock[h] += draw(st.integers(0, 30 * NS))
        t[i] = clock[h] - draw(st.integers(0, SLACK_NS))  # a board's own jitter, within the slack
    step = draw(st.none() | st.integers(1, n - 1))
    if step is not None:
        h = int(heads[step])
        earlier = np.flatnonzero(heads[:step] == h)
        if len(earlier) == 0:
            step = None
        else:
            back = draw(st.integers(3 * SLACK_NS, 3600 * NS))
            t[step] = t[earlier[-1]] - back
    return heads, t, step, draw(st.integers(1, n))


@settings(max_examples=300, deadline=None)
@given(_heads_in_read_order())
def test_one_step_is_found_where_it_is_whatever_the_chunks(
    case: tuple[np.ndarray, np.ndarray, int | None, int],
) -> None:
    heads, t, step, cut = case
    line = np.arange(1, len(t) + 1, dtype=np.int64)
    found = []
    for pieces in ([slice(0, len(t))], [slice(0, cut), slice(cut, len(t))]):
        steps = ClockSteps(SLACK_NS)
        for p in pieces:
            steps.feed(0, heads[p], t[p], line[p])
        found.append([(s.head_key, s.line, s.back_ns) for s in steps.steps])
    assert found[0] == found[1]
    assert [x[1] - 1 for x in found[0]] == ([] if step is None else [step])


def test_follow_tells_the_step_as_it_reads_it(tmp_path: Path) -> None:
    log = tmp_path / "stepped.log"
    line = _stepped(SAMPLES / "example_station.log", log, "WS5", "09:47:05", 40.0)
    p = subprocess.run(
        [TRACKSIDE, "follow", str(log), "--from-start", "--layout", "example", "--jsonl", "--idle-exit", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    events = [json.loads(x) for x in p.stdout.splitlines()]
    steps = [e for e in events if e.get("kind") == "clock_step"]
    assert [(e["counting_head"], e["line"], e["back_s"]) for e in steps] == [("WS5", line, 20.0)]
    assert steps[0]["file"] == str(log) and steps[0]["detail"].startswith("WS5: its records go back 20.0 s")


# -- fail-safe: a clock stepped back never shows a section clear with an axle inside ---------------------------


def _simulated_runs(root: Path, seeds: range) -> list[tuple[Path, dict[str, list[tuple[int, int]]], int, int]]:
    """Simulated hours (trains both ways, the example layout): each run's log, its true axles per section
    (a step function in ns), and its start and end."""
    from console.sim.line_values import SimConfig
    from console.sim.station import StationSim
    from console.sim.writers import write_run

    out = []
    for seed in seeds:
        sim = StationSim(load_layout("example"), SimConfig(seed=seed, trains_per_hour=12))
        sim.run(3600)
        write_run(sim, root / f"run{seed}")
        truth = json.loads((root / f"run{seed}" / "truth.json").read_text("utf-8"))
        inside = {s: [(_ns(t), int(n)) for t, n in rows] for s, rows in truth["sections"].items()}
        out.append((root / f"run{seed}", inside, _ns(truth["start"]), _ns(truth["end"])))
    return out


def _ns(iso_text: str) -> int:
    return int(np.datetime64(iso_text.rstrip("Z"), "ns").astype(np.int64))


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> list[tuple[Path, dict[str, list[tuple[int, int]]], int, int]]:
    return _simulated_runs(tmp_path_factory.mktemp("clock"), range(1, 5))


def _step_at(log: Path, out: Path, head: str, at_ns: int, back_s: float) -> bool:
    """``log`` with ``head``'s records stamped from ``at_ns`` on (true time) ``back_s`` earlier. True when the
    step shows in the records: the first record after it is stamped more than the order slack before the
    head's last record before it (a step back smaller than the time since the head's last record, its
    heartbeat, leaves every record in order: no reader can see it)."""
    lines = []
    before = after = None
    for line in log.read_text("utf-8").splitlines(keepends=True):
        m = _STAMP.search(line)
        if m and f"Trackinfo:{head}\t" in line:
            t_ns = _ns(f"{m[1]}T{m[2]}")
            if t_ns < at_ns:
                before = t_ns
            else:
                after = t_ns if after is None else after
                t = dt.datetime.fromisoformat(f"{m[1]} {m[2]}") - dt.timedelta(seconds=back_s)
                line = line.replace(m[0], f"Date:{t:%Y-%m-%d}\tTime:{t:%H:%M:%S.%f}"[:-3])
        lines.append(line)
    out.write_text("".join(lines), "utf-8")
    return before is not None and after is not None and before - (after - int(back_s * NS)) > SLACK_NS


@settings(max_examples=int(os.environ.get("CLOCK_STEP_EXAMPLES", "40")), deadline=None)
@given(
    pick=st.integers(0, 3),
    head=st.sampled_from(["WS1", "WS2", "WS3", "WS4", "WS5"]),
    at=st.floats(0.02, 0.98),
    back_s=st.floats(3.0, 3600.0),
)
def test_never_clear_with_an_axle_inside_when_a_clock_steps_back(
    runs: list[tuple[Path, dict[str, list[tuple[int, int]]], int, int]],
    tmp_path_factory: pytest.TempPathFactory,
    pick: int,
    head: str,
    at: float,
    back_s: float,
) -> None:
    run, inside, start_ns, end_ns = runs[pick]
    log = tmp_path_factory.mktemp("step") / "diagnostic.log"
    assume(_step_at(run / "diagnostic.log", log, head, start_ns + int(at * (end_ns - start_ns)), back_s))
    res = CliRunner().invoke(app, ["sections", str(log), "--layout", str(run / "layout.toml"), "--json"])
    assert res.exit_code == 0, res.output
    timeline = json.loads(res.stdout)["timeline"]
    for sid, steps in inside.items():
        rows = sorted((_ns(r["time"]), r["state"]) for r in timeline if r["section"] == sid)
        for (t0, state), (t1, _) in zip(rows, [*rows[1:], (end_ns + 1, "")], strict=True):
            if state != "clear":
                continue
            # The true axles inside over [t0, t1): the value at t0 and every change before t1.
            held = [n for t, n in steps if t <= t0][-1:] + [n for t, n in steps if t0 < t < t1]
            assert max(held, default=0) == 0, f"{sid} clear from {t0} to {t1} with axles inside ({head} -{back_s} s)"


def test_follow_never_stamps_a_section_row_before_the_rows_it_told_already(tmp_path: Path) -> None:
    """A step read after later records (follow reads a file as it comes): the doubt is stamped when it was read.

    Found by hand (2026-11-29): WS5's board back at 2000-03-02 after a battery loss, from 09:47:05 on; follow
    told 2G disturbed in a row stamped 2000-03-02 09:47:20, after rows of 2026: read by time (a table, a
    database), 2G was clear from its last 2026 row to the end. Now the row is stamped when the engine met it."""
    log = tmp_path / "battery.log"
    _stepped(SAMPLES / "example_station.log", log, "WS5", "09:47:05", 820_454_400.0)  # 26 years back: 2000
    p = subprocess.run(
        [TRACKSIDE, "follow", str(log), "--from-start", "--layout", "example", "--jsonl", "--idle-exit", "1"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    rows = [e for e in map(json.loads, p.stdout.splitlines()) if e.get("type") == "section"]
    for sid in ("1G", "B1", "B2", "2G"):
        times = [r["time_ns"] for r in rows if r["section"] == sid]
        assert times == sorted(times), sid
    # Stamped at the latest event the engine had when the step reached it: no later than the step's line
    # (09:47:20), however the file was cut into reads, so never after a row that shows 2G clear too long.
    last = [r for r in rows if r["section"] == "2G"][-1]
    assert last["state"] == "disturbed" and "2026-03-02T08:00" <= last["time"] <= "2026-03-02T09:47:20"
    assert last["reason"] == "records of WS5 went back in time: counts after it may be out of order"
