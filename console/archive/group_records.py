"""What a group's archived records tell its derivation, read with SQL: whether older files hold records of
its heads, which records repeat another file's at a seam, and each head's facts."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from console.analysis.counting.wheels import SYS1, SYS2, WHEEL_SENSOR_ADDRESS
from console.analysis.passages.overlap import overlap_mask
from console.analysis.passages.registers import RegisterTables
from console.analysis.sections.stream import HeadFacts
from console.archive.derive_groups import HEAD_KEY, group_where, head_key
from console.archive.store import Manifest
from console.archive.views import connect
from parsers.diag.registry import DiagRegistry
from parsers.units import NS_PER_DAY


def older_records(root: Path, manifest: Manifest, heads: frozenset[tuple[int, Any]], new_seqs: list[int]) -> bool:
    """Whether the group's heads have records in files other than this ingest's new ones."""

    cond, params = group_where(heads, None)
    con, _ = connect(root, manifest, tables=("records",))
    try:
        rows = con.sql(
            f"SELECT count(*) FROM records WHERE {cond} AND file_seq NOT IN (SELECT unnest(?))",
            params=[*params, list(new_seqs)],
        ).fetchall()
    finally:
        con.close()
    return bool(rows and rows[0][0])


_RECORD_PRINT = "hash(time, diag_id, device_id, counting_head, channel, address, label, value)"


def repeated_records(root: Path, manifest: Manifest, where: tuple[str, list[Any]]) -> dict[str, np.ndarray]:
    """The archived records that repeat another file's at a seam: ``key`` (file_seq << 32 | line), sorted,
    and their ``time_ns``.  Only heads whose files' time ranges intersect are compared record by record."""

    none = {"key": np.zeros(0, np.int64), "time_ns": np.zeros(0, np.int64)}
    con, _ = connect(root, manifest, tables=("records",))
    try:
        cond, params = where
        w = f" WHERE {cond}" if cond else ""
        spans = con.sql(
            f"SELECT device_id, counting_head, file_seq, min(time) AS lo, max(time) AS hi FROM records{w} "
            "GROUP BY ALL ORDER BY device_id, counting_head, file_seq",
            params=params,
        ).fetchall()
        suspects: set[tuple[int, str]] = set()
        latest: dict[tuple[int, str], Any] = {}
        for dev, head, _seq, lo, hi in spans:  # per head and file: a few hundred rows
            k = (dev, head)
            if k in latest and lo <= latest[k]:
                suspects.add(k)
            latest[k] = max(latest.get(k, hi), hi)
        if not suspects:
            return none
        rows = con.sql(
            "SELECT file_seq, line, device_id, counting_head, epoch_ns(time) AS t, "
            f"{_RECORD_PRINT} AS fp "
            f"FROM records WHERE {HEAD_KEY} IN (SELECT unnest(?)) ORDER BY file_seq, line",
            params=[sorted(head_key(d, h) for d, h in suspects)],
        ).fetchnumpy()

        def whole_files(fa: int, fb: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            # Every record of the two files (all heads, all boards), as the batch read compares them.
            got = []
            for seq in (fa, fb):
                r = con.sql(
                    f"SELECT line, {_RECORD_PRINT} AS fp FROM records WHERE file_seq = ? ORDER BY line",
                    params=[seq],
                ).fetchnumpy()
                got += [(np.int64(seq) << 32) | r["line"].astype(np.int64), r["fp"].astype(np.uint64)]
            return got[0], got[1], got[2], got[3]

        import pandas as pd

        head = pd.factorize(pd.MultiIndex.from_arrays([rows["device_id"], rows["counting_head"]]))[0]
        mask = overlap_mask(
            rows["file_seq"].astype(np.int64),
            head.astype(np.int64),
            rows["fp"].astype(np.uint64),
            rows["t"].astype(np.int64),
            key=(rows["file_seq"].astype(np.int64) << 32) | rows["line"].astype(np.int64),
            whole_files=whole_files,
        )
    finally:
        con.close()
    key = (rows["file_seq"].astype(np.int64)[mask] << 32) | rows["line"].astype(np.int64)[mask]
    order = np.argsort(key)
    return {"key": key[order], "time_ns": rows["t"].astype(np.int64)[mask][order]}


def head_facts(
    root: Path, manifest: Manifest, registry: DiagRegistry, where: tuple[str, list[Any]]
) -> tuple[dict[int, Any], np.ndarray]:
    """Per head key of ``registry`` (its registers numbered), what a read of every record knows of it: the
    facts detection events count by, and its stamps' resolution (axles pair by it)."""

    con, _ = connect(root, manifest, tables=("records",))
    try:
        rows = con.sql(
            "SELECT device_id, counting_head, bool_or(value = 0) AS releases, "
            "bool_and(subsecond) FILTER (WHERE value = 1) AS fine, "
            "bool_and(epoch_ns(time) % 1000000 = 0) FILTER (WHERE value = 1) AS ms, "
            "bool_and(epoch_ns(time) % 1000 = 0) FILTER (WHERE value = 1) AS us, "
            "bool_or(NOT subsecond) AS whole FROM records "
            "WHERE (label_canonical = 'wheel_sensor' OR (label = '' AND address = ?)) AND channel IN (?, ?) "
            + (f"AND {where[0]} " if where[0] else "")
            + "GROUP BY ALL",
            params=[WHEEL_SENSOR_ADDRESS, SYS1, SYS2, *where[1]],
        ).fetchall()
    finally:
        con.close()
    heads = RegisterTables(registry).update().heads
    key_of = {(int(d), n): k for k, (d, n) in enumerate(heads)}
    steps = np.full(len(heads), np.nan)
    facts: dict[int, Any] = {}
    for dev, name, releases, fine, ms, us, whole in rows:  # per head
        k = key_of.get((int(dev), name))
        if k is None:
            continue
        facts[k] = HeadFacts(point_mode=not releases, whole_second=bool(whole))
        if fine is not None:
            steps[k] = (1e-3 if ms else 1e-6 if us else 1e-9) if fine else 1.0
    return facts, steps


def repeats_per_day(repeated: dict[str, np.ndarray]) -> dict[str, int]:
    days, counts = np.unique(repeated["time_ns"] // NS_PER_DAY, return_counts=True)
    return {str(np.datetime64(int(d), "D")): int(n) for d, n in zip(days.tolist(), counts.tolist(), strict=True)}
