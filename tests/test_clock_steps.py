"""A head's records going back in time within one file are told, with head, file, line and size.

Found on a hand-made case (2026-11-29): the example log with WS5's clock stepped back 40 s at 09:47 (an NTP
correction) was read without a word, and 2G was shown clear at 09:47:37 while the train stood in it until
09:48:17. The analysis still sorts by time (a file out of order is read right that way); the step is now said.

The truths: steps made by hand at known lines; no step in logs written the way devices and exports write
them (boards interleaved at µs, ms and whole-second resolution, the simulator's logs, the shipped samples),
and the same steps whatever the chunks a file is read in.
"""

from __future__ import annotations

import datetime as dt
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages.clock_steps import ClockSteps
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
        "back, or the file is not in time order; sorted by time, a section it bounds may show clear early after a "
        "step back)"
    ]
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
    import json

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
