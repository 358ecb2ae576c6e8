"""The archive's targets, measured (issue "The archive"; figures in docs/archive.md, Measured).

    python benchmarks/gen_realistic_diag.py 3000000 r3m.log --truth r3m.json
    python benchmarks/bench_archive.py r3m.log --replicas 10 --work W3
    python benchmarks/bench_archive.py r3m.log --replicas 10 --work W3 --skip-ingest --skip-processes
    python benchmarks/bench_archive.py --big W3/big --baseline /tmp/base --rounds 5

1. ingest vs analyze vs report on the same log: wall time, CPU time and
   peak RSS of each child process (wait4's rusage); the ingest's phases
   (``ingest --json``) and its read step alone (parse, encode, write the
   record parts: no derivation, nothing published);
2. archive size against the raw text (the whole archive, and per table);
3. queries on a big archive: the ingested records (and axles) are
   replicated ``--replicas`` times, each copy shifted by whole days into
   partitions of their own (as more days of the same line would be), and
   published as one manifest; then
   * axles per head per day (the preset) and one hour of one head's records:
     in process as ``trackside query`` runs them, on an open connection, and
     through a new ``trackside query`` process (beside ``trackside --version``
     and ``query "SELECT 1"``: the start-up alone);
   * a one-day report: ``history.report_data`` and ``trackside report --archive``.

``--big DIR`` times only the commands (one-day report, the two queries, start-up) on an existing big
archive, read-only; with ``--baseline CHECKOUT`` each round runs that checkout's code too, alternately,
and the outputs of both are compared byte for byte.

On a shared machine compare the CPU seconds: wall time counts other jobs' turns.
"""

from __future__ import annotations

import argparse
import json
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
    print(
        f"{label:34s}: {seconds:6.1f} s  {n / seconds:10,.0f} records/s  peak RSS {rss_mb:5.0f} MB"
        f"  CPU {_LAST_CPU[0]:6.1f} s"
    )


_LAST_OUT = [b""]
_LAST_CPU = [0.0]


def run(cmd: list[str], keep_stdout: bool = False, cwd: Path | None = None) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one child process; stdout discarded unless ``keep_stdout``."""
    with tempfile.TemporaryFile() as out_file:
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            cmd, stdout=out_file if keep_stdout else subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=cwd
        )
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        err = proc.stderr.read().decode() if proc.stderr else ""
        if os.waitstatus_to_exitcode(status) != 0:
            raise SystemExit(f"{' '.join(cmd)} failed: {err}")
        out_file.seek(0)
        _LAST_OUT[0] = out_file.read()
    _LAST_RSS[0] = usage.ru_maxrss / 1024
    _LAST_CPU[0] = usage.ru_utime + usage.ru_stime
    return wall, usage.ru_maxrss / 1024


# The ingest's reading step alone (parse, encode, write the record parts; no derivation, nothing published):
# what the ingest costs besides the analyses it shares with `report`.
READ_ONLY = """
import sys
from pathlib import Path
from console.archive.ingest_finish import finish_records
from console.archive.ingest_inputs import expand_inputs
from console.archive.ingest_job import IngestJob
from console.archive.store import ensure_layout, read_current
root = Path(sys.argv[2])
ensure_layout(root)
job = IngestJob(root, read_current(root), None, None)  # no on_bytes, no derivation: the read alone
for path, shown in expand_inputs([Path(sys.argv[1])], root):
    job.add_file(path, shown)
finish_records(job)
"""


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
            if table in ("head_days", "identity_days"):  # per day: each copy on its shifted day, as the records
                t = pq.read_table(src / rel, partitioning=None)
                day = rel.split("day=")[1][:10]
                for k in range(replicas):
                    shifted = t
                    for col in ("first_time", "last_time", "at_time"):
                        if col in shifted.column_names:
                            idx = shifted.schema.get_field_index(col)
                            delta = pa.scalar(k * span * NS_PER_DAY, pa.duration("ns"))
                            shifted = shifted.set_column(idx, col, pc.add(shifted.column(col), delta))
                    new_day = str(__import__("numpy").datetime64(day) + k * span)
                    new_rel = rel.replace(f"day={day}", f"day={new_day}").replace(".parquet", f"-c{k}.parquet")
                    (dst / new_rel).parent.mkdir(parents=True, exist_ok=True)
                    pq.write_table(shifted, dst / new_rel, compression="zstd")
                    out.tables.setdefault(table, []).append(new_rel)
                    new.append(new_rel)
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
    from console.archive.query import run_query

    return int(run_query(dst, "SELECT count(*) FROM records")[1][0][0])  # type: ignore[call-overload]


def timed(fn: object, runs: int = 5) -> str:
    """Median wall and CPU seconds (this process, every thread: DuckDB's too) of ``runs`` calls.

    The CPU time is what to compare with a target on a shared machine: the wall time there counts
    the other jobs' turns.
    """
    walls, cpus = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()  # type: ignore[operator]
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return f"{statistics.median(walls):.3f} s (CPU {statistics.median(cpus):.3f} s)"


def median_run(cmd: list[str], runs: int = 3) -> str:
    """Median wall and CPU seconds of ``runs`` child processes."""
    walls, cpus = [], []
    for _ in range(runs):
        walls.append(run(cmd)[0])
        cpus.append(_LAST_CPU[0])
    return f"{statistics.median(walls):.3f} s (CPU {statistics.median(cpus):.3f} s)"


# `trackside` as run from a checkout: its own console package first (python -c puts the directory first).
LAUNCH = "import sys; sys.argv[0] = 'trackside'; from console.cli.app import app; app()"


def load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


def big_commands(big: Path) -> dict[str, list[str]]:
    """The commands timed on a big archive: start-up, the two queries, the one-day report.

    The first head and its first time are asked of a child process: this one stays small, since a child's
    peak RSS counts the parent's pages it was forked with.
    """
    import datetime as dt

    sql = "SELECT min(time), counting_head FROM records GROUP BY counting_head ORDER BY 2 LIMIT 1"
    ask = "import sys; from pathlib import Path; from console.archive.query import run_query; "
    ask += "t, h = run_query(Path(sys.argv[1]), sys.argv[2])[1][0]; print(t.isoformat()); print(h)"
    lines = subprocess.run([sys.executable, "-c", ask, str(big), sql], capture_output=True, text=True, check=True)
    first, head = lines.stdout.splitlines()[-2:]  # after DuckDB's progress bar, if a slow machine shows one
    t_first = dt.datetime.fromisoformat(first)

    t_end = t_first + dt.timedelta(hours=1)
    hour_sql = (
        f"SELECT * FROM records WHERE counting_head = '{head}' AND time >= TIMESTAMP '{t_first}'"
        f" AND time < TIMESTAMP '{t_end}' AND day = DATE '{t_first.date()}'"
    )
    day0 = dt.datetime.combine(t_first.date(), dt.time())
    day1 = day0 + dt.timedelta(days=1)
    q = ["query", "--archive", str(big), "--format", "csv"]
    return {
        "trackside --version": ["--version"],
        "query SELECT 1": [*q, "SELECT 1"],
        "axles per head per day (query)": [*q, "--preset", "axles-per-head-per-day"],
        "one hour of one head (query)": [*q, hour_sql],
        "one-day report --format json": [
            *["report", "--archive", str(big), "--from", day0.isoformat(), "--to", day1.isoformat()],
            *["--format", "json"],
        ],
    }


def derivation_note(big: Path, code: Path) -> str:
    """Whether ``code``'s report reads ``big``'s derived tables or, derived by another version, its records
    through the whole pipeline (several times slower).  Asked of a child: this process stays small."""
    current = (big / "CURRENT").read_text().strip()
    stored = json.loads((big / "manifests" / current).read_text()).get("derived", {}).get("fingerprint", {})
    ask = "from console.archive.derive_sink import DERIVE_VERSION; print(DERIVE_VERSION)"
    version = subprocess.run([sys.executable, "-c", ask], capture_output=True, text=True, check=True, cwd=code)
    ours = int(version.stdout.split()[-1])
    how = "the report reads the derived tables" if stored.get("version") == ours else "the report reads the RECORDS"
    return f"archive derived by version {stored.get('version')}, code's version {ours}: {how}"


def compare_big(big: Path, baseline: Path | None, rounds: int, baseline_big: Path | None = None) -> None:
    """Each command ``rounds`` times, alternating this checkout and ``baseline``'s; medians of wall and CPU,
    peak RSS; the outputs compared byte for byte.  ``baseline_big``: the baseline reads this archive instead
    (the same records derived by the baseline's own derive version)."""
    here = Path(__file__).resolve().parent.parent
    sides = {"ours": here, **({"baseline": baseline.resolve()} if baseline is not None else {})}
    print(f"big archive: {big} ({du(big) / 1e6:.0f} MB); {rounds} rounds; load {load()}")
    for side, cwd in sides.items():
        print(f"  {side}: {derivation_note(baseline_big if side == 'baseline' and baseline_big else big, cwd)}")
    other = big_commands(baseline_big) if baseline_big is not None else {}
    for label, args in big_commands(big).items():
        cmds = {
            side: [sys.executable, "-c", LAUNCH, *(other.get(label, args) if side == "baseline" else args)]
            for side in sides
        }
        got: dict[str, list[tuple[float, float, float]]] = {k: [] for k in sides}
        outs: dict[str, bytes] = {}
        loads = []
        for _ in range(rounds):
            for side, cwd in sides.items():
                wall, rss = run(cmds[side], keep_stdout=True, cwd=cwd)
                got[side].append((wall, _LAST_CPU[0], rss))
                outs.setdefault(side, _LAST_OUT[0])
                if outs[side] != _LAST_OUT[0]:
                    raise SystemExit(f"{label}: {side}'s output changed between runs")
            loads.append(load())
        line = f"{label:32s}"
        for side, runs in got.items():
            wall = statistics.median(w for w, _, _ in runs)
            cpu = statistics.median(c for _, c, _ in runs)
            line += f"  {side} {wall:.3f} s (CPU {cpu:.3f} s, min {min(c for _, c, _ in runs):.3f}) "
            line += f"{max(r for _, _, r in runs):.0f} MB"
        if baseline is not None:
            line += "  same output" if outs["ours"] == outs["baseline"] else "  OUTPUT DIFFERS"
        print(line + f"  load {loads[0]} .. {loads[-1]}", flush=True)
    print(f"load at the end {load()}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path, nargs="?")
    ap.add_argument("--big", type=Path, help="time the commands on this existing big archive only (read-only)")
    ap.add_argument("--baseline", type=Path, help="with --big: also run this checkout's code, alternately")
    ap.add_argument("--baseline-big", type=Path, help="with --baseline: the baseline reads this archive instead")
    ap.add_argument("--rounds", type=int, default=5, help="with --big: runs of each command per side (median)")
    ap.add_argument("--replicas", type=int, default=15)
    ap.add_argument("--skip-processes", action="store_true", help="no analyze, report or read-only runs")
    ap.add_argument("--skip-ingest", action="store_true", help="reuse WORK/arc (an archive of LOG, see --work)")
    ap.add_argument("--report-runs", type=int, default=3, help="runs of the one-day report timings (median)")
    ap.add_argument("--skip-reports", action="store_true", help="no one-day report timings")
    ap.add_argument("--work", type=Path, help="work directory, kept (default: a temporary one, removed)")
    args = ap.parse_args()
    if args.big is not None:
        compare_big(args.big, args.baseline, args.rounds, args.baseline_big)
        return
    if args.log is None:
        ap.error("give LOG (or --big DIR)")
    work = args.work or Path(tempfile.mkdtemp(prefix="bench-archive-"))
    work.mkdir(parents=True, exist_ok=True)
    arc = work / "arc"
    exe = [sys.executable, "-c", "from console.cli.app import app; app()"]
    raw = args.log.stat().st_size
    try:
        if not args.skip_ingest:
            shutil.rmtree(arc, ignore_errors=True)
            t_ing, r_ing = run([*exe, "ingest", str(args.log), "--archive", str(arc), "--json"], keep_stdout=True)
            cpu_ing = _LAST_CPU[0]
            phases = json.loads(_LAST_OUT[0]).get("phase_seconds", {})
        from console.archive.query import run_query

        n = int(run_query(arc, "SELECT count(*) FROM records")[1][0][0])  # type: ignore[call-overload]
        print(f"log: {args.log} {raw / 1e6:.0f} MB, {n:,} records")
        if not args.skip_ingest:
            _LAST_CPU[0] = cpu_ing
            show("ingest (parse, write, derive)", t_ing, n, r_ing)
            print("  phases (s): " + ", ".join(f"{k} {v:.1f}" for k, v in phases.items()))
        if not args.skip_processes:
            scratch = work / "read-only"
            shutil.rmtree(scratch, ignore_errors=True)
            read_only = [sys.executable, "-c", READ_ONLY, str(args.log), str(scratch)]
            show("ingest's read step alone", *run(read_only)[:1], n, run_rss_last())
            shutil.rmtree(scratch, ignore_errors=True)
            show("analyze --json", *run([*exe, "analyze", "--json", str(args.log)])[:1], n, run_rss_last())
            show(
                "report --format json", *run([*exe, "report", str(args.log), "--format", "json"])[:1], n, run_rss_last()
            )
        size = du(arc)
        rec = du(arc / "data" / "records")
        print(f"archive size: {size / 1e6:.1f} MB = {100 * size / raw:.2f} % of the raw log", end="")
        print(f"; records alone {100 * rec / raw:.2f} %")
        for table in sorted(p.name for p in (arc / "data").iterdir()):
            print(f"  {table}: {du(arc / 'data' / table) / 1e6:.2f} MB")

        big = work / "big"
        shutil.rmtree(big, ignore_errors=True)
        total = replicate(arc, big, args.replicas)
        from console.archive.store import read_current

        n_parts = len(read_current(big).parts("records"))
        print(
            f"big archive: {total:,} records ({args.replicas} replicas, {n_parts} record parts), {du(big) / 1e6:.0f} MB"
        )
        from console.archive.history import report_data
        from console.archive.presets import PRESETS
        from console.archive.reader import Window
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
        # What `trackside query` runs once its process is up: connection, views, the query, the rows.
        from console.archive.query import run_query_result

        print(f"axles per head per day (query, in process): {timed(lambda: run_query_result(big, axles_sql))}")
        print(f"one hour of one head   (query, in process): {timed(lambda: run_query_result(big, hour_sql))}")
        # A long-lived reader (a TUI, a service) keeps its connection: the query alone.
        con, _ = connect(big)
        print(f"axles per head per day (open connection)  : {timed(lambda: con.execute(axles_sql).fetchall())}")
        print(f"one hour of one head   (open connection)  : {timed(lambda: con.execute(hour_sql).fetchall())}")
        con.close()
        # Through the commands, as a user runs them: a new process each time (median of 3).
        q = [*exe, "query", "--archive", str(big), "--format", "csv"]
        print(f"trackside --version (process start)       : {median_run([*exe, '--version'])}")
        print(f"SELECT 1 (trackside query)                : {median_run([*q, 'SELECT 1'])}")
        axles_cmd = [*q, "--preset", "axles-per-head-per-day"]
        print(f"axles per head per day (trackside query)  : {median_run(axles_cmd)}")
        print(f"one hour of one head   (trackside query)  : {median_run([*q, hour_sql])}")
        if not args.skip_reports:
            day0 = dt.datetime.combine(t_first.date(), dt.time())
            w = Window(start=day0, end=day0 + dt.timedelta(days=1))
            t_report = timed(lambda: report_data(big, None, w), runs=args.report_runs)
            print(f"one-day report data (report_data)         : {t_report}")
            day1 = (day0 + dt.timedelta(days=1)).isoformat()
            rep = [*exe, "report", "--archive", str(big), "--from", day0.isoformat(), "--to", day1, "--format", "json"]
            print(f"one-day report (trackside report)         : {median_run(rep, args.report_runs)}")
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
