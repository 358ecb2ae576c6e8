"""``follow -``, a named FIFO: a stream read as it comes, to its end.

A log written into a pipe in random pieces (lines cut anywhere) with pauses gives what following the
same log as a file gives; the end of the stream ends ``follow`` with its summary and exit 0; every line
is a record, blank or rejected (with ``-`` and its number) and the totals add up; a terminal on
standard input is refused in one line.
"""

from __future__ import annotations

import contextlib
import json
import os
import pty
import queue
import random
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from console.cli.app import app
from console.inputs.base import Item, LineBlock
from console.inputs.stream import READ_BYTES, StreamSource
from console.live.backlog import Backlog
from tests.live_fixtures import REPO, read_jsonl, trackside, wait_until

pytestmark = pytest.mark.timeout(90)

SAMPLES = REPO / "sample_logs"
EVENT_TYPES = ("passage", "section", "crossing", "integrity", "health")
# (sample, follow's options): a diagnostic log with its layout's sections, a CAN log, a sensor frame log.
LOGS = [
    ("example_station.log", ("--layout", "example", "--include-status")),
    ("ws4_health.log", ()),
    ("can_counts.log", ()),
    ("sensor_frames.txt", ()),
]


def write_in_pieces(write: Callable[[bytes], object], data: bytes, seed: int, max_piece: int = 8192) -> None:
    """``data`` in pieces of random size (lines cut anywhere), with a short pause now and then."""
    rng = random.Random(seed)
    pos = 0
    while pos < len(data):
        n = rng.randint(1, max_piece)
        write(data[pos : pos + n])
        pos += n
        if rng.random() < 0.2:
            time.sleep(rng.uniform(0.0, 0.03))


def follow_piped(data: bytes, *args: str, seed: int = 1, tmp: Path) -> tuple[int, list[dict[str, Any]], str]:
    """``trackside follow - --jsonl ARGS`` with ``data`` written into its standard input in pieces, then closed:
    (exit code, its JSON lines, its stderr).  It must end by itself: the end of the stream ends it."""
    out_path, err_path = tmp / f"out{seed}.jsonl", tmp / f"err{seed}.txt"
    with out_path.open("wb") as out, err_path.open("wb") as err:
        proc = subprocess.Popen(
            trackside("follow", "-", "--jsonl", *args), stdin=subprocess.PIPE, stdout=out, stderr=err
        )
        try:
            assert proc.stdin is not None
            stdin = proc.stdin

            def write(piece: bytes) -> None:
                stdin.write(piece)
                stdin.flush()

            write_in_pieces(write, data, seed)
            stdin.close()
            code = proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    return code, read_jsonl(out_path.read_text()), err_path.read_text()


@cache
def followed_file(path: Path, args: tuple[str, ...]) -> tuple[dict[str, Any], ...]:
    """What ``follow file:PATH --from-start`` gives for a whole file (ended by --idle-exit)."""
    out = subprocess.run(
        trackside("follow", f"file:{path}", "--from-start", "--idle-exit", "1", "--jsonl", *args),
        capture_output=True,
        text=True,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )
    assert out.returncode == 0, out.stderr
    return tuple(read_jsonl(out.stdout))


def events(lines: list[dict[str, Any]] | tuple[dict[str, Any], ...], drop: tuple[str, ...] = ()) -> list[str]:
    """The analysis events, as sorted JSON (sources interleave their events differently, the events are equal)."""
    return sorted(
        json.dumps({k: v for k, v in e.items() if k not in drop}, sort_keys=True)
        for e in lines
        if e["type"] in EVENT_TYPES
    )


def rejections(lines: list[dict[str, Any]] | tuple[dict[str, Any], ...]) -> list[tuple[int, str, str]]:
    return [(e["line"], e["reason"], e["text"]) for e in lines if e["type"] == "source" and e["kind"] == "rejected"]


def line_totals_add_up(summary: dict[str, Any], data: bytes) -> None:
    assert summary["type"] == "summary"
    for f in summary["files"]:
        assert f["lines_read"] == f["records"] + f["blank"] + f["rejected"] + f.get("unrecognised", 0), f
    assert sum(f["lines_read"] for f in summary["files"]) == data.count(b"\n") + (not data.endswith(b"\n"))


@pytest.mark.parametrize(("name", "args"), LOGS, ids=[n for n, _ in LOGS])
def test_a_log_piped_in_random_pieces_gives_what_following_the_file_gives(
    name: str, args: tuple[str, ...], tmp_path: Path
) -> None:
    data = (SAMPLES / name).read_bytes()
    code, got, err = follow_piped(data, *args, seed=len(name), tmp=tmp_path)
    assert code == 0, err  # the end of the stream ended it
    want = followed_file(SAMPLES / name, args)
    assert events(got) == events(want) and events(want)
    summary, file_summary = got[-1], want[-1]
    assert [f["file"] for f in summary["files"]] == ["-"]
    strip = [{k: v for k, v in f.items() if k != "file"} for f in summary["files"]]
    assert strip == [{k: v for k, v in f.items() if k != "file"} for f in file_summary["files"]]
    line_totals_add_up(summary, data)
    (ended,) = [e for e in got if e["type"] == "source" and e["kind"] == "ended"]
    assert "end of stream" in ended["detail"]


def test_nmea_piped_in_gives_the_fixes_and_crossing_warnings_of_the_followed_file(tmp_path: Path) -> None:
    run = tmp_path / "run"
    sim = ("simulate", "-o", str(run), "--duration", "5m", "--trains-per-hour", "12", "--layout", "example")
    subprocess.run(trackside(*sim), capture_output=True, check=True, timeout=60)
    head = run / "nmea" / "T1-head.nmea"
    data = head.read_bytes()
    code, got, err = follow_piped(data, "--layout", "example", seed=3, tmp=tmp_path)
    assert code == 0, err
    want = followed_file(head, ("--layout", "example"))
    # A pipe has no name: its unit is "-" where the file's is T1 (its stem); the warnings are the same.
    assert events(got, drop=("train",)) == events(want, drop=("train",))
    assert any(e["type"] == "crossing" for e in got)
    assert got[-1]["gnss_fixes"] == want[-1]["gnss_fixes"] > 0
    line_totals_add_up(got[-1], data)


def test_junk_and_binary_bytes_in_the_stream_are_rejected_by_line_as_in_a_file(tmp_path: Path) -> None:
    rng = random.Random(7)
    lines = (SAMPLES / "example_station.log").read_bytes().splitlines(keepends=True)
    for k in sorted(rng.sample(range(len(lines)), 12), reverse=True):
        lines.insert(k, bytes(rng.randrange(256) for _ in range(rng.randint(1, 200))).replace(b"\n", b"") + b"\n")
    data = b"".join(lines)
    junk = tmp_path / "junk.log"
    junk.write_bytes(data)
    code, got, err = follow_piped(data, "--layout", "example", seed=5, tmp=tmp_path)
    assert code == 0, err
    want = followed_file(junk, ("--layout", "example"))
    assert events(got) == events(want)
    # Each junk line said: file "-", its number, why (the same as in the file).
    assert {e["file"] for e in got if e.get("kind") == "rejected"} == {"-"}
    assert rejections(got) == rejections(want) and len(rejections(got)) >= 12
    assert got[-1]["files"][0]["rejected"] == len(rejections(got))
    line_totals_add_up(got[-1], data)


def test_a_stream_of_no_format_is_one_note_and_its_lines_are_counted_as_unrecognised(tmp_path: Path) -> None:
    data = random.Random(9).randbytes(50_000)
    code, got, err = follow_piped(data, seed=9, tmp=tmp_path)
    assert code == 0, err
    (note,) = [e for e in got if e.get("kind") == "unrecognised"]
    assert "binary" in note["detail"]
    (f,) = got[-1]["files"]
    assert f["file"] == "-" and f["unrecognised"] == f["lines_read"] == data.count(b"\n") + 1
    line_totals_add_up(got[-1], data)


def test_the_end_of_the_stream_hands_over_an_unfinished_last_line(tmp_path: Path) -> None:
    data = (SAMPLES / "ws4_subsecond.log").read_bytes() + b"Diag_id: 1; ID"  # the writer died mid-line
    code, got, err = follow_piped(data, seed=11, tmp=tmp_path)
    assert code == 0, err
    n = data.count(b"\n") + 1
    assert any(e.get("kind") == "info" and f"line {n}: unfinished line" in e["detail"] for e in got)
    assert [r[0] for r in rejections(got)][-1] == n
    line_totals_add_up(got[-1], data)


def test_a_named_fifo_waits_for_its_writer_and_its_end_ends_follow(tmp_path: Path) -> None:
    fifo = tmp_path / "station.log"
    os.mkfifo(fifo)
    out_path = tmp_path / "out.jsonl"
    with out_path.open("wb") as out:
        proc = subprocess.Popen(
            trackside("follow", str(fifo), "--jsonl", "--layout", "example", "--include-status"),
            stdout=out,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
        )
        try:
            assert wait_until(lambda: b'"connected"' in out_path.read_bytes(), 20)
            time.sleep(0.5)
            assert proc.poll() is None  # no writer yet is not the end of the stream
            data = (SAMPLES / "example_station.log").read_bytes()
            fd = os.open(fifo, os.O_WRONLY)
            try:
                write_in_pieces(lambda piece: os.write(fd, piece), data, seed=13)
            finally:
                os.close(fd)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 0, err
    got = read_jsonl(out_path.read_text())
    want = followed_file(SAMPLES / "example_station.log", ("--layout", "example", "--include-status"))
    assert events(got) == events(want)
    assert [f["file"] for f in got[-1]["files"]] == [str(fifo)]
    line_totals_add_up(got[-1], data)


def test_ctrl_c_analyses_what_the_pipe_holds_and_says_so_in_the_summary(tmp_path: Path) -> None:
    data = (SAMPLES / "example_station.log").read_bytes()
    half = data[: data.index(b"\n", len(data) // 2) + 1] + b"Diag_id: 4081; ID: 1"  # and a line half-written
    out_path, err_path = tmp_path / "out.jsonl", tmp_path / "err.txt"
    with out_path.open("wb") as out, err_path.open("wb") as err:
        proc = subprocess.Popen(trackside("follow", "-", "--jsonl"), stdin=subprocess.PIPE, stdout=out, stderr=err)
        try:
            assert proc.stdin is not None
            proc.stdin.write(half)  # the writer goes on living: the stream does not end
            proc.stdin.flush()
            assert wait_until(lambda: b'diagnostic log"' in out_path.read_bytes(), 20)
            proc.send_signal(signal.SIGINT)
            code = proc.wait(timeout=60)  # standard input still open: the stop, not the end of the stream, ends it
        finally:
            if proc.poll() is None:
                proc.kill()
            assert proc.stdin is not None
            proc.stdin.close()
    assert code == 130, err_path.read_text()
    got = read_jsonl(out_path.read_text())
    summary = got[-1]
    # Everything written before the interrupt was analysed, the half-written line as one rejected line.
    line_totals_add_up(summary, half)
    assert "not_analysed" not in summary
    assert any("unfinished line" in e.get("detail", "") and "at stop" in e["detail"] for e in got)
    assert summary["sources"][0]["detail"] == "ended: -: stopped"


def test_standard_input_that_is_a_terminal_is_refused_in_one_line() -> None:
    pid, fd = pty.fork()
    if pid == 0:  # the child: its standard input, output and error are the pseudo-terminal
        argv = trackside("follow", "-")
        os.execv(argv[0], argv)
    said = b""
    end = time.monotonic() + 30
    while time.monotonic() < end:
        try:
            piece = os.read(fd, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not piece:
            break
        said += piece
    _, status = os.waitpid(pid, 0)
    os.close(fd)
    assert os.waitstatus_to_exitcode(status) == 2
    text = said.decode()
    assert text.strip().splitlines() == [
        "trackside: error: -: standard input is a terminal; pipe a log into it (… | trackside follow -) or give a file"
    ]


runner = CliRunner()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["follow", "-", "-"], "-: standard input given twice"),
        (["follow", "-", "file:-"], "file:-: standard input given twice"),
        (["station", "--live", "-"], "--live -: the station view reads keys from standard input"),
        (["station", "--live", "file:/nonexistent/a.log", "file:-"], "--live -: the station view reads keys"),
    ],
)
def test_a_stream_given_where_it_cannot_be_read_is_a_one_line_error(args: list[str], message: str) -> None:
    res = runner.invoke(app, args)
    assert res.exit_code == 2
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"trackside: error: {message}")


def test_one_fifo_given_twice_is_a_one_line_error(tmp_path: Path) -> None:
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    res = runner.invoke(app, ["follow", str(fifo), f"file:{fifo}"])
    assert res.exit_code == 2
    assert res.stderr.strip() == f"trackside: error: file:{fifo}: the same stream as {fifo}"


def test_a_fast_writer_waits_on_the_full_pipe_while_the_engine_is_behind(tmp_path: Path) -> None:
    """The stream's reader is held by the backlog like a file's: the pipe fills, the writer waits, memory
    stays bounded; once the engine takes the items, every line arrives, in order."""
    fifo = tmp_path / "fast.log"
    os.mkfifo(fifo)
    backlog = Backlog(limit_bytes=1 << 20)
    source = StreamSource(str(fifo), fifo)
    source.start(backlog.putter(source))
    line = b"Diag_id: 4081; ID: 1; Device: x; Type: y; GS: 1; 2026-03-02 08:00:00.000; junk\n"
    total = 60 << 20
    written = [0]

    def writer() -> None:
        fd = os.open(fifo, os.O_WRONLY)
        block = line * (65536 // len(line))
        while written[0] < total:
            written[0] += os.write(fd, block)
        os.close(fd)

    t = threading.Thread(target=writer, daemon=True)
    t.start()
    time.sleep(1.5)
    # Held: what was read waits in the backlog (its limit, one read block, one read gathered), the rest in
    # the pipe (at most 1 MiB) and the writer.
    assert written[0] < backlog.limit_bytes + 3 * READ_BYTES + (1 << 20) + (64 << 10), written[0]
    got: list[Item] = []
    end = time.monotonic() + 60
    while not (source.input_ended and backlog.empty()) and time.monotonic() < end:
        with contextlib.suppress(queue.Empty):  # the reader is between reads
            got.append(backlog.get(1.0))
    t.join(10)
    blocks = [i for i in got if isinstance(i, LineBlock)]
    assert sum(len(b.data) for b in blocks) == written[0]
    firsts = [b.first_line for b in blocks]
    assert firsts == sorted(firsts) and firsts[0] == 1
    assert blocks[-1].first_line + blocks[-1].data.count(b"\n") - 1 == written[0] // len(line)


def test_standard_input_closed_is_a_one_line_error() -> None:
    # bash closes fd 0 (<&-) before trackside starts: nothing there to read, not some file that took fd 0.
    out = subprocess.run(
        ["bash", "-c", 'exec "$@" <&-', "bash", *trackside("follow", "-")], capture_output=True, text=True, timeout=30
    )
    assert out.returncode == 2
    assert out.stderr.strip() == "trackside: error: -: standard input is closed"


def test_a_fifo_made_where_a_followed_file_was_awaited_is_said_not_read_by_position(tmp_path: Path) -> None:
    late = tmp_path / "late.log"
    out_path = tmp_path / "out.jsonl"
    with out_path.open("wb") as out:
        proc = subprocess.Popen(
            trackside("follow", str(late), "--jsonl"), stdout=out, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL
        )
        try:
            assert wait_until(lambda: b"waiting for the file" in out_path.read_bytes(), 20)
            os.mkfifo(late)
            assert wait_until(lambda: b"not a file now" in out_path.read_bytes(), 10)
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
    assert proc.returncode == 143, err  # stopped at once: nothing blocked on opening the FIFO
    assert b"Illegal seek" not in out_path.read_bytes()
    assert read_jsonl(out_path.read_text())[-1]["type"] == "summary"


def test_the_station_view_reads_a_fifo_and_says_when_it_ended(tmp_path: Path) -> None:
    from console.layout import load_layout
    from console.tui.live_source import LiveSource, status_line

    fifo = tmp_path / "station.log"
    os.mkfifo(fifo)
    source = StreamSource(f"file:{fifo}", fifo)
    view = LiveSource(load_layout("example"), [source])
    view.start()
    data = (SAMPLES / "example_station.log").read_bytes()
    writer = threading.Thread(target=lambda: fifo.write_bytes(data), daemon=True)  # opens, writes, closes
    writer.start()
    end = time.monotonic() + 60
    while not (source.input_ended and not view.pending()) and time.monotonic() < end:
        view.advance(0.1)
    view.advance(0.1)
    view.stop()
    (status,) = view.statuses()
    assert status.messages == data.count(b"\n")
    assert f"file:{fifo}: ended" in status_line(status)
    assert view.live.diag.stats.passages > 0  # analysed as it came, by the view's engine


def test_strict_exits_1_on_a_line_of_the_stream_rejected(tmp_path: Path) -> None:
    data = (SAMPLES / "ws4_subsecond.log").read_bytes() + b"not a record\n"
    code, got, err = follow_piped(data, "--strict", seed=17, tmp=tmp_path)
    assert code == 1, err
    assert rejections(got)[-1][0] == data.count(b"\n")
    code, _, err = follow_piped((SAMPLES / "ws4_subsecond.log").read_bytes(), "--strict", seed=19, tmp=tmp_path)
    assert code == 0, err
