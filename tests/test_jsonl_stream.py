"""`analyze --jsonl`: one JSON object per line, written as found (issue 12).

Lines are ``rejected`` (as the parser meets them, the first 100 unless
``--rejected-all``), ``passage`` (as each closes), then one ``device`` per
board and a last ``summary``.  The passages are those of ``--json``; the
output reaches a pipe while the input is still being read.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from benchmarks.gen_realistic_diag import generate
from console.cli.options import REJECTIONS_LISTED
from tests.live_fixtures import trackside

TYPES = {"rejected", "passage", "device", "summary"}


def run(*args: str) -> subprocess.CompletedProcess[str]:
    out = subprocess.run(trackside(*args), capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out


def jsonl(*args: str) -> list[dict[str, Any]]:
    lines = run("analyze", "--jsonl", *args).stdout.splitlines()
    return [json.loads(line) for line in lines]


def by_type(lines: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [{k: v for k, v in d.items() if k != "type"} for d in lines if d["type"] == kind]


def passage_key(p: dict[str, Any]) -> tuple[Any, ...]:
    return (p["device_id"], p["counting_head"], p["start"], p["end"])


@pytest.fixture(scope="module")
def damaged_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    """Four boards (us, ms, s, us), a damaged line in 20: more rejections than are listed."""
    path = tmp_path_factory.mktemp("jsonl") / "damaged.log"
    truth = generate(4000, path, boards=4, seed=5, interleave_seed=9, corrupt_every=20, block_s=60)
    assert truth["corrupt_lines"] > REJECTIONS_LISTED
    return path, truth


def test_every_line_is_one_json_object_with_a_type(damaged_log: tuple[Path, dict[str, Any]]) -> None:
    path, truth = damaged_log
    lines = jsonl(str(path))
    assert {d["type"] for d in lines} == TYPES
    kinds = [d["type"] for d in lines]
    # Rejections and passages as found, then the devices, then one summary last.
    first_device = kinds.index("device")
    assert set(kinds[:first_device]) == {"rejected", "passage"}
    assert set(kinds[first_device:-1]) == {"device"}
    assert kinds[-1] == "summary" and kinds.count("summary") == 1
    assert len(by_type(lines, "device")) == len(truth["boards"])


def test_passages_and_devices_are_those_of_json(damaged_log: tuple[Path, dict[str, Any]]) -> None:
    path, _ = damaged_log
    for extra in ([], ["--include-status"]):
        lines = jsonl(str(path), *extra)
        doc = json.loads(run("analyze", "--json", str(path), *extra).stdout)
        streamed = by_type(lines, "passage")
        # The stream writes passages as they close (by time); --json by head, then time.
        assert sorted(streamed, key=passage_key) == sorted(doc["passages"], key=passage_key)
        assert len(streamed) == len(doc["passages"]) > 0
        devices = [{("type" if k == "device_type" else k): v for k, v in d.items()} for d in by_type(lines, "device")]
        assert devices == doc["devices"]
        summary = by_type(lines, "summary")[0]
        assert summary["passages"] == len(doc["passages"])
        assert summary["unpaired_detections"] == doc["unpaired_detections"]
        assert summary.get("status_passages") == doc.get("status_passages")


def test_status_passages_are_counted_unless_included(damaged_log: tuple[Path, dict[str, Any]]) -> None:
    path, _ = damaged_log
    listed = by_type(jsonl(str(path), "--include-status"), "passage")
    lines = jsonl(str(path))
    summary = by_type(lines, "summary")[0]
    status = [p for p in listed if p["kind"] == "status"]
    assert status and all(p["kind"] != "status" for p in by_type(lines, "passage"))
    assert summary["status_passages"]["passages"] == len(status)
    assert summary["passages"] + len(status) == len(listed)


def test_rejected_lines_are_capped_but_all_counted(damaged_log: tuple[Path, dict[str, Any]]) -> None:
    path, truth = damaged_log
    lines = jsonl(str(path))
    shown = by_type(lines, "rejected")
    report = by_type(lines, "summary")[0]["parse_report"]
    assert len(shown) == REJECTIONS_LISTED
    assert report["rejected"] == truth["corrupt_lines"]
    assert report["rejections_shown"] == REJECTIONS_LISTED
    numbers = [r["line"] for r in shown]
    assert numbers == sorted(numbers)
    # The same first lines as --json's parse report lists.
    doc = json.loads(run("analyze", "--json", str(path)).stdout)
    assert shown == doc["parse_report"]["rejections"]


def test_rejected_all_lists_every_rejected_line(damaged_log: tuple[Path, dict[str, Any]]) -> None:
    path, truth = damaged_log
    lines = jsonl(str(path), "--rejected-all")
    shown = by_type(lines, "rejected")
    assert len(shown) == truth["corrupt_lines"] == by_type(lines, "summary")[0]["parse_report"]["rejected"]
    assert len({r["line"] for r in shown}) == len(shown)
    assert all(r["file"] == str(path) and r["reason"] for r in shown)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs a FIFO")
def test_passages_reach_a_pipe_while_the_input_is_still_being_written(tmp_path: Path) -> None:
    """Fed through a FIFO that stays open: the process cannot have ended, yet passages arrive."""
    log = tmp_path / "big.log"
    generate(150_000, log, boards=8, seed=3, interleave_seed=1)
    data = log.read_bytes()
    # More than the reader's read-ahead (three 4 MiB chunks), cut at a line end.
    cut = data.index(b"\n", min(len(data) - 1, 16 << 20)) + 1
    assert cut < len(data)
    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    proc = subprocess.Popen(
        trackside("analyze", "--jsonl", str(fifo)), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    seen = threading.Event()

    def feed() -> None:
        with open(fifo, "wb") as writer:
            writer.write(data[:cut])
            writer.flush()
            seen.wait(timeout=120)  # the rest only once a passage was read
            writer.write(data[cut:])

    # Fed from a thread: while this one reads, the process may wait for its stdout to drain.
    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    try:
        assert proc.stdout is not None
        head: list[dict[str, Any]] = []
        deadline = time.monotonic() + 90
        while not by_type(head, "passage") and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            head.append(json.loads(line))
        assert by_type(head, "passage"), proc.stderr.read() if proc.stderr else ""
        # The input is still open: the passage was written before the end of the input.
        assert proc.poll() is None
        seen.set()
        # Not communicate(): it would skip what this reader has buffered already.
        rest = proc.stdout.read()
        err = proc.stderr.read() if proc.stderr else ""
        proc.wait(timeout=120)
    finally:
        seen.set()
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    feeder.join(timeout=10)
    assert not feeder.is_alive()
    assert proc.returncode == 0, err
    lines = head + [json.loads(line) for line in rest.splitlines()]
    assert lines[-1]["type"] == "summary"
    assert lines[-1]["passages"] == len(by_type(lines, "passage")) > 1


def test_a_log_out_of_time_order_is_read_whole_for_json_and_warned_about_for_jsonl(tmp_path: Path) -> None:
    log = tmp_path / "b.log"
    # Each half more than the four 4 MiB chunks a file read closes passages after (FILE_CLOSE_EVERY_CHUNKS).
    generate(150_000, log, boards=3, seed=1)
    lines = log.read_bytes().splitlines(keepends=True)
    swapped = tmp_path / "swapped.log"
    swapped.write_bytes(b"".join(lines[len(lines) // 2 :] + lines[: len(lines) // 2]))
    out = run("analyze", "--json", str(swapped))
    # Read whole: the passages are those of the log in order. Where the halves meet, each head's records go
    # back in time, as across a clock stepped back: that, and nothing else, is told, once per head.
    told = [w for w in out.stderr.splitlines() if not w.startswith("trackside: warning: and ")]  # past 5 heads
    junction = b"".join(lines[len(lines) // 2 :]).count(b"\n") + 1  # the first line of the half written second
    heads = [
        re.match(r"trackside: warning: (\S+): its records go back [\d,.]+ s at \S+ line ([\d,]+)", w) for w in told
    ]
    assert told and all(heads)
    assert all(int(m[2].replace(",", "")) >= junction for m in heads if m)
    assert len({m[1] for m in heads if m}) == len(told)
    from console.analysis.passages.speed_settings import SpeedSettings
    from tests.reads import stream_job

    job = stream_job([swapped], SpeedSettings(), whole=True, include_status=False)
    assert json.loads(out.stdout)["passages"] == json.loads(job.analysis.passages_json_text())
    streamed = run("analyze", "--jsonl", str(swapped))
    late = [w for w in streamed.stderr.splitlines() if "go back" not in w]
    assert len(late) == 1 and "out of time order" in late[0]
    summary = json.loads(streamed.stdout.splitlines()[-1])
    assert summary["late_records"] > 0
