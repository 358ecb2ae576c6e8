"""Incremental ingests: a later ingest resumes from the pipeline state the last one saved and never reads
the archived records again, and the archive still equals ``analyze`` (and the report) of all the files
read together.

Simulated logs run over midnight (the example layout's heads, trains every ~90 s).
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import pandas as pd
import pytest

from console.archive import group_run, reader
from console.archive.history import cross_head_tables, report_data
from console.archive.ingest import run_ingest
from console.archive.query import run_query
from console.archive.store import read_current
from parsers.units import NS
from tests.reads import whole_job
from tests.test_archive_derive import MIDNIGHT_S, simulate_over_midnight

# A WS4 passage runs from 23:59:58.99 to 00:00:01.7 with these settings (asserted below, not assumed).
SEED = 7
BEFORE_S = 301
PASSAGE_COLUMNS = ["device_id", "counting_head", "start_ns", "end_ns", "records", "axles", "kind"]
AXLE_COLUMNS = ["device_id", "counting_head", "time_ns", "direction"]


def _split_at(log: Path, day: str) -> tuple[bytes, bytes]:
    """The log's lines before the first line dated ``day`` (or later), and the rest."""
    lines = log.read_bytes().splitlines(keepends=True)
    at = [line.index(b"Date:") + 5 for line in lines]
    cut = next(i for i, (line, a) in enumerate(zip(lines, at, strict=True)) if line[a : a + 10] >= day.encode())
    return b"".join(lines[:cut]), b"".join(lines[cut:])


def _stored(root: Path, table: str, columns: list[str]) -> pd.DataFrame:
    names, rows = run_query(root, f"SELECT {', '.join(columns)} FROM {table}")
    return pd.DataFrame(rows, columns=names).sort_values(columns[:3], kind="stable").reset_index(drop=True)


def _assert_equals_analyze(root: Path, logs: list[Path]) -> None:
    """Stored passages and axles == analyze's on the files; stored cross-head tables == the report's, whose
    diagnostic part reads every archived record again through the pipeline."""
    job = whole_job(logs)
    heads = job.analysis.heads
    want_p = job.analysis.passages[PASSAGE_COLUMNS].sort_values(PASSAGE_COLUMNS[:3], kind="stable")
    ax = job.analysis.axles
    ax = ax.assign(device_id=[heads[h][0] for h in ax["head"]], counting_head=[heads[h][1] for h in ax["head"]])
    want_a = ax[AXLE_COLUMNS].sort_values(AXLE_COLUMNS[:3], kind="stable")
    got_p, got_a = _stored(root, "passages", PASSAGE_COLUMNS), _stored(root, "axles", AXLE_COLUMNS)
    pd.testing.assert_frame_equal(got_p, want_p.reset_index(drop=True), check_dtype=False, obj="passages")
    pd.testing.assert_frame_equal(got_a, want_a.reset_index(drop=True), check_dtype=False, obj="axles")
    want = cross_head_tables(report_data(root, job="read"))
    m = read_current(root)
    for table, by in (
        ("section_states", ["time_ns", "section", "state"]),
        ("count_ledger", ["time_ns", "section", "head"]),
        ("health_findings", ["rule", "counting_head", "channel", "message"]),
    ):
        if table not in want:
            assert not m.parts(table), table
            continue
        names, rows = run_query(root, f"SELECT * FROM {table}")
        got = pd.DataFrame(rows, columns=names).drop(columns=["day", "seq"], errors="ignore")
        w = want[table][list(got.columns)].sort_values(by, kind="stable").reset_index(drop=True)
        g = got.sort_values(by, kind="stable").reset_index(drop=True)
        pd.testing.assert_frame_equal(g, w, check_dtype=False, obj=table)


@pytest.fixture
def no_record_reads(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the reads of archived records (a resumed ingest makes none)."""
    reads: list[int] = []
    real = reader.record_batches

    def counted(*args: object, **kwargs: object) -> object:
        reads.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    # Where it is defined (the archive's own reads) and where a group's run took it.
    monkeypatch.setattr(reader, "record_batches", counted)
    monkeypatch.setattr(group_run, "record_batches", counted)
    return reads


def test_a_later_day_resumes_from_the_saved_state_without_reading_records(
    tmp_path: Path, no_record_reads: list[int]
) -> None:
    log = tmp_path / "nights.log"
    simulate_over_midnight(log, SEED, 900, minutes=20, days=3)  # records on 03-02 .. 03-05
    early, late = _split_at(log, "2026-03-04")
    first, second = tmp_path / "a.log", tmp_path / "b.log"
    first.write_bytes(early)
    second.write_bytes(late)
    root = tmp_path / "arc"
    run_ingest([first], root, layout="example")
    state1 = read_current(root).derived["states"]
    run_ingest([second], root)
    m = read_current(root)
    assert m.derived["states"] != state1 and not no_record_reads  # resumed: no archived record read back
    _assert_equals_analyze(root, [first, second])
    # A third ingest adding nothing publishes nothing.
    run_ingest([first, second], root)
    assert read_current(root).generation == m.generation


def test_a_passage_over_midnight_split_across_two_ingests_is_one_passage(tmp_path: Path) -> None:
    log = tmp_path / "whole.log"
    simulate_over_midnight(log, SEED, BEFORE_S, minutes=6)
    midnight = MIDNIGHT_S * NS
    whole = whole_job([log]).analysis.passages
    crossing = whole[(whole["start_ns"] < midnight) & (whole["end_ns"] > midnight)]
    assert len(crossing) == 1  # the premise: one passage runs over midnight
    head = crossing["counting_head"].iloc[0]

    before, after = _split_at(log, "2026-03-03")
    assert before and after
    growing = tmp_path / "growing.log"
    root = tmp_path / "arc"
    growing.write_bytes(before)
    run_ingest([growing], root, layout="example")
    with growing.open("ab") as f:
        f.write(after)
    run_ingest([growing], root)

    _assert_equals_analyze(root, [log])
    _, rows = run_query(
        root,
        f"SELECT device_id, day, start_ns, end_ns, axles FROM passages WHERE counting_head = '{head}' "
        f"AND start_ns < {midnight} AND end_ns > {midnight}",
    )
    assert len(rows) == 1  # one passage over midnight, not one per side of it (nor per ingest)
    _device_id, day, start_ns, end_ns, axles = rows[0]
    assert axles == int(crossing["axles"].iloc[0]) > 0
    assert day == dt.date(2026, 3, 2)  # stored with the day it starts
    assert (start_ns, end_ns) == (int(crossing["start_ns"].iloc[0]), int(crossing["end_ns"].iloc[0]))


def test_a_rotated_file_adds_its_new_content_to_the_days_already_derived(
    tmp_path: Path, no_record_reads: list[int]
) -> None:
    """A log rotated in place (its first bytes changed) is a new file: its records continue the history
    (resumed, no record read back), and the archive equals ``analyze`` of both files."""
    log = tmp_path / "unit.log"
    old = tmp_path / "unit.log.1"
    root = tmp_path / "arc"
    simulate_over_midnight(log, SEED, BEFORE_S, minutes=6, days=3)  # 03-02 .. 03-05 00:0x
    log.write_bytes(_split_at(log, "2026-03-05")[0])  # up to 03-04 24:00
    run_ingest([log], root, layout="example")
    old.write_bytes(log.read_bytes())
    later = tmp_path / "later.log"
    simulate_over_midnight(later, SEED + 1, BEFORE_S, minutes=6, days=4)
    log.write_bytes(_split_at(later, "2026-03-05")[1])  # from 03-05 00:00 on: the rotated log's new content
    run_ingest([log], root)
    assert not no_record_reads
    _assert_equals_analyze(root, [old, log])


def test_records_older_than_the_history_rebuild_it_from_every_record(
    tmp_path: Path, no_record_reads: list[int]
) -> None:
    """The later day ingested first, then the earlier one: the state cannot continue (the new records come
    before what it closed), so the derived tables are made again from every archived record."""
    log = tmp_path / "nights.log"
    simulate_over_midnight(log, SEED, 900, minutes=20, days=2)
    early, late = _split_at(log, "2026-03-04")
    first, second = tmp_path / "a.log", tmp_path / "b.log"
    first.write_bytes(late)
    second.write_bytes(early)
    root = tmp_path / "arc"
    run_ingest([first], root, layout="example")
    run_ingest([second], root)
    assert no_record_reads  # rebuilt
    _names, rows = run_query(root, "SELECT count(*), sum(axles) FROM passages")
    job = whole_job([second, first])
    assert rows == [(len(job.analysis.passages), int(job.analysis.passages["axles"].sum()))]


def test_the_fingerprint_survives_the_manifest_and_keeps_older_archives_resuming(tmp_path: Path) -> None:
    """The manifest keeps the fingerprint as JSON: a layout with heads of their own spacing must compare equal
    after the round trip (else every later ingest reads every record again); a layout of one spacing keeps
    the fingerprint archives had before heads had spacings of their own."""
    import json
    from types import SimpleNamespace

    from console.analysis.passages.speed_settings import SpeedSettings
    from console.archive.derive_settings import fingerprint
    from console.layout import load_layout
    from console.layouts import __file__ as layouts_init

    uniform = SimpleNamespace(speed=SpeedSettings.of_layout(load_layout("example")))
    fp = fingerprint(uniform, "example")  # type: ignore[arg-type]
    assert set(fp["settings"]) == {"spacing_m", "train_length_m", "idle_gap_s", "pair_window_s", "max_speed_kmh"}
    text = Path(layouts_init).with_name("example_station.toml").read_text(encoding="utf-8")
    (tmp_path / "mixed.toml").write_text(text.replace("spacing_m = 0.13", "spacing_m = 0.2", 1), encoding="utf-8")
    mixed = SimpleNamespace(speed=SpeedSettings.of_layout(load_layout(tmp_path / "mixed.toml")))
    fp = fingerprint(mixed, "mixed.toml")  # type: ignore[arg-type]
    assert json.loads(json.dumps(fp)) == fp and fp["settings"]["head_spacing_m"] == [["WS1", 0.2]]
