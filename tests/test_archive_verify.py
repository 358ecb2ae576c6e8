"""`trackside verify`: an archive checked against its manifest; an ingest refuses to build on a missing part.

Archives are made by real ingests of the shipped samples (every kind the archive stores), grown and rewritten
the way logs are; the damage is done the way disks and hands do it: a part deleted, cut short, replaced by a
folder, decoded wrong in the middle, or rewritten with rows lost or stored twice.
"""

from __future__ import annotations

import gzip
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from console.archive.query import run_query
from console.archive.store import read_current
from console.archive.tables import TABLES
from console.cli.app import app
from tests.conftest import SAMPLES

runner = CliRunner()
TRACKSIDE = str(Path(sys.executable).parent / "trackside")


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The samples ingested with a layout, then a log grown by lines (one of them junk) and ingested again."""
    root = tmp_path_factory.mktemp("verify")
    logs = root / "logs"
    shutil.copytree(SAMPLES, logs, ignore=shutil.ignore_patterns("*.py", "*.md"))
    station = logs / "example_station.log"
    lines = station.read_text("utf-8").splitlines(keepends=True)
    station.write_text("".join(lines[:2000]), "utf-8")
    arc = root / "arc"
    for _ in range(2):
        res = runner.invoke(app, ["ingest", str(logs), "--archive", str(arc), "--layout", "example"])
        assert res.exit_code == 0, res.output
        with station.open("a", encoding="utf-8") as f:
            f.writelines(lines[2000:3000])
            f.write("this line is no record\n")
    return arc


def test_an_ingest_that_adds_nothing_leaves_no_file_behind(tmp_path: Path) -> None:
    """docs/archive.md's second ingest ("already ingested", archive unchanged) left its ledger part under
    data/ingests/, named by no manifest: verify then said "1 file under data/ no manifest names" of a clean
    archive, as of one a killed ingest left."""
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(SAMPLES / "osong_ws4_0932_detection.log", logs)
    arc = tmp_path / "arc"
    for _ in range(2):
        res = runner.invoke(app, ["ingest", str(logs), "--archive", str(arc)])
        assert res.exit_code == 0, res.output
    assert "archive unchanged" in res.output
    code, doc = _verify(arc)
    assert code == 0 and doc["unlisted_files"] == 0, doc


def _copy(made: Path, tmp_path: Path) -> Path:
    arc = tmp_path / "arc"
    shutil.copytree(made, arc)
    return arc


def _verify(arc: Path, *args: str) -> tuple[int, dict]:
    res = runner.invoke(app, ["verify", "--archive", str(arc), "--json", *args])
    return res.exit_code, json.loads(res.stdout)


def _part(arc: Path, table: str, index: int = 0) -> str:
    return sorted(read_current(arc).parts(table))[index]


def test_an_ingested_archive_is_intact_and_its_rows_are_what_a_query_counts(made: Path) -> None:
    code, doc = _verify(made, "--deep")
    assert code == 0 and doc["intact"] and doc["schema"] == "trackside.verify/1"
    assert doc["damaged"] == [] and doc["mismatches"] == [] and doc["unlisted_files"] == 0
    m = read_current(made)
    assert doc["files_checked"] == len(m.files) >= 16
    assert set(doc["tables"]) == {t for t, parts in m.tables.items() if parts}
    for table, figures in doc["tables"].items():
        if table not in TABLES:  # the archive's own (the pipeline's state, channel events): no view
            continue
        _names, rows = run_query(made, f"SELECT count(*) FROM {table}")
        assert figures["rows"] == rows[0][0], table
        assert figures["parts"] == len(m.parts(table))
    # The grown log's lines are in (its junk line among the rejected): what the ledger says, stored.
    assert doc["tables"]["records"]["rows"] == sum(int(e["records"]) for e in m.files if e["kind"] == "diagnostic")
    assert doc["tables"]["rejected"]["rows"] == sum(int(e["rejected"]) for e in m.files) >= 1


def test_a_compressed_log_read_again_leaves_the_archive_intact(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    log = tmp_path / "station.log.gz"
    text = (SAMPLES / "example_station.log").read_bytes().splitlines(keepends=True)
    # A compressed log that changed is read again whole: its old entry goes out of use, and its records with it.
    log.write_bytes(gzip.compress(b"".join(text[:300])))
    assert runner.invoke(app, ["ingest", str(log), "--archive", str(arc)]).exit_code == 0
    log.write_bytes(gzip.compress(b"".join(text[:450])))
    res = runner.invoke(app, ["ingest", str(log), "--archive", str(arc)])
    assert res.exit_code == 0 and "read again whole" in res.output
    assert any(not e.get("active", True) for e in read_current(arc).files)
    code, doc = _verify(arc)
    assert code == 0 and doc["intact"], doc


def test_missing_cut_and_foldered_parts_are_each_named_and_exit_1(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    gone, cut, folder = _part(arc, "passages"), _part(arc, "records"), _part(arc, "fixes")
    (arc / gone).unlink()
    data = (arc / cut).read_bytes()
    (arc / cut).write_bytes(data[: len(data) // 2])  # a copy cut short: no footer
    (arc / folder).unlink()
    (arc / folder).mkdir()
    code, doc = _verify(arc)
    assert code == 1 and not doc["intact"]
    problems = {d["part"]: d["problem"] for d in doc["damaged"]}
    assert problems[gone] == "missing"
    assert problems[cut].startswith("cannot be read (")
    assert problems[folder] == "not a regular file"
    assert len(problems) == 3
    # The text says the same, one line a part, and what to do.
    out = subprocess.run([TRACKSIDE, "verify", "--archive", str(arc)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1 and "Traceback" not in out.stderr
    assert f"damaged  passages: {gone}: missing" in out.stdout
    assert "DAMAGED: 3 parts missing or unreadable; ingest the logs again into a new archive" in out.stdout


def test_rows_lost_or_stored_twice_show_as_counts_the_ledger_does_not_hold(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    m = read_current(arc)
    # A records part holding rows twice (as a run that spooled a log twice once did), and a fixes part short of
    # its last row: every part still reads.
    twice = _part(arc, "records")
    table = pq.read_table(arc / twice)
    pq.write_table(pa.concat_tables([table, table]), arc / twice)
    entry = next(e for e in m.files if e["kind"] != "diagnostic" and e["parts"] and "fixes" in e["parts"][0])
    short = entry["parts"][0]
    fixes = pq.read_table(arc / short)
    pq.write_table(fixes.slice(0, fixes.num_rows - 1), arc / short)
    code, doc = _verify(arc)
    assert code == 1 and doc["damaged"] == []
    got = {(d["file"], d["table"]): (d["ledger"], d["stored"]) for d in doc["mismatches"]}
    assert got[(entry["path"], "fixes")] == (int(entry["records"]), int(entry["records"]) - 1)
    seqs = table.column("file_seq").to_pylist()
    for e in m.files:
        if e["kind"] == "diagnostic" and int(e["file_seq"]) in seqs:
            extra = seqs.count(int(e["file_seq"]))
            assert got[(e["path"], "records")] == (int(e["records"]), int(e["records"]) + extra)
    assert len(got) == 1 + len({s for s in seqs})


def test_a_part_damaged_inside_is_found_by_deep_only(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    rel = _part(arc, "records")
    data = bytearray((arc / rel).read_bytes())
    for i in range(100, 500):  # inside the first columns' compressed pages; the footer reads
        data[i] ^= 0x5A
    (arc / rel).write_bytes(bytes(data))
    assert _verify(arc)[0] == 0  # the footer and the file_seq column read
    code, doc = _verify(arc, "--deep")
    assert code == 1 and [d["part"] for d in doc["damaged"]] == [rel]


def test_ingest_refuses_to_build_on_a_missing_part_and_leaves_the_archive_as_it_was(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    gone = _part(arc, "axles")
    (arc / gone).unlink()
    before = (arc / "CURRENT").read_text()
    new = tmp_path / "new.log"
    shutil.copy(SAMPLES / "ws4_subsecond.log", new)
    out = subprocess.run(
        [TRACKSIDE, "ingest", str(new), "--archive", str(arc)], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert out.stderr.strip().splitlines() == [
        f"trackside: error: {arc}: the archive is damaged: {gone} is missing or not a file"
        " (`trackside verify` lists what is damaged); nothing ingested"
    ]
    assert (arc / "CURRENT").read_text() == before


def test_leftovers_of_a_killed_ingest_are_counted_not_damage(made: Path, tmp_path: Path) -> None:
    arc = _copy(made, tmp_path)
    stray = arc / "data" / "records" / "g999999-r.parquet"
    shutil.copy(arc / _part(arc, "records"), stray)
    code, doc = _verify(arc)
    assert code == 0 and doc["unlisted_files"] == 1


def test_no_archive_is_one_line_and_exit_2(tmp_path: Path) -> None:
    res = runner.invoke(app, ["verify", "--archive", str(tmp_path / "none")])
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        f"trackside: error: {tmp_path / 'none'}: no archive here yet (run `trackside ingest FILES --archive"
        f" {tmp_path / 'none'}`)"
    ]
    assert not (tmp_path / "none").exists()


@pytest.mark.parametrize("command", [["verify"], ["query", "--schema"], ["forecast"], ["report", "--format", "json"]])
def test_an_archive_given_as_a_file_is_said_of_the_path_given(tmp_path: Path, command: list[str]) -> None:
    not_a_folder = tmp_path / "arc.parquet"
    not_a_folder.write_bytes(b"PAR1")
    res = runner.invoke(app, [*command, "--archive", str(not_a_folder)])
    assert res.exit_code == 2
    assert res.output.strip().splitlines() == [
        f"trackside: error: {not_a_folder}: not a directory (an archive is a folder)"
    ]


def test_nmea_fixes_are_counted_against_the_rows_written_not_the_sentences(tmp_path: Path) -> None:
    """An NMEA file's ledger counts sentences (RMC and GGA: two an epoch) and its part holds fixes (one an epoch):
    checked against the rows its parts were written with; an archive made before that figure, at most one row a
    sentence."""
    run = tmp_path / "run"
    res = runner.invoke(app, ["simulate", "-o", str(run), "--duration", "10m", "--seed", "4"])
    assert res.exit_code == 0, res.output
    arc = tmp_path / "arc"
    assert runner.invoke(app, ["ingest", str(run), "--archive", str(arc)]).exit_code == 0
    m = read_current(arc)
    nmea = [e for e in m.files if e["kind"] == "nmea"]
    assert nmea and all(0 < int(e["rows"]) < int(e["records"]) for e in nmea)
    code, out = _verify(arc)
    assert code == 0 and out["intact"], out
    # As an older trackside wrote the ledger (no rows): still intact.
    current = arc / "manifests" / (arc / "CURRENT").read_text().strip()
    doc = json.loads(current.read_text())
    for e in doc["files"]:
        e.pop("rows", None)
    current.write_text(json.dumps(doc))
    code, out = _verify(arc)
    assert code == 0 and out["intact"], out
    # A fixes part holding its rows three times is more rows than sentences (twice would be as many): found,
    # even without the figure.
    part = nmea[0]["parts"][0]
    fixes = pq.read_table(arc / part)
    pq.write_table(pa.concat_tables([fixes] * 3), arc / part)
    code, out = _verify(arc)
    assert code == 1 and [m["file"] for m in out["mismatches"]] == [nmea[0]["path"]]


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (lambda doc: {**doc, "generation": "x"}, "damaged manifest (ValueError"),
        (lambda doc: {**doc, "tables": []}, "damaged manifest (AttributeError"),
        (lambda doc: {**doc, "tables": {"records": [1, 2]}}, "damaged manifest (TypeError: a part's name"),
        (lambda doc: {**doc, "files": ["x"]}, "damaged manifest (TypeError: a file's entry"),
        (lambda doc: [doc], "not a trackside archive manifest"),
        (None, "names no manifest"),  # CURRENT emptied
        ("cut", "unreadable manifest"),  # the manifest cut short on disk
        ("gone", "unreadable manifest"),  # the manifest CURRENT names deleted
    ],
)
def test_a_manifest_edited_by_hand_is_one_line_never_an_internal_error(made: Path, tmp_path: Path, edit, said) -> None:
    # Found by review47: "generation": "x" gave "internal error: ValueError", an empty CURRENT an unclear line.
    arc = tmp_path / "arc"
    shutil.copytree(made, arc)
    current = arc / "CURRENT"
    manifest = arc / "manifests" / current.read_text("utf-8").strip()
    if edit is None:
        current.write_text("", "utf-8")
    elif edit == "cut":
        manifest.write_bytes(manifest.read_bytes()[:100])
    elif edit == "gone":
        manifest.unlink()
    else:
        manifest.write_text(json.dumps(edit(json.loads(manifest.read_text("utf-8")))), "utf-8")
    # verify finds damage (exit 1, as its help and docs/archive.md say); the others cannot read the archive (2).
    for command, code in (
        (["verify"], 1),
        (["verify", "--json"], 1),
        (["query", "SELECT 1"], 2),
        (["report", "--format", "json", "-o", str(tmp_path / "r.json")], 2),
    ):
        p = subprocess.run([TRACKSIDE, *command, "--archive", str(arc)], capture_output=True, text=True, timeout=120)
        assert p.returncode == code, (command, p.stderr)
        assert said in p.stderr and "internal error" not in p.stderr, (command, p.stderr)
        assert len(p.stderr.strip().splitlines()) == 1, (command, p.stderr)
