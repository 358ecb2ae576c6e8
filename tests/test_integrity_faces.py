"""Train integrity where a person reads it: follow --jsonl, crossing --json and its table, the report.

One simulated run (a train parted under the ``train_parting`` fault) read by the real
``trackside`` commands, as subprocesses."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

TRACKSIDE = Path(sys.executable).with_name("trackside")


def run(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(TRACKSIDE), *args], capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def parted_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("parted") / "run"
    # Parted at 12 min, before T2 has cleared 11+850: that warning is held for the rear part.
    r = run("simulate", "-o", str(out), "--duration", "25m", "--fault", "train_parting:T2:12m")
    assert r.returncode == 0, r.stderr
    return out


def test_follow_jsonl_tells_the_integrity_changes_with_their_evidence(parted_run: Path) -> None:
    r = run(
        "follow",
        str(parted_run / "gnss_devices.csv"),
        str(parted_run / "diagnostic.log"),
        "--layout",
        str(parted_run / "layout.toml"),
        "--from-start",
        "--jsonl",
        "--idle-exit",
        "3",
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    lines = [json.loads(x) for x in r.stdout.splitlines()]
    integrity = [x for x in lines if x["type"] == "integrity"]
    t2 = [x for x in integrity if x["train"] == "T2"]
    assert [x["state"] for x in t2][-1] == "parted"
    parted = t2[-1]
    assert parted["witnesses"] and parted["evidence"] and parted["rear_m"] is not None
    assert parted["time"].startswith("2026-03-02T08:12:")  # the data's clock, not the wall clock
    assert all(x["state"] == "whole" for x in integrity if x["train"] == "T1")
    assert lines[-1]["type"] == "summary" and lines[-1]["integrity_events"] == len(integrity)
    # A parted train's crossing warnings are held for its rear part.
    assert any(x["type"] == "crossing" and x["reason"].startswith("train parted") for x in lines)


def test_crossing_shows_the_integrity_timeline_per_train(parted_run: Path) -> None:
    r = run("crossing", str(parted_run / "gnss_devices.csv"), "--layout", "example", "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    by_train = {t["train"]: t for t in doc["integrity"]}
    assert by_train["T2"]["state"] == "parted" and by_train["T1"]["state"] == "whole"
    changes = by_train["T2"]["changes"]
    assert changes[0]["state"] == "whole" and changes[-1]["previous"] in ("whole", "doubtful")
    assert changes[-1]["evidence"] and changes[-1]["witnesses"] == ["gnss"]
    table = run("crossing", str(parted_run / "gnss_devices.csv"), "--layout", "example")
    assert table.returncode == 0 and "Train integrity" in table.stdout and "parted" in table.stdout


def test_the_report_puts_a_parted_train_first_and_its_timeline_in_the_crossings_part(parted_run: Path) -> None:
    r = run("report", str(parted_run), "--format", "json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    unsafe = [i for i in doc["safety"]["items"] if i["topic"] == "integrity"]
    assert unsafe and unsafe[0]["class"] == "unsafe" and unsafe[0]["subject"] == "train T2"
    assert doc["verdict"] == "unsafe"
    tl = {t["train"]: t for t in doc["crossings"]["integrity"]}
    assert tl["T2"]["state"] == "parted"
    md = run("report", str(parted_run))
    assert "### Train integrity" in md.stdout and "| T2 |" in md.stdout
