"""station --replay runs the one live engine: played to the end, it gives what ``follow`` gives for the same files.

The replay feeds the engine the files' parsed records and fixes as its clock passes their times (several
files interleaved by time), so how the time is stepped, and jumps back, change nothing; and where ``follow``
of several files reads each as its own stream, the replay's time order matches the batch reading.
"""

from __future__ import annotations

import json
import random
import subprocess
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from console.layout import load_layout
from console.sim.faults import Fault
from console.sim.line_values import SimConfig
from console.sim.station import StationSim
from console.sim.writers import write_run
from console.tui.replay_source import ReplaySource

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
TRACKSIDE = str(Path(sys.executable).with_name("trackside"))


def _key(e: dict[str, Any]) -> tuple[Any, ...] | None:
    t = e.get("type")
    if t == "section":
        return (t, e["time_ns"], e["section"], e["state"], e["count"], e["reason"])
    if t == "crossing":
        return (t, e["time_ns"], e["crossing"], e["train"], e["kind"], e["reason"])
    if t == "passage":
        return (t, e["counting_head"], e["start"], e["end"], e["axles"], e.get("direction"))
    if t == "integrity":
        return (t, e["time_ns"], e["train"], e["state"])
    return None


def _played(source: ReplaySource, steps_s: list[float] | None = None) -> Counter[tuple[Any, ...]]:
    events: list[dict[str, Any]] = []
    source.sink = events.append
    k = 0
    while source.now_ns < source.end_ns:
        source.advance(steps_s[k % len(steps_s)] if steps_s else 60.0)
        k += 1
    return Counter(k for k in map(_key, events) if k is not None)


def _followed(layout: str, files: list[Path]) -> Counter[tuple[Any, ...]]:
    argv = [TRACKSIDE, "follow", *map(str, files), "--from-start", "--layout", layout, "--jsonl", "--idle-exit", "2"]
    out = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=True)
    events = [json.loads(line) for line in out.stdout.splitlines() if line.strip()]
    return Counter(k for k in map(_key, events) if k is not None)


@pytest.fixture(scope="module")
def simulated_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A simulated half hour with a dead channel and a parted train, as ``simulate`` writes it."""
    cfg = SimConfig(
        seed=7,
        trains_per_hour=12,
        first_train_s=30,
        faults=(Fault("dead_channel", "WS3", 300.0, 1800.0), Fault("train_parting", "T2", 840.0)),
    )
    sim = StationSim(load_layout("example"), cfg)
    sim.run(1800.0)
    out = tmp_path_factory.mktemp("sim") / "run"
    write_run(sim, out)
    return out


def test_the_replay_gives_what_follow_gives_for_the_samples() -> None:
    files = [SAMPLES / "example_station.log", SAMPLES / "crossing_example.csv"]
    played = _played(ReplaySource(files, load_layout("example")))
    assert {k[0] for k in played} >= {"passage", "section", "crossing", "integrity"}
    assert played == _followed("example", files)


def test_the_replay_gives_what_follow_gives_for_a_simulated_run(simulated_run: Path) -> None:
    files = [simulated_run / "diagnostic.log", simulated_run / "gnss_devices.csv"]
    layout = str(simulated_run / "layout.toml")
    played = _played(ReplaySource(files, load_layout(layout)))
    assert {k[0] for k in played} >= {"passage", "section", "crossing"}
    assert played == _followed(layout, files)


@pytest.mark.parametrize("seed", range(3))
def test_how_the_clock_is_stepped_changes_nothing(simulated_run: Path, seed: int) -> None:
    files = [simulated_run / "diagnostic.log", simulated_run / "gnss_devices.csv"]
    lay = load_layout(str(simulated_run / "layout.toml"))
    want = _played(ReplaySource(files, lay))
    rng = random.Random(seed)
    steps = [rng.choice((0.1, 0.5, 1.0, 7.0, 45.0, 300.0, 1200.0)) for _ in range(50)]
    assert _played(ReplaySource(files, lay), steps) == want
    # A jump back replays quietly from the start: played on from there, what a replay that never jumped gives.
    jumped = ReplaySource(files, lay)
    jumped.advance(900, skip_quiet=False)
    jumped.jump(-600)
    assert jumped.now_ns == jumped.start_ns + 300 * 1_000_000_000
    straight = ReplaySource(files, lay)
    straight.advance(300, skip_quiet=False)
    assert _played(jumped) == _played(straight)


def test_several_files_are_interleaved_by_time_as_batch_reads_them() -> None:
    """Two logs of one head: ``follow`` reads each as its own stream (a passage spanning both is split there);
    the replay plays their records in time order, as ``analyze`` of both files does."""
    files = [SAMPLES / "ws4_health.log", SAMPLES / "ws4_subsecond.log"]
    played = _played(ReplaySource(files, load_layout("example")))
    out = subprocess.run([TRACKSIDE, "analyze", *map(str, files), "--json"], capture_output=True, text=True, check=True)
    batch = json.loads(out.stdout)["passages"]
    want = sorted((p["counting_head"], p["start"], p["axles"]) for p in batch)
    got = sorted((k[1], k[2], k[4]) for k in played.elements() if k[0] == "passage")
    assert got == want
