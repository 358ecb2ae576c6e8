"""Where an ingest's memory goes, over time: RSS against glibc's heap, Arrow and the ingest's phases.

Runs one ingest in this process (as ``trackside ingest`` does: one malloc heap, set before pyarrow
loads) while a thread samples, every ``--every`` seconds: VmRSS; glibc's heap (``mallinfo2``: its size,
the bytes in use and the bytes free inside it, and the large blocks mapped on their own); Arrow's
allocated bytes; the bytes read; the part files open.  Each phase's end is printed as it comes, and the
head_days aggregates (the derivation's DuckDB step) get their own peak.  The sampler adds a little.

    python -m benchmarks.ingest_rss_phases r12m.log /tmp/arc --every 0.5 --peaks

Read it so: RSS growing with ``free`` inside the heap is fragmentation (pages the heap keeps); growing
with ``used`` is memory held.  Figures: docs in the ingest notes (issue 22).
"""

from __future__ import annotations

import argparse
import ctypes
import resource
import shutil
import sys
import threading
import time
from pathlib import Path
from typing import Any

from console.memory import one_malloc_arena


class _MallInfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks")
    ] + [("keepcost", ctypes.c_size_t)]


def _heap() -> str:
    try:
        info = ctypes.CDLL(None).mallinfo2
    except (OSError, AttributeError):
        return "heap=?"
    info.restype = _MallInfo2
    m = info()
    mb = 1 << 20
    return f"heap={m.arena // mb} used={m.uordblks // mb} free={m.fordblks // mb} mapped={m.hblkhd // mb}"


def _rss_mb() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) // 1024
    return 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("log", type=Path)
    ap.add_argument("archive", type=Path, help="a fresh archive directory (removed first)")
    ap.add_argument("--every", type=float, default=0.5, help="seconds between samples printed")
    ap.add_argument(
        "--peaks",
        action="store_true",
        help="also print a line at each new peak of the read (after start-up): where the peak sits in the input",
    )
    args = ap.parse_args()

    one_malloc_arena()  # as the ingest command does, before pyarrow is imported
    import pyarrow as pa

    from console.archive import derive, ingest, ingest_summary, parts

    shutil.rmtree(args.archive, ignore_errors=True)
    writers: list[Any] = []
    state: dict[str, Any] = {"phase": "read", "bytes": 0, "peak": 0, "step_peak": 0}
    t0 = time.perf_counter()

    init = parts.PartWriter.__init__

    def counted_init(self: Any, *a: Any, **k: Any) -> None:
        init(self, *a, **k)
        writers.append(self)

    lap = ingest_summary.PhaseClock.lap

    def marked_lap(self: Any, name: str) -> None:
        lap(self, name)
        state["phase"] = f"after {name}"
        print(f"{time.perf_counter() - t0:7.1f}s  end of {name}: rss={_rss_mb()} MB", flush=True)

    derive_days = derive.derive_days

    def marked_derive_days(*a: Any, **k: Any) -> Any:
        state["step_peak"] = 0
        out = derive_days(*a, **k)
        print(f"{time.perf_counter() - t0:7.1f}s  head_days aggregates: peak {state['step_peak']} MB", flush=True)
        return out

    parts.PartWriter.__init__ = counted_init  # type: ignore[method-assign]
    ingest_summary.PhaseClock.lap = marked_lap  # type: ignore[method-assign]
    derive.derive_days = marked_derive_days

    stop = threading.Event()

    def sample() -> None:
        last = 0.0
        while not stop.is_set():
            rss = _rss_mb()
            now = time.perf_counter() - t0
            if args.peaks and rss > state["peak"] and state["phase"] == "read" and state["bytes"]:
                print(
                    f"{now:7.1f}s new peak rss={rss} MB {_heap()} arrow={pa.total_allocated_bytes() >> 20} "
                    f"read={state['bytes'] >> 20} MB open_parts={sum(len(w._writers) for w in writers)}",
                    flush=True,
                )
            state["peak"] = max(state["peak"], rss)
            state["step_peak"] = max(state["step_peak"], rss)
            if now - last >= args.every:
                last = now
                open_files = sum(len(w._writers) for w in writers)
                print(
                    f"{now:7.1f}s rss={rss} MB {_heap()} arrow={pa.total_allocated_bytes() >> 20} "
                    f"read={state['bytes'] >> 20} MB open_parts={open_files} {state['phase']}",
                    flush=True,
                )
            time.sleep(0.05)

    def on_bytes(n: int) -> None:
        state["bytes"] += n

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    summary = ingest.run_ingest([args.log], args.archive, on_bytes=on_bytes)
    stop.set()
    thread.join()
    ru = resource.getrusage(resource.RUSAGE_SELF)
    phases = {k: round(v, 2) for k, v in summary.phases.items()}
    print(
        f"peak {state['peak']} MB (ru_maxrss {ru.ru_maxrss >> 10} MB); CPU {ru.ru_utime + ru.ru_stime:.2f} s; {phases}"
    )


if __name__ == "__main__":
    sys.exit(main())
