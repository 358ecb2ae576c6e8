"""file:PATH — following a growing log: partial lines, rotation, copytruncate, and
`trackside follow` reporting exactly what `trackside analyze` finds in the whole log.

The transport tests write lines that start like diagnostic records (``Diag_id:``): a file
is followed as the format its first lines show (tests/test_live_follow_formats.py), and
a diagnostic log's lines are handed on as they are read."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from console.inputs.base import Item, LineBlock
from console.inputs.follow import FileSource
from tests.live_fixtures import REPO, free_port, lines_read, read_jsonl, trackside, wait_until

pytestmark = pytest.mark.timeout(60)

SAMPLE = REPO / "sample_logs" / "example_station.log"


class Collector:
    def __init__(self) -> None:
        self.items: list[Item] = []
        self.lock = threading.Lock()

    def __call__(self, item: Item) -> None:
        with self.lock:
            self.items.append(item)

    def data(self) -> bytes:
        with self.lock:
            return b"".join(i.data for i in self.items if isinstance(i, LineBlock))

    def notes(self, kind: str) -> int:
        with self.lock:
            return sum(1 for i in self.items if getattr(i, "kind", None) == kind)


def _follow(path: Path, **kw: bool) -> tuple[FileSource, Collector]:
    src = FileSource(f"file:{path}", path, **kw)
    got = Collector()
    src.start(got)
    assert wait_until(lambda: src.status().connected, 5)  # the file is open before the test writes
    return src, got


@pytest.mark.parametrize("polling", [False, True], ids=["inotify", "polling"])
def test_a_partial_last_line_waits_for_its_newline(tmp_path: Path, polling: bool) -> None:
    log = tmp_path / "a.log"
    log.write_bytes(b"")
    src, got = _follow(log, from_start=True, force_polling=polling)
    try:
        with log.open("ab") as f:
            f.write(b"Diag_id: line one\nDiag_id: line tw")
            f.flush()
            assert wait_until(lambda: got.data() == b"Diag_id: line one\n", 5)
            time.sleep(0.2)
            assert got.data() == b"Diag_id: line one\n"  # "line tw" is not handed over half-written
            f.write(b"o\n")
            f.flush()
        assert wait_until(lambda: got.data() == b"Diag_id: line one\nDiag_id: line two\n", 5)
    finally:
        src.stop()
    blocks = [i for i in got.items if isinstance(i, LineBlock)]
    assert [b.first_line for b in blocks] == [1, 2]


def test_from_the_end_skips_what_is_there_but_keeps_true_line_numbers(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_bytes(b"Diag_id: old 1\nDiag_id: old 2\nDiag_id: old 3 unfinish")
    src, got = _follow(log)
    try:
        assert wait_until(lambda: src.status().connected, 5)
        with log.open("ab") as f:
            f.write(b"ed\nDiag_id: new 4\n")
        assert wait_until(lambda: got.data() == b"Diag_id: old 3 unfinished\nDiag_id: new 4\n", 5)
    finally:
        src.stop()
    first = next(i for i in got.items if isinstance(i, LineBlock))
    assert first.first_line == 3


def test_rotation_by_rename_loses_and_repeats_nothing(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_bytes(b"")
    src, got = _follow(log, from_start=True)
    expected = b""
    try:
        with log.open("ab") as f:
            for i in range(50):
                line = f"Diag_id: first {i}\n".encode()
                f.write(line)
                expected += line
            f.flush()
            os.rename(log, tmp_path / "a.log.1")
            # The writer has not reopened yet: these still go to the renamed file.
            for i in range(5):
                line = f"Diag_id: late {i}\n".encode()
                f.write(line)
                expected += line
        with log.open("ab") as f:
            for i in range(50):
                line = f"Diag_id: second {i}\n".encode()
                f.write(line)
                expected += line
        assert wait_until(lambda: got.data() == expected, 10), got.data()[-200:]
    finally:
        src.stop()
    assert src.rotations == 1
    assert got.notes("rotated") == 1


def test_copytruncate_takes_what_was_missed_from_the_copy(tmp_path: Path) -> None:
    log = tmp_path / "a.log"
    log.write_bytes(b"")
    src, got = _follow(log, from_start=True)
    expected = b""
    try:
        with log.open("ab") as f:
            for i in range(100):
                line = f"Diag_id: before {i:03d}\n".encode()
                f.write(line)
                expected += line
            f.flush()
            assert wait_until(lambda: got.data() == expected, 5)
            # Written and copied before the follower looks again, then truncated.
            tail = b"".join(f"Diag_id: unseen {i:03d}\n".encode() for i in range(7))
            f.write(tail)
            f.flush()
            expected += tail
            shutil.copyfile(log, tmp_path / "a.log.1")
            f.truncate(0)
            for i in range(30):  # grows again, past the old size's tail check
                line = f"Diag_id: after {i:03d}\n".encode()
                f.write(line)
                expected += line
        assert wait_until(lambda: got.data() == expected, 10), got.data()[-300:]
    finally:
        src.stop()
    assert src.truncations == 1


def mid_train(src: bytes, after: float) -> int:
    """A line boundary inside a train: ten wheel-sensor lines into the first train after ``after`` of the log."""
    start = src.index(b"Label:Radsensor", int(len(src) * after))
    cut = src.rindex(b"\n", 0, start) + 1
    for _ in range(10):
        cut = src.index(b"\n", cut) + 1
    return cut


def _write_in_pieces(src: bytes, dest: Path, cut: int, mode: str, read_all_of: Callable[[bytes], bool]) -> None:
    """Write ``src`` into ``dest`` in uneven pieces (lines cut anywhere), rotating at byte ``cut`` (a line end)
    once ``read_all_of(src[:cut])`` says the follower has read up to it."""
    halves = (src[:cut], src[cut:])
    for k, half in enumerate(halves):
        with dest.open("ab") as f:
            step = 7919  # a prime: pieces end mid-line
            for i in range(0, len(half), step):
                f.write(half[i : i + step])
                f.flush()
                time.sleep(0.01)
            if k == 0:
                # copytruncate loses what the follower has not read when the file is cut (logrotate's own
                # gap): the test rotates once the follower has caught up, which a fixed 0.3 s did not
                # always give it on a loaded machine.
                assert wait_until(lambda: read_all_of(halves[0]), 60), "the follower did not catch up"
                if mode == "rename":
                    os.rename(dest, dest.with_name(dest.name + ".1"))
                else:
                    shutil.copyfile(dest, dest.with_name(dest.name + ".1"))
                    f.truncate(0)


@pytest.fixture(scope="module")
def analyze_passages() -> list[dict[str, object]]:
    import json

    out = subprocess.run(
        trackside("analyze", str(SAMPLE), "--json", "--include-status", "--layout", "example"),
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return list(json.loads(out.stdout)["passages"])


@pytest.mark.parametrize("mode", ["rename", "copytruncate"])
def test_follow_of_a_log_written_in_pieces_and_rotated_mid_train_reports_what_analyze_finds(
    tmp_path: Path, mode: str, analyze_passages: list[dict[str, object]]
) -> None:
    log = tmp_path / "station.log"
    log.write_bytes(b"")
    port = free_port()  # its metrics tell how many lines the follower has read
    proc = subprocess.Popen(
        trackside(
            "follow",
            str(log),
            "--from-start",
            "--jsonl",
            "--layout",
            "example",
            "--idle-exit",
            "1.5",
            "--include-status",
            "--metrics",
            f"127.0.0.1:{port}",
        ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # the follower is up before the first piece
        assert '"connected"' in first
        data = SAMPLE.read_bytes()
        cut = mid_train(data, 0.5)
        # The rotation falls inside a train: wheel records just before and just after it.
        assert data[:cut].splitlines()[-1].count(b"Radsensor") == data[cut:].splitlines()[0].count(b"Radsensor") == 1
        _write_in_pieces(data, log, cut, mode, lambda written: lines_read(port) >= written.count(b"\n"))
        out, err = proc.communicate(timeout=40)
        out = first + out
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    events = read_jsonl(out)
    passages = [{k: v for k, v in e.items() if k != "type"} for e in events if e["type"] == "passage"]

    def key(p: dict[str, object]) -> tuple[str, str]:
        return str(p["start"]), str(p["counting_head"])

    assert len(passages) == len(analyze_passages) > 100, (events[-1], err[-500:])
    assert sorted(passages, key=key) == sorted(analyze_passages, key=key)
    summary = events[-1]
    assert summary["type"] == "summary"
    for f in summary["files"]:
        assert f["lines_read"] == f["records"] + f["blank"] + f["rejected"]
    assert sum(f["records"] for f in summary["files"]) == SAMPLE.read_bytes().count(b"\n")
    kinds = {e.get("kind") for e in events if e["type"] == "source"}
    assert ("rotated" if mode == "rename" else "truncated") in kinds


def test_passages_of_status_records_only_are_counted_not_listed_unless_asked(
    tmp_path: Path, analyze_passages: list[dict[str, object]]
) -> None:
    log = tmp_path / "station.log"
    log.write_bytes(SAMPLE.read_bytes())
    out = subprocess.run(
        trackside("follow", f"file:{log}", "--from-start", "--jsonl", "--layout", "example", "--idle-exit", "0.5"),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    events = read_jsonl(out.stdout)
    listed = [{k: v for k, v in e.items() if k != "type"} for e in events if e["type"] == "passage"]
    trains = [p for p in analyze_passages if p["kind"] != "status"]
    assert listed and sorted(listed, key=str) == sorted(trains, key=str)
    assert events[-1]["status_only_passages"] == len(analyze_passages) - len(trains) > 0


def test_follow_jsonl_lines_are_flushed_one_by_one_and_rejections_are_shown(tmp_path: Path) -> None:
    log = tmp_path / "x.log"
    good = SAMPLE.read_bytes().splitlines(keepends=True)[:30]
    log.write_bytes(b"".join(good[:10]) + b"\x1b[31mnot a record\n" + b"".join(good[10:]))
    out = subprocess.run(
        trackside("follow", f"file:{log}", "--from-start", "--jsonl", "--idle-exit", "0.5", "--strict"),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert out.returncode == 1, out.stderr  # --strict: a rejected line is a finding
    events = read_jsonl(out.stdout)
    rej = [e for e in events if e.get("kind") == "rejected"]
    assert len(rej) == 1 and rej[0]["line"] == 11 and rej[0]["file"] == str(log)
    summary = events[-1]
    assert summary["files"][0]["lines_read"] == 31 and summary["files"][0]["rejected"] == 1


def test_follow_human_output_escapes_log_content() -> None:
    from console.cli.commands.follow import _line

    ev = {
        "type": "source",
        "kind": "rejected",
        "file": "a\x1b[2J.log",
        "line": 1,
        "reason": "r",
        "text": "\x1b]0;x\x07",
    }
    shown = _line(ev)
    assert "\x1b" not in shown and "\\x1b" in shown
    passage = {"type": "passage", "counting_head": "WS\u202e1", "start": "s", "end": "e", "axles": 2}
    assert "\u202e" not in _line(passage)


@pytest.mark.parametrize("polling", [False, True], ids=["inotify", "polling"])
def test_a_log_replaced_by_a_directory_or_a_fifo_is_waited_for_not_the_end_of_the_source(
    tmp_path: Path, polling: bool
) -> None:
    # A directory there stopped the source for good (IsADirectoryError); a FIFO would have blocked it in open().
    log = tmp_path / "a.log"
    log.write_bytes(b"Diag_id: first\n")
    src, got = _follow(log, from_start=True, force_polling=polling)
    try:
        assert wait_until(lambda: got.data() == b"Diag_id: first\n", 10)
        log.unlink()
        log.mkdir()
        assert wait_until(lambda: "not a file now" in src.status().detail, 10), src.status()
        log.rmdir()
        os.mkfifo(log)
        time.sleep(0.5)
        log.unlink()
        log.write_bytes(b"Diag_id: second\n")
        assert wait_until(lambda: got.data() == b"Diag_id: first\nDiag_id: second\n", 10), src.status()
        assert src.running and src.status().connected
    finally:
        src.stop()


def test_follow_of_an_impossible_source_is_a_one_line_error(tmp_path: Path) -> None:
    out = subprocess.run(trackside("follow", "mqtt://127.0.0.1:1883"), capture_output=True, text=True, timeout=30)
    assert out.returncode == 2
    assert out.stderr.startswith("trackside: error:") and "topic" in out.stderr
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_or_sigterm_end_follow_cleanly_with_a_summary(tmp_path: Path, sig: int, code: int) -> None:
    log = tmp_path / "x.log"
    log.write_bytes(b"".join(SAMPLE.read_bytes().splitlines(keepends=True)[:50]))
    proc = subprocess.Popen(
        trackside("follow", str(log), "--from-start"), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    assert "connected" in proc.stdout.readline()
    proc.send_signal(sig)
    _out, err = proc.communicate(timeout=30)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    assert "followed:" in err and "50 lines = 50 records + 0 blank + 0 rejected" in err


def test_duration_takes_what_simulate_takes_and_zero_reads_nothing_old(tmp_path: Path) -> None:
    """--duration 2s as simulate writes it; --duration 0 stops at once, and what was in the file before the
    follow began is still not read (it was all read, as if --from-start)."""
    import json

    log = tmp_path / "station.log"
    shutil.copy(REPO / "sample_logs" / "example_station.log", log)

    def summary(*args: str) -> dict:
        out = subprocess.run(
            trackside("follow", f"file:{log}", "--jsonl", *args), capture_output=True, text=True, timeout=60
        )
        assert out.returncode == 0, out.stderr
        return dict(json.loads(out.stdout.splitlines()[-1]))

    for duration in ("0", "0.5s", "0.01m"):
        assert sum(f["lines_read"] for f in summary("--duration", duration)["files"]) == 0, duration
    assert summary("--duration", "0", "--from-start")["files"][0]["lines_read"] == 3385
    bad = subprocess.run(trackside("follow", f"file:{log}", "--duration", "soon"), capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "--duration" in bad.stderr
