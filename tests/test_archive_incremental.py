"""Incremental derivation: an ingest derives again only the partitions it changed, and the archive
still equals ``analyze`` (and the report) of all the files read together.

Simulated logs run over midnight (the example layout's heads, trains every ~90 s).
``manifest.derived["partitions"][key]["generation"]`` says which ingest last derived a partition.
"""

from __future__ import annotations

import datetime as dt
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow.parquet as pq

from console.analysis.timefmt import NS
from console.archive.derive import affected_partitions, cross_head_tables, derive_tables, partition_parts
from console.archive.history import report_data, speed_settings
from console.archive.ingest import run_ingest
from console.archive.partition import PartitionKey, axles_table, passages_table
from console.archive.store import Manifest, read_current
from console.archive.views import run_query
from tests.reads import whole_job
from tests.test_archive_derive import MIDNIGHT_S, simulate_over_midnight

# A WS4 passage runs from 23:59:58.99 to 00:00:01.7 with these settings (asserted below, not assumed).
SEED = 7
BEFORE_S = 301


def _split_at(log: Path, day: str) -> tuple[bytes, bytes]:
    """The log's lines before the first line dated ``day`` (or later), and the rest."""
    lines = log.read_bytes().splitlines(keepends=True)
    at = [line.index(b"Date:") + 5 for line in lines]
    cut = next(i for i, (line, a) in enumerate(zip(lines, at, strict=True)) if line[a : a + 10] >= day.encode())
    return b"".join(lines[:cut]), b"".join(lines[cut:])


def _generations(root: Path) -> dict[str, int]:
    return {k: int(v["generation"]) for k, v in read_current(root).derived["partitions"].items()}


def _stored(root: Path, table: str, by: list[str]) -> pd.DataFrame:
    names, rows = run_query(root, f"SELECT * FROM {table}")
    df = pd.DataFrame(rows, columns=names).drop(columns=["day"])
    return df.sort_values(by, kind="stable").reset_index(drop=True)


def _assert_equals_analyze(root: Path, logs: list[Path]) -> None:
    """Stored passages and axles == analyze's on the files; stored cross-head tables == the report's path."""
    m = read_current(root)
    job = whole_job(logs, speed_settings(m), keep_releases=True)
    by_p = ["device_id", "counting_head", "start_ns"]
    by_a = ["device_id", "counting_head", "time_ns", "direction"]
    want_p = passages_table(job.analysis).sort_values(by_p, kind="stable").reset_index(drop=True)
    want_a = axles_table(job.analysis).sort_values(by_a, kind="stable").reset_index(drop=True)
    got_p = _stored(root, "passages", by_p)[list(want_p.columns)]
    got_a = _stored(root, "axles", by_a)[list(want_a.columns)]
    pd.testing.assert_frame_equal(got_p, want_p, check_dtype=False, obj="passages")
    pd.testing.assert_frame_equal(got_a, want_a, check_dtype=False, obj="axles")
    # The cross-head tables, from the combined partition rows == from every record read again (the report).
    want = cross_head_tables(report_data(root))
    for table, by in (
        ("section_states", ["time_ns", "section", "state"]),
        ("count_ledger", ["time_ns", "section", "head"]),
        ("health_findings", ["rule", "counting_head", "channel", "message"]),
    ):
        if table not in want:
            assert not m.parts(table)
            continue
        names, rows = run_query(root, f"SELECT * FROM {table}")
        got = pd.DataFrame(rows, columns=names).drop(columns=["day"], errors="ignore")
        w = want[table][list(got.columns)].sort_values(by, kind="stable").reset_index(drop=True)
        g = got.sort_values(by, kind="stable").reset_index(drop=True)
        pd.testing.assert_frame_equal(g, w, check_dtype=False, obj=table)


def test_a_later_day_derives_only_the_partitions_it_touches(tmp_path: Path) -> None:
    log = tmp_path / "nights.log"
    simulate_over_midnight(log, SEED, 900, minutes=20, days=3)  # records on 03-02 .. 03-05
    early, late = _split_at(log, "2026-03-04")
    first, second = tmp_path / "a.log", tmp_path / "b.log"
    first.write_bytes(early)
    second.write_bytes(late)
    root = tmp_path / "arc"
    run_ingest([first], root, layout="example")
    gen1 = _generations(root)
    assert {PartitionKey.parse(k).day.isoformat() for k in gen1} == {"2026-03-02", "2026-03-03"}
    run_ingest([second], root)
    gen2 = _generations(root)
    g = read_current(root).generation
    redone = {k for k, v in gen2.items() if v == g}
    days = {k: PartitionKey.parse(k).day.isoformat() for k in gen2}
    # The new days are derived; the first day is not (nothing of it, nor of the day after it, changed).
    assert {k for k in gen2 if days[k] >= "2026-03-04"} <= redone
    assert not {k for k in redone if days[k] == "2026-03-02"}
    assert {k: gen2[k] for k in gen1 if days[k] == "2026-03-02"} == {
        k: v for k, v in gen1.items() if days[k] == "2026-03-02"
    }
    # Unchanged partitions keep their parts (same files, not rewritten).
    m = read_current(root)
    for k, v in m.derived["partitions"].items():
        if days[k] == "2026-03-02":
            parts = partition_parts(k, v)
            assert parts and all(f"/g{gen1[k]:06d}-d.parquet" in rel for rel in parts.values())
            assert set(parts.values()) <= set(m.parts("passages") + m.parts("axles") + m.parts("wheel_records"))
    _assert_equals_analyze(root, [first, second])
    # A third ingest adding nothing derives nothing.
    run_ingest([first, second], root)
    assert _generations(root) == gen2


def test_a_passage_over_midnight_split_across_two_ingests_is_one_passage(tmp_path: Path) -> None:
    log = tmp_path / "whole.log"
    simulate_over_midnight(log, SEED, BEFORE_S, minutes=6)
    midnight = MIDNIGHT_S * NS
    whole = whole_job([log], speed_settings(Manifest()), keep_releases=True).analysis.passages
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
    device_id, day, start_ns, end_ns, axles = rows[0]
    assert axles == int(crossing["axles"].iloc[0]) > 0
    assert day == dt.date(2026, 3, 2)  # stored with the day it starts
    assert (start_ns, end_ns) == (int(crossing["start_ns"].iloc[0]), int(crossing["end_ns"].iloc[0]))
    # The day before was derived again by the second ingest: its passage ran on into the new day.
    gens = _generations(root)
    g = read_current(root).generation
    assert gens[f"{device_id}/2026-03-02"] == g
    assert gens[f"{device_id}/2026-03-03"] == g


def test_a_mapper_runs_the_picklable_tasks_with_the_same_result(tmp_path: Path) -> None:
    log = tmp_path / "nights.log"
    simulate_over_midnight(log, SEED, BEFORE_S, minutes=6, days=2)
    root = tmp_path / "arc"
    run_ingest([log], root, layout="example")
    calls: list[int] = []

    def mapper(fn: Callable[[Any], Any], items: list[Any]) -> list[Any]:
        # As another process would: the function and each task and result go through pickle.
        f = pickle.loads(pickle.dumps(fn))
        calls.append(len(items))
        return [pickle.loads(pickle.dumps(f(pickle.loads(pickle.dumps(i))))) for i in items]

    m = read_current(root)
    m.derived = {"layout": m.derived["layout"]}  # as if never derived: every partition again
    m.generation += 1
    derive_tables(root, m, None, mapper=mapper)
    assert calls and sum(calls) >= 1
    published = read_current(root)
    assert sorted(m.derived["partitions"]) == sorted(published.derived["partitions"])
    for table in ("passages", "axles", "wheel_records"):
        mine = [pq.read_table(root / rel).to_pandas() for rel in sorted(m.parts(table))]
        theirs = [pq.read_table(root / rel).to_pandas() for rel in sorted(published.parts(table))]
        assert len(mine) == len(theirs)
        for a, b in zip(mine, theirs, strict=True):
            pd.testing.assert_frame_equal(a, b, obj=table)


def test_affected_partitions_follow_the_passages_over_midnight() -> None:
    """Which partitions a change derives again: itself, the day after, earlier days whose passages reach it."""
    day = [dt.date(2026, 3, 1) + dt.timedelta(days=i) for i in range(7)]

    def key(i: int, dev: int = 1) -> PartitionKey:
        return PartitionKey(dev, day[i])

    def midnight(i: int) -> int:
        return (day[i] - dt.date(1970, 1, 1)).days * 86_400 * NS

    keys = [key(i) for i in (0, 1, 2, 3, 4, 6)] + [key(i, dev=2) for i in range(7)]
    info = {
        key(0).name: {"reach_ns": midnight(3) + 1},  # a passage from day 0 running into day 3
        key(1).name: {"reach_ns": None},
        key(2).name: {"reach_ns": midnight(3) - 5 * NS},  # ends 5 s before midnight: within the 10 s idle gap
        key(3).name: {"reach_ns": midnight(3) + 3600 * NS},
        key(4).name: {"reach_ns": midnight(5) - 1},  # up to midnight; day 5 has no records (any more)
    }

    def affected(*changed: PartitionKey) -> set[PartitionKey]:
        return affected_partitions(keys, changed, info, idle_gap_s=10.0)

    assert affected(key(3)) == {key(0), key(2), key(3), key(4)}
    assert affected(key(1)) == {key(0), key(1), key(2)}  # day 0's passage runs over day 1 too
    assert affected(key(2)) == {key(0), key(2), key(3)}  # ... and day 2; day 1's passages end early
    assert affected(key(6)) == {key(6)}  # a day without records before it: nothing carried
    assert affected(key(4, dev=2)) == {key(4, dev=2), key(5, dev=2)}  # other devices' days never
    # A day gone (its records replaced): the day after derives again, and what reached it.
    assert affected(key(5)) == {key(4), key(6)}


def test_a_rotated_file_adds_its_new_content_to_the_days_already_derived(tmp_path: Path) -> None:
    """A log rotated in place (its first bytes changed) is a new file: its records join days already
    derived (one of them shared with the old content), and the archive equals ``analyze`` of both files."""
    log = tmp_path / "unit.log"
    old = tmp_path / "unit.log.1"
    root = tmp_path / "arc"
    simulate_over_midnight(log, SEED, BEFORE_S, minutes=6, days=3)  # 03-02 .. 03-05 00:0x
    run_ingest([log], root, layout="example")
    gen1 = _generations(root)
    old.write_bytes(log.read_bytes())
    later = tmp_path / "later.log"
    simulate_over_midnight(later, SEED + 1, BEFORE_S, minutes=6, days=4)
    log.write_bytes(_split_at(later, "2026-03-05")[1])  # from 03-05 00:00 on: the rotated log's new content
    run_ingest([log], root)
    gens = _generations(root)
    g = read_current(root).generation
    days = {k: PartitionKey.parse(k).day.isoformat() for k in gens}
    assert {k for k in gens if days[k] <= "2026-03-03"} == {k for k in gen1 if days[k] <= "2026-03-03"}
    assert all(gens[k] == gen1[k] for k in gens if days[k] <= "2026-03-03")  # untouched
    assert all(gens[k] == g for k in gens if days[k] >= "2026-03-05")
    _assert_equals_analyze(root, [old, log])
