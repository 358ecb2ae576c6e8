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
peak RSS within a small multiple of the input size.
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


def run(cmd: list[str], limit_mb: int, timeout_s: float) -> tuple[float, float, int, str]:
    """(wall s, peak RSS MB, exit code, stderr tail) of one child; stdout discarded."""

    def limit() -> None:
        limit_bytes = limit_mb << 20
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, preexec_fn=limit)
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
    return wall, usage.ru_maxrss / 1024, code, err.strip()[-300:]


def profile(argv: list[str], top: int = 12) -> None:
    """Run one command in-process under tracemalloc; print the allocation sites at the peak."""
    from console.cli import app

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
    ap.add_argument("--only", default="", help="comma-separated commands to run: analyze, analyze-text, gnss")
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    exe = str(Path(sys.executable).with_name("trackside"))

    jobs = []
    if args.heads:
        log = args.dir / f"heads_{args.heads}.log"
        if not log.exists():
            write_heads_log(log, args.heads)
        jobs += [
            ("analyze", ["analyze", str(log), "--json"], log),
            ("analyze (text)", ["analyze", str(log)], log),
        ]
    if args.devices:
        csv = args.dir / f"devices_{args.devices}.csv"
        if not csv.exists():
            write_devices_csv(csv, args.devices)
        jobs += [("gnss", ["gnss", str(csv), "--json"], csv)]

    print(f"{'command':<16} {'input':>28} {'MB in':>7} {'wall s':>7} {'peak RSS MB':>12} {'RSS/in':>7}  exit")
    wanted = {w.strip() for w in args.only.split(",") if w.strip()}
    for name, argv, path in jobs:
        if wanted and name.replace(" (text)", "-text") not in wanted:
            continue
        size_mb = path.stat().st_size / 2**20
        wall, rss_mb, code, err = run([exe, *argv], args.limit_mb, args.timeout)
        print(
            f"{name:<16} {path.name:>28} {size_mb:7.1f} {wall:7.1f} {rss_mb:12.0f} {rss_mb / size_mb:7.1f}  {code}"
            + (f"  {err}" if code not in (0, 1) else "")
        )
        if args.profile:
            profile(argv)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
