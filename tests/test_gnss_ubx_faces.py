"""Binary GNSS input works the same in every command that reads GNSS: gnss, crossing, report, the archive, follow.

The sample crossing run (sample_logs/crossing_example.csv, two trains over
two crossings) is written as what u-blox and Septentrio receivers log, one
file per unit, each in another dialect (tests/ubx_fixtures.py): A-head as
NAV-PVT with its companions, A-eot as NAV-SOL + NAV-TIMEGPS (ECEF, GPS
time), B-head as NAV-POSLLH + NAV-VELNED + NAV-STATUS + NAV-TIMEUTC, B-eot
as SBF PVTGeodetic + ReceiverTime, with RTCM3 corrections and junk between
epochs.  Every command must give what it gives for the CSV.
"""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from console.cli.app import app
from parsers.gnss.packets import rtcm3_packet
from parsers.gnss_files import parse_gnss
from tests import ubx_fixtures as ubx
from tests.live_fixtures import trackside

runner = CliRunner()
DIALECT = {"A-head": "pvt", "A-eot": "sol", "B-head": "llh", "B-eot": "sbf"}
# What a timeline must repeat (t_head_arrival and t_tail_clear are interpolated between fixes: NAV-SOL's
# centimetre ECEF moves them by a fraction of a millisecond).
TIMELINE_KEYS = ("crossing", "train", "t_on", "t_off", "reason_on", "reason_off", "violations", "alarms")


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[Path], pd.DataFrame]:
    csv = Path(__file__).resolve().parents[1] / "sample_logs" / "crossing_example.csv"
    fixes, _, _ = parse_gnss([csv])
    out = tmp_path_factory.mktemp("ubx_run")
    between = rtcm3_packet(bytes([0x3E, 0xD0]) + bytes(17)) + b"\x8f\xfe junk \xb5"
    files = []
    for device, dialect in DIALECT.items():
        path = out / f"{device}.ubx"
        path.write_bytes(ubx.write_fixes(fixes[fixes["device"] == device], dialect, between=between))
        files.append(path)
    return csv, files, fixes


def _json(*args: str) -> dict:
    res = runner.invoke(app, list(args))
    assert res.exit_code == 0, res.output
    return json.loads(res.stdout)


def _timelines(doc: dict) -> list[list[object]]:
    return [[t[k] for k in TIMELINE_KEYS] for t in doc["timelines"]]


def test_gnss_gives_the_csvs_fixes(run: tuple[Path, list[Path], pd.DataFrame]) -> None:
    _, files, fixes = run
    proc = subprocess.run(trackside("gnss", "--json", *map(str, files)), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    got = pd.DataFrame(doc["fixes"])
    assert doc["parse_report"]["rejected"] == 0 and doc["parse_report"]["skipped"]["RTCM3 packets"] == len(fixes)
    for device, dialect in DIALECT.items():
        ours = got[got["device"] == device].reset_index(drop=True)
        truth = fixes[fixes["device"] == device].reset_index(drop=True)
        assert len(ours) == len(truth) and ours["valid"].all()
        assert (pd.to_datetime(ours["time"]).to_numpy() == truth["time"].to_numpy()).all(), device
        assert (ours["lat"] - truth["lat"]).abs().max() <= 1e-6 and (ours["lon"] - truth["lon"]).abs().max() <= 1e-6
        assert (ours["speed_mps"] - truth["speed_mps"]).abs().max() <= 0.01, device
        assert (
            set(ours["sentence"])
            == {
                "pvt": {"NAV-PVT+NAV-POSECEF+NAV-VELECEF+NAV-TIMEGPS"},
                "sol": {"NAV-SOL+NAV-TIMEGPS"},
                "llh": {"NAV-POSLLH+NAV-VELNED+NAV-STATUS+NAV-TIMEUTC"},
                "sbf": {"PVTGeodetic+ReceiverTime"},
            }[dialect]
        )


def test_crossing_gives_the_csvs_warnings(run: tuple[Path, list[Path], pd.DataFrame]) -> None:
    csv, files, _ = run
    want = _json("crossing", str(csv), "--layout", "example", "--json")
    got = _json("crossing", *map(str, files), "--layout", "example", "--json")
    assert got["events"] == want["events"] and len(got["events"]) == 12  # 4 on, 4 off, 4 stale alarms
    assert _timelines(got) == _timelines(want) and got["violations"] == 0


def test_report_gives_the_csvs_crossings(run: tuple[Path, list[Path], pd.DataFrame]) -> None:
    csv, files, _ = run
    want = _json("report", str(csv), "--layout", "example", "--format", "json")
    got = _json("report", *map(str, files), "--layout", "example", "--format", "json")
    assert _timelines(got["crossings"]) == _timelines(want["crossings"])
    assert {f["format"] for f in got["inputs"]["files"]} == {"nmea"}  # read as receiver streams
    assert {u["device"]: u["fixes"] for u in got["gnss_units"]} == {u["device"]: u["fixes"] for u in want["gnss_units"]}


def test_the_archive_stores_and_reports_them_as_it_does_the_csv(
    run: tuple[Path, list[Path], pd.DataFrame], tmp_path: Path
) -> None:
    csv, files, fixes = run
    station = csv.with_name("example_station.log")  # a report from the archive needs detection records too
    docs = []
    for name, inputs in (("csv", [csv]), ("ubx", files)):
        arc = tmp_path / name
        res = runner.invoke(app, ["ingest", str(station), *map(str, inputs), "--archive", str(arc)])
        assert res.exit_code == 0, res.output
        docs.append(_json("report", "--archive", str(arc), "--layout", "example", "--format", "json"))
    assert _timelines(docs[1]["crossings"]) == _timelines(docs[0]["crossings"]) and docs[1]["crossings"]["timelines"]
    sql = "SELECT device, count(*) AS n, min(sentence) AS s FROM fixes GROUP BY device ORDER BY device"
    res = runner.invoke(app, ["query", "--archive", str(tmp_path / "ubx"), sql, "--format", "json"])
    assert res.exit_code == 0, res.output
    stored = {r["device"]: (r["n"], r["s"]) for r in json.loads(res.stdout)}
    assert stored["A-eot"] == (int((fixes["device"] == "A-eot").sum()), "NAV-SOL+NAV-TIMEGPS")
    assert stored["B-eot"] == (int((fixes["device"] == "B-eot").sum()), "PVTGeodetic+ReceiverTime")


@pytest.mark.timeout(180)
def test_follow_reads_every_fix_of_the_binary_files(run: tuple[Path, list[Path], pd.DataFrame]) -> None:
    """Followed from their start, the files give every fix the batch reader gives.  (Which warnings a live
    run shows depends on the order the four files are read in: a head's fixes before its EOT's hold the
    warning on, as they must; so only that the crossings are warned of is checked here.)"""
    _, files, fixes = run
    args = ("follow", *map(str, files), "--layout", "example", "--jsonl", "--from-start")
    follow = subprocess.Popen(trackside(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    ready = threading.Event()

    def read() -> None:
        assert follow.stdout is not None
        for line in follow.stdout:
            lines.append(line)
            events = [json.loads(x) for x in lines]
            if sum(e["type"] == "source" and e["kind"] == "info" for e in events) == len(files):
                ready.set()  # every file recognised, and read from its start

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert ready.wait(120), "".join(lines[-5:])
        time.sleep(3.0)  # small files: read at once
        follow.send_signal(signal.SIGINT)
        follow.wait(60)
        reader.join(30)
    finally:
        if follow.poll() is None:
            follow.kill()
            follow.wait(10)
    # Ctrl-C: the summary, then 130 (as every command interrupted).
    assert follow.returncode == 130, follow.stderr.read() if follow.stderr else ""
    events = [json.loads(x) for x in lines]
    summary = events[-1]
    assert summary["gnss_fixes"] == len(fixes)
    batch = parse_gnss(files)[1]
    assert [(f["lines_read"], f["rejected"]) for f in summary["files"]] == [
        (f.lines_read, f.rejected) for f in batch.files
    ]
    assert any(e["type"] == "crossing" and e["kind"] == "on" for e in events)
