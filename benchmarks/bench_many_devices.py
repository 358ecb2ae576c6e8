"""Peak memory with adversarial device counts: many distinct counting heads, many GNSS devices.

Writes (once, then reuses) a diagnostic log where every record names its own
counting head, and a GNSS device CSV where every row is its own device, runs
the commands on them as fresh processes and reports wall time and peak RSS
(``wait4``'s ``ru_maxrss``), beside the input size.  A child is limited in
address space (``--limit-mb``) and time (``--timeout``) so an explosion
fails the run instead of the machine.

    python benchmarks/bench_many_devices.py --heads 1000000 --devices 1000000
    python benchmarks/bench_many_devices.py --heads 100000 --devices 100000 --profile

``--profile`` also runs each command in-process under tracemalloc and
prints the allocation sites holding the most memory at the peak (Python and
numpy allocations; Arrow's own memory pool is not traced).

Target (issue "Memory from many devices"): per-device state small and flat,
peak RSS within a small multiple (<= ~4x) of the input size, no super-linear time.

``--code DIR`` (twice: alternating) runs the commands from other checkouts,
e.g. ``git archive 43c5cc4 | tar -x -C /tmp/h7_old`` for "before".

Measured 2026-11-23 on the shared 2-core box (load average 9-14 from other
jobs all the while: times are noisy, RSS less so; a bare ``trackside
analyze`` of a tiny log peaks at 142 MB, imports included).  "before" is
43c5cc4, "after" the tree at 216977f-76147c7.

100 k heads / 100 k devices, before and after run alternately::

    python benchmarks/bench_many_devices.py --heads 100000 --devices 100000 \
        --code /tmp/h7_old --code /work/main --only analyze,analyze-text,gnss,gnss-text

    command          input                 MB in   before s / MB        after s / MB
    analyze --json   heads_100000.log       13.2     81.1 /  412          50.4 /  317
    analyze (text)   heads_100000.log       13.2    254.4 /  886          30.6 /  285
    gnss --json      devices_100000.csv      5.9     21.9 /  313          13.5 /  216
    gnss (text)      devices_100000.csv      5.9    killed at 300 s       7.8 /  228
    report (json)    heads_100000.log       13.2        -                31.8 /  801

1 M heads / 1 M devices, after (``--heads 1000000 --devices 1000000``)::

    command          input                 MB in   wall s   peak RSS MB   RSS/in
    analyze --json   heads_1000000.log     132.5     81.2          1184      8.9
    analyze (text)   heads_1000000.log     132.5     34.8          1305      9.9
    gnss --json      devices_1000000.csv    59.4     33.4           526      8.8
    gnss (text)      devices_1000000.csv    59.4     18.2           522      8.8

1 M heads / 1 M devices on an idle machine (2026-11-26, load average < 1),
at bd9337f: flat registers (``parsers/diag/registry.py``, columns per
register, names in a flat ``StringDictionary``), heads and devices as
column tables (``HeadTable``, ``DeviceTable``), GNSS devices interned flat;
the last row after a975886 (the report's GNSS unit table as flat columns,
rows made as written)::

    command          input                 MB in   wall s   CPU s  peak RSS MB  RSS/in
    analyze --json   heads_1000000.log     132.5     25.6    26.5          486     3.7
    analyze (text)   heads_1000000.log     132.5     17.5    18.3          470     3.5
    report (json)    heads_1000000.log     132.5     39.2    40.0          792     6.0
    gnss --json      devices_1000000.csv    59.4     11.6    11.8          416     7.0
    gnss (text)      devices_1000000.csv    59.4      6.6     6.7          412     6.9
    report (json)    devices_1000000.csv    59.4     57.6    57.6         1726    29.0
    report (json)    devices_1000000.csv    59.4     34.6       -          540     9.1   (after a975886)

The imports alone are 107-142 MB of each figure.  ``analyze`` is within
the <= ~4x target; ``gnss`` and ``report`` are not: the GNSS parse builds
the whole fix table before anything is derived (414 MB peak for the 1 M
device CSV in ``parse_gnss`` alone, of which the table is 124 MB: the
device categorical holds a Python string per device), and ``report`` on
the head log holds the per-head inventory and findings for its document.
Streaming the GNSS fixes (they are sorted for the crossing controller)
would be the next step.

Before, ``analyze --json`` on the 1 M-head log was killed after 400 s at
1568 MB; with only the pairing and inventory fixed it finished in 664 s at
2327 MB (the passages JSON then encoded every head's name per batch).

What the fixes were: axle pairing over all heads at once (was a loop over
heads, each a scan of every onset: heads x onsets); the device inventory
without numpy calls per device; ``DiagRegistry.arrays`` extended, not
rebuilt, per chunk; the passages JSON encodes only each batch's heads; the
head list built once; ``RegisterKey`` with slots and shared names interned;
``gnss --json`` written block by block (was one dict per fix for the whole
file); the GNSS device table, the report's GNSS units and the analyze text
tables from grouped reductions or only the rows shown (were a DataFrame per
device, or a column per device).

Then (2026-11-23), still over the target: at 1 M heads most of the memory was the
diagnostic registry's Python objects per register (a ``RegisterKey``, its
head name, the span bytes that key the register cache: ~0.5 kB a
register, against ~139 bytes of log line); flat, columnar registers in
``parsers.diag.read`` are the next step.  The counting path's per-head state
(``console/analysis/sections/stream.py``, ``counting.py``) is flat arrays
since 2026-11-26, about 120 bytes a head where it held a ``HeadCounter``
and a ``_Head`` object (1.5 kB a head; ``bench_event_stream_heads.py``):
``report`` on the 100 k-head log then took 9.4 / 9.9 s against 16.2 /
14.1 s, alternately, at the same peak (808 / 801 MB before, 826 / 822 MB
after), which is the report's JSON document.

``report`` within the target (2026-11-28, load average 5-7, base ee49b64 and 80b573c alternated)::

    command          input                 MB in   base CPU s / MB    after CPU s / MB   RSS/in
    report (json)    heads_1000000.log     132.5       28.3 /  655        30.0 /  520     3.9
    report (json)    devices_1000000.csv    59.4       23.6 /  255        23.7 /  221     3.7

pandas is no longer loaded before the report's reads (~33 MB under the GNSS read), and the diagnostic
read maps blocks from 512 kB on their own (``big_read_memory``): a million heads' growing columns had
left ~110 MB of freed heap under the read's end.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import resource
import subprocess
import sys
import threading
import time
import tracemalloc
from pathlib import Path

RECORD = (
    "Diag_id:00002\tID:{dev}\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:H{head:07d}\tch:{ch}\tAdr:026\t"
    "Label:Radsensor\tData:{data}\tDate:2026-03-02\tTime:{hh:02d}:{mm:02d}:{ss:02d}.{ms:03d}\n"
)


def write_heads_log(path: Path, heads: int) -> None:
    """One wheel-sensor record per counting head: every line is a new head (the adversarial case)."""
    with path.open("w", encoding="utf-8") as f:
        batch = []
        for i in range(heads):
            t_ms = i * 7  # increasing times, several records a second
            s, ms = divmod(t_ms, 1000)
            batch.append(
                RECORD.format(
                    dev=4000 + i % 60000,
                    head=i,
                    ch=1 + i % 2,
                    data=i % 2,
                    hh=(s // 3600) % 24,
                    mm=(s // 60) % 60,
                    ss=s % 60,
                    ms=ms,
                )
            )
            if len(batch) == 10000:
                f.write("".join(batch))
                batch.clear()
        f.write("".join(batch))


def write_devices_csv(path: Path, devices: int) -> None:
    """One fix per GNSS device: every row a new device."""
    with path.open("w", encoding="utf-8") as f:
        f.write("time,device,role,lat,lon,speed\n")
        batch = []
        for i in range(devices):
            s = i // 10
            batch.append(
                f"2026-01-19T{(s // 3600) % 24:02d}:{(s // 60) % 60:02d}:{s % 60:02d}Z,D{i:07d},"
                f"{'head' if i % 2 == 0 else 'eot'},{20.6 + (i % 1000) * 1e-5:.7f},{105.9 + (i % 997) * 1e-5:.7f},"
                f"{(i % 60) + 0.5}\n"
            )
            if len(batch) == 10000:
                f.write("".join(batch))
                batch.clear()
        f.write("".join(batch))


def run(
    cmd: list[str], limit_mb: int, timeout_s: float, env: dict[str, str] | None = None
) -> tuple[float, float, float, int, str]:
    """(wall s, CPU s (user + system), peak RSS MB, exit code, stderr tail) of one child; stdout discarded.
    CPU time is what to compare on a machine shared with other jobs."""

    def limit() -> None:
        limit_bytes = limit_mb << 20
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=limit, env=env)
    assert proc.stderr is not None
    deadline = t0 + timeout_s
    while True:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            break
        if time.perf_counter() > deadline:
            proc.kill()
            pid, status, usage = os.wait4(proc.pid, 0)
            break
        time.sleep(0.05)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode("utf-8", "replace")
    code = os.waitstatus_to_exitcode(status)
    if wall > timeout_s:
        err = f"killed after {timeout_s:.0f} s; " + err
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, code, err.strip()[-300:]


def profile(argv: list[str], top: int = 12) -> None:
    """Run one command in-process under tracemalloc; print the allocation sites at the peak."""
    from console.cli.app import app

    tracemalloc.start(8)
    tracemalloc.reset_peak()
    best: list[tracemalloc.Snapshot | int] = [0]
    done = threading.Event()

    def sample() -> None:
        # A snapshot whenever the traced total passes the last one's by 10 %: the last is near the peak.
        while not done.wait(0.2):
            current, _ = tracemalloc.get_traced_memory()
            if current > 1.1 * float(best[-1] if isinstance(best[-1], int) else 0):
                best[:] = [tracemalloc.take_snapshot(), current]

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    quiet = io.StringIO()
    with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet), contextlib.suppress(SystemExit):
        app(argv, standalone_mode=False)
    done.set()
    sampler.join()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(f"  tracemalloc: peak {peak / 2**20:.0f} MB traced")
    if len(best) < 2:
        return
    snapshot, at = best
    assert isinstance(snapshot, tracemalloc.Snapshot) and isinstance(at, int)
    print(f"  largest sites held when {at / 2**20:.0f} MB were traced (file:line, MB, blocks):")
    for stat in snapshot.statistics("lineno")[:top]:
        frame = stat.traceback[0]
        print(f"    {frame.filename.split('/work/main/')[-1]}:{frame.lineno}  {stat.size / 2**20:.1f} MB  {stat.count}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--heads", type=int, default=1_000_000, help="distinct counting heads (records) in the log")
    ap.add_argument("--devices", type=int, default=1_000_000, help="distinct GNSS devices (rows) in the CSV")
    ap.add_argument("--dir", type=Path, default=Path("/tmp/trackside_many_devices"))
    ap.add_argument("--limit-mb", type=int, default=6144, help="address-space limit of each child")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds before a child is killed")
    ap.add_argument("--profile", action="store_true", help="also profile each command in-process (tracemalloc)")
    ap.add_argument(
        "--only", default="", help="comma-separated commands to run: analyze, analyze-text, gnss, gnss-text, report"
    )
    ap.add_argument(
        "--code",
        type=Path,
        action="append",
        default=[],
        help="run the commands from this checkout (e.g. a `git archive` of an older commit); "
        "given twice or more, each command alternates between them",
    )
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    exe = str(Path(sys.executable).with_name("trackside"))
    runner = "import sys; from console.cli.app import app; sys.argv[0] = 'trackside'; app()"
    codes: list[Path | None] = list(args.code) or [None]

    jobs = []
    if args.heads:
        log = args.dir / f"heads_{args.heads}.log"
        if not log.exists():
            write_heads_log(log, args.heads)
        jobs += [
            ("analyze", ["analyze", str(log), "--json"], log),
            ("analyze (text)", ["analyze", str(log)], log),
            ("report", ["report", str(log), "--format", "json"], log),
        ]
    if args.devices:
        csv = args.dir / f"devices_{args.devices}.csv"
        if not csv.exists():
            write_devices_csv(csv, args.devices)
        jobs += [
            ("gnss", ["gnss", str(csv), "--json"], csv),
            ("gnss (text)", ["gnss", str(csv)], csv),
            ("report", ["report", str(csv), "--format", "json"], csv),
        ]

    print(
        f"{'command':<16} {'input':>28} {'MB in':>7} {'wall s':>7} {'CPU s':>7} {'peak RSS MB':>12} {'RSS/in':>7}"
        "  exit  code"
    )
    wanted = {w.strip() for w in args.only.split(",") if w.strip()}
    profiled = []
    for name, argv, path in jobs:
        if wanted and name.replace(" (text)", "-text") not in wanted:
            continue
        size_mb = path.stat().st_size / 2**20
        for code in codes:
            cmd = [exe, *argv] if code is None else [sys.executable, "-P", "-c", runner, *argv]  # -P: not the cwd first
            env = None if code is None else {**os.environ, "PYTHONPATH": str(code)}
            wall, cpu, rss_mb, rc, err = run(cmd, args.limit_mb, args.timeout, env)
            print(
                f"{name:<16} {path.name:>28} {size_mb:7.1f} {wall:7.1f} {cpu:7.1f} {rss_mb:12.0f}"
                f" {rss_mb / size_mb:7.1f}  {rc:4d}"
                + f"  {code or 'installed'}"
                + (f"  {err}" if rc not in (0, 1) else ""),
                flush=True,
            )
        if args.profile:
            profiled.append(argv)
    # Profiled last: a child forked from a parent grown by a profile reports the parent's RSS as its peak.
    for argv in profiled:
        print(f"profile: trackside {' '.join(argv)}")
        profile(argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
