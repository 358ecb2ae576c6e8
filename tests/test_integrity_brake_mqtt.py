"""A parting seen by the brake pipe, end to end: `simulate --live --mqtt` publishes the units'
LoRa uplinks (payload version 2: the brake-pipe pressure, the EOT unit's emergency status) to a
real mosquitto, and `follow --jsonl` tells the integrity change with its evidence."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.live_fixtures import Mosquitto, follow_a_live_simulation, mosquitto, read_jsonl  # noqa: F401

pytestmark = pytest.mark.timeout(120)


def test_follow_over_mqtt_tells_a_brake_pipe_parting_with_its_evidence(tmp_path: Path, mosquitto: Mosquitto) -> None:  # noqa: F811
    run = tmp_path / "run"
    said, out, _sim = follow_a_live_simulation(
        [
            f"{mosquitto.url}/application/+/device/+/event/up",
            "--layout",
            "example",
            "--jsonl",
            "--idle-exit",
            "10",  # as test_live_sim's: a simulator starved of CPU may pause seconds between uplinks
            "--include-status",
        ],
        1,
        lambda said: '"connected"' in said[0],
        [
            *["-o", str(run), "--layout", "example", "--live", "--speed", "150", "--duration", "8m"],
            *["--fault", "train_parting:T1:3m", "--mqtt", mosquitto.url, "--json"],
        ],
    )
    (parting,) = json.loads((run / "truth.json").read_text())["partings"]
    events = read_jsonl("".join(said) + out)
    integrity = [e for e in events if e["type"] == "integrity"]
    # The payload says the train by its number: T1 is train 1.
    parted = [e for e in integrity if e["train"] == "1" and e["state"] == "parted"]
    assert len(parted) == 1, integrity
    p = parted[0]
    assert p["witnesses"] == ["brake_pipe"]
    assert "rear brake pipe vented (emergency status" in p["evidence"][0]
    assert "front stayed charged" in p["evidence"][0]
    assert p["time"] > parting["time"]  # the units' clock: the simulated day
    # No other train is seen parted, and the summary counts every integrity line.
    assert all(e["state"] != "parted" for e in integrity if e["train"] != "1")
    assert events[-1]["type"] == "summary" and events[-1]["integrity_events"] == len(integrity)
