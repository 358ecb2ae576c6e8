"""Memory and CPU the event stream (the counting path of sections, health, report) holds per counting head.

An adversarial log for the counting path: N heads with one wheel record
each (every other one a lone onset, so each head also leaves a pulse to
settle), fed to :class:`console.analysis.sections.stream.EventStream` in
batches of 10 000 records as ``stream_jobs`` feeds it, released after each
batch.  Prints the memory the stream holds after the last batch
(tracemalloc: Python and numpy allocations) and the CPU time.

    python benchmarks/bench_event_stream_heads.py 100000
    python benchmarks/bench_event_stream_heads.py 1000000 --code /tmp/old_checkout

Measured 2026-11-26 on the shared 2-core machine (load 5-7 from other jobs):

    heads      before (HeadCounter + _Head per head, heap)    after (flat arrays, CounterBank)
    100 000    148.4 MB (1556 B/head), 22.0 CPU s              11.2 MB (118 B/head), 0.3 CPU s
    1 000 000  not done in 1200 s (killed)                      85.4 MB  (90 B/head), 3.6 CPU s
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

BATCH = 10_000


def measure(n: int) -> str:
    from console.analysis.diag_events import DiagEventSettings
    from console.analysis.sections.stream import EventStream

    heads = [(4000 + i % 60000, f"H{i:07d}") for i in range(n)]
    wheel = {
        "head": np.arange(n, dtype=np.int64),
        "channel": (1 + np.arange(n) % 2).astype(np.int16),
        "time_ns": np.arange(n, dtype=np.int64) * 7_000_000,  # several records a second
        "value": (np.arange(n) % 2).astype(np.int8),
        "subsecond": np.ones(n, bool),
    }
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    t0 = time.process_time()
    stream = EventStream(None, DiagEventSettings())
    release = getattr(stream, "release_block", stream.release)  # an older checkout has release only
    for lo in range(0, n, BATCH):
        stream.add({c: v[lo : lo + BATCH] for c, v in wheel.items()}, None, heads)
        release(int(wheel["time_ns"][min(lo + BATCH, n - 1)]))
    held = tracemalloc.get_traced_memory()[0] - base
    getattr(stream, "finish_block", stream.finish)()
    cpu = time.process_time() - t0
    return f"{n} heads: {held / 2**20:.1f} MB held by the stream ({held / n:.0f} B/head), {cpu:.1f} CPU s"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("heads", type=int)
    ap.add_argument("--code", type=Path, help="run from this checkout instead (a fresh process)")
    args = ap.parse_args()
    if args.code is None:
        print(measure(args.heads))
        return
    # -P: not the cwd first; the checkout's console, this script's measure().
    env = {**os.environ, "PYTHONPATH": f"{args.code}:{Path(__file__).parent}"}
    launch = f"from bench_event_stream_heads import measure; print(measure({args.heads}))"
    subprocess.run([sys.executable, "-P", "-c", launch], check=True, env=env)


if __name__ == "__main__":
    main()
