"""The archive's targets, measured (issue "The archive").

    python benchmarks/gen_diag_log.py 2000000 /tmp/diag_2M.log
    python benchmarks/bench_archive.py /tmp/diag_2M.log --replicas 15

1. ingest vs analyze vs report on the same log: wall time and peak RSS of
   each child process (wait4's ru_maxrss);
2. archive size against the raw text (the whole archive, and records alone);
3. queries on a big archive: the ingested records (and axles) are
   replicated ``--replicas`` times, each copy shifted by whole days into
   partitions of their own (as more days of the same line would be), and
   published as one manifest; then the median of 5 runs of
   * axles per head per day (the preset),
   * one hour of one head's records,
   * a one-day report's data (``history.report_data`` for one day and head set).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

NS_PER_DAY = 86_400 * 10**9


_LAST_RSS = [0.0]


def run_rss_last() -> float:
    return _LAST_RSS[0]


def show(label: str, seconds: float, n: int, rss_mb: float) -> None:
    print(f"{label:30s}: {seconds:6.1f} s  {n / seconds:10,.0f} records/s  peak RSS {rss_mb:5.0f} MB")


def run(cmd: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one child process; stdout discarded."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {err}")
    _LAST_RSS[0] = usage.ru_maxrss / 1024
    return wall, usage.ru_maxrss / 1024


def du(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def replicate(src: Path, dst: Path, replicas: int) -> int:
    """A bigger archive: records and axles copied ``replicas`` times, shifted by the log's span in days."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from console.archive.store import Manifest, ensure_layout, publish, read_current

    m = read_current(src)
    ensure_layout(dst)
    out = Manifest(generation=1, files=m.files, derived=m.derived)
    days = [p.split("day=")[1][:10] for p in m.parts("records")]
    span = (
        (
            int(pc.max(pa.array(days, pa.string()).cast(pa.date32()).cast(pa.int32())).as_py())
            - int(pc.min(pa.array(days, pa.string()).cast(pa.date32()).cast(pa.int32())).as_py())
        )
        + 1
        if days
        else 1
    )
    new: list[str] = []
    for table in m.tables:
        for rel in m.parts(table):
            if table == "axles":
                t = pq.read_table(src / rel)
                copies = []
                for k in range(replicas):
                    shift = k * span
                    c = t
                    for col, delta in (
                        ("time", pa.scalar(shift * NS_PER_DAY, pa.duration("ns"))),
                        ("time_ns", shift * NS_PER_DAY),
                        ("day", pa.scalar(shift * 86_400_000, pa.duration("ms"))),
                    ):
                        i = c.schema.get_field_index(col)
                        shifted_col = pc.add(c.column(col), delta)
                        c = c.set_column(i, col, shifted_col.cast(c.schema.field(col).type))
                    copies.append(c)
                target = dst / rel
                target.parent.mkdir(parents=True, exist_ok=True)
                pq.write_table(pa.concat_tables(copies), target, compression="zstd")
                out.tables.setdefault(table, []).append(rel)
                new.append(rel)
                continue
            if table != "records":
                target = dst / rel
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy(src / rel, target)
                out.tables.setdefault(table, []).append(rel)
                new.append(rel)
                continue
            t = pq.read_table(src / rel, partitioning=None)
            day = rel.split("day=")[1][:10]
            for k in range(replicas):
                shift = k * span
                shifted = t
                for col in ("time",):
                    idx = shifted.schema.get_field_index(col)
                    shifted = shifted.set_column(
                        idx, col, pc.add(shifted.column(col), pa.scalar(shift * NS_PER_DAY, pa.duration("ns")))
                    )
                if "time_ns" in shifted.column_names:
                    idx = shifted.schema.get_field_index("time_ns")
                    shifted = shifted.set_column(idx, "time_ns", pc.add(shifted.column("time_ns"), shift * NS_PER_DAY))
                new_day = str(__import__("numpy").datetime64(day) + shift)
                new_rel = rel.replace(f"day={day}", f"day={new_day}").replace(".parquet", f"-c{k}.parquet")
                path = dst / new_rel
                path.parent.mkdir(parents=True, exist_ok=True)
                pq.write_table(shifted, path, compression="zstd")
                out.tables.setdefault(table, []).append(new_rel)
                new.append(new_rel)
    publish(dst, out, new)
    from console.archive.views import run_query

    return int(run_query(dst, "SELECT count(*) FROM records")[1][0][0])  # type: ignore[call-overload]


def timed(fn: object, runs: int = 5) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("--replicas", type=int, default=15)
    ap.add_argument("--skip-processes", action="store_true", help="only the query part")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="bench-archive-"))
    arc = work / "arc"
    exe = [sys.executable, "-c", "from console.cli import app; app()"]
    raw = args.log.stat().st_size
    try:
        t_ing, r_ing = run([*exe, "ingest", str(args.log), "--archive", str(arc)])
        from console.archive.views import run_query

        n = int(run_query(arc, "SELECT count(*) FROM records")[1][0][0])  # type: ignore[call-overload]
        print(f"log: {args.log} {raw / 1e6:.0f} MB, {n:,} records")
        show("ingest (parse, write, derive)", t_ing, n, r_ing)
        if not args.skip_processes:
            show("analyze --json", *run([*exe, "analyze", "--json", str(args.log)])[:1], n, run_rss_last())
            show(
                "report --format json", *run([*exe, "report", str(args.log), "--format", "json"])[:1], n, run_rss_last()
            )
        size = du(arc)
        rec = du(arc / "data" / "records")
        print(f"archive size: {size / 1e6:.1f} MB = {100 * size / raw:.2f} % of the raw log", end="")
        print(f"; records alone {100 * rec / raw:.2f} %")

        big = work / "big"
        total = replicate(arc, big, args.replicas)
        print(f"big archive: {total:,} records ({args.replicas} replicas), {du(big) / 1e6:.0f} MB")
        from console.archive.history import Window, report_data
        from console.archive.presets import PRESETS
        from console.archive.views import connect

        sql = "SELECT min(time), counting_head FROM records GROUP BY counting_head ORDER BY 2 LIMIT 1"
        t_first, head = run_query(big, sql)[1][0]
        import datetime as dt

        assert isinstance(t_first, dt.datetime)
        t_end = t_first + dt.timedelta(hours=1)
        hour_sql = (
            f"SELECT * FROM records WHERE counting_head = '{head}' AND time >= TIMESTAMP '{t_first}'"
            f" AND time < TIMESTAMP '{t_end}' AND day = DATE '{t_first.date()}'"
        )
        axles_sql = PRESETS["axles-per-head-per-day"].sql
        print(f"axles per head per day (query command) : {timed(lambda: run_query(big, axles_sql)):.3f} s")
        print(f"one hour of one head   (query command) : {timed(lambda: run_query(big, hour_sql)):.3f} s")
        # A long-lived reader (a TUI, a service) keeps its connection: the query alone.
        con, _ = connect(big)
        print(f"axles per head per day (open connection): {timed(lambda: con.execute(axles_sql).fetchall()):.3f} s")
        print(f"one hour of one head   (open connection): {timed(lambda: con.execute(hour_sql).fetchall()):.3f} s")
        con.close()
        day0 = dt.datetime.combine(t_first.date(), dt.time())
        w = Window(start=day0, end=day0 + dt.timedelta(days=1))
        print(f"one-day report data                     : {timed(lambda: report_data(big, None, w), runs=3):.3f} s")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
