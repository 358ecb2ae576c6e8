"""Cut one export at many points (a rotation by size, nothing repeated) and count the cuts the overlap rule
misreads: the two files must give the axles of the whole.

    python benchmarks/overlap_cuts.py [--step 7] [--records 12000]

The export is benchmarks/gen_realistic_diag.py's 12-board log (µs, ms and whole-second boards interleaved),
as tests/test_whole_second.py uses it.  Each cut is read in both orders.  A cut that only bytes can tell from
a repeat (the file's first lines are two identical wheels of the one head writing) is misread by any rule.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.gen_realistic_diag import generate
from console.analysis.passages.speed_settings import SpeedSettings
from tests.reads import whole_job


def axles(files: list[Path]) -> Counter[str]:
    job = whole_job(files, SpeedSettings())
    out: Counter[str] = Counter()
    for p in job.analysis.passages_json():
        out[p["counting_head"]] += p["axles"]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--step", type=int, default=7, help="cut every STEP lines")
    ap.add_argument("--records", type=int, default=12_000)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        export = d / "export.log"
        generate(args.records, export, boards=12, seed=5, interleave_seed=6, corrupt=False)
        lines = export.read_bytes().splitlines(keepends=True)
        whole = axles([export])
        a, b = d / "a.log", d / "b.log"
        cuts = range(3, len(lines), args.step)
        misread = []
        for k in cuts:
            a.write_bytes(b"".join(lines[:k]))
            b.write_bytes(b"".join(lines[k:]))
            got = [axles(files) for files in ([a, b], [b, a])]
            if any(g != whole for g in got):
                misread.append((k, {h: (got[0][h], whole[h]) for h in whole if got[0][h] != whole[h]}))
        print(f"{len(lines)} lines, {sum(whole.values())} axles; {len(cuts)} cuts, {len(misread)} misread")
        for k, diff in misread:
            print(f"  cut after line {k}: {diff}")


if __name__ == "__main__":
    main()
