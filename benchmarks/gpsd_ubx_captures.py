"""u-blox epochs gpsd decodes in its regression captures, and how many ``trackside gnss`` matches.

gpsd's ``test/daemon`` keeps, for each receiver capture ``X.log``, the
decoding ``X.log.chk`` (the TPV reports).  An epoch is a distinct TPV time
with ``mode`` >= 2 and a position; it matches when one of our rows has its
time, one of gpsd's positions for it within 1e-6° and, where both give one,
one of its speeds within 0.01 m/s (``tests/gpsd_truth.py``).  Two columns:

* ``matched``: by any row (the fix table's decoding, whatever our verdict
  on the fix);
* ``valid``: by a row we call a fix (``valid``).  gpsd reports a fix where
  the receiver's gnssFixOK flag is clear or the fix is time-only; we do not.

The captures are read with ``parsers.gnss_files.parse_gnss``, the reader of
``trackside gnss``, ``crossing``, ``report`` and the archive.  The
SiRF-mode capture (``ublox-sirf1``) is left aside: it is SiRF binary.

Get the captures (gpsd is BSD-2-Clause) into a directory, e.g. from a clone
of gpsd: ``cp gpsd/test/daemon/ublox*.log* CAPTURES/``, then::

    python benchmarks/gpsd_ubx_captures.py CAPTURES [--markdown]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from parsers.gnss_files import parse_gnss  # noqa: E402
from tests.gpsd_truth import compare_with_gpsd  # noqa: E402


def captures(directory: Path) -> list[Path]:
    """The u-blox captures with gpsd's decoding beside them, the SiRF-mode one aside."""
    return sorted(
        p for p in directory.glob("ublox*.log") if p.with_name(p.name + ".chk").is_file() and "sirf" not in p.name
    )


def measure(log: Path) -> dict[str, float]:
    t0 = time.perf_counter()
    fixes, _report, _ = parse_gnss([log])
    seconds = time.perf_counter() - t0
    valid = compare_with_gpsd(log, fixes)
    every = fixes.copy()
    every["valid"] = True
    anyrow = compare_with_gpsd(log, every)
    return {
        "epochs": anyrow["nmea"] + anyrow["binary"],
        "matched": anyrow["nmea_matched"] + anyrow["binary_matched"],
        "valid": valid["nmea_matched"] + valid["binary_matched"],
        "extra": valid["extra"],
        "rows": len(fixes),
        "seconds": seconds,
        "bytes": log.stat().st_size,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("directory", type=Path, help="gpsd's test/daemon captures (ublox*.log with .chk)")
    ap.add_argument("--markdown", action="store_true", help="a Markdown table")
    a = ap.parse_args(argv)
    logs = captures(a.directory)
    if not logs:
        print(f"no ublox*.log with a .chk in {a.directory}", file=sys.stderr)
        return 2
    print(f"$ python benchmarks/gpsd_ubx_captures.py {a.directory}" + (" --markdown" if a.markdown else ""))
    head = ("capture", "matched", "valid", "extra valid rows", "rows", "parse s")
    if a.markdown:
        print("| " + " | ".join(head) + " |")
        print("|---|---:|---:|---:|---:|---:|")
    else:
        print(f"{head[0]:34} {head[1]:>11} {head[2]:>11} {head[3]:>16} {head[4]:>6} {head[5]:>8}")
    total = {"epochs": 0.0, "matched": 0.0, "valid": 0.0, "extra": 0.0, "rows": 0.0, "seconds": 0.0, "bytes": 0.0}
    for log in logs:
        m = measure(log)
        for k in total:
            total[k] += m[k]
        name = log.name.removesuffix(".log")
        cells = (
            name,
            f"{m['matched']:.0f} / {m['epochs']:.0f}",
            f"{m['valid']:.0f} / {m['epochs']:.0f}",
            f"{m['extra']:.0f}",
            f"{m['rows']:.0f}",
            f"{m['seconds']:.2f}",
        )
        if a.markdown:
            print("| " + " | ".join(cells) + " |")
        else:
            print(f"{cells[0]:34} {cells[1]:>11} {cells[2]:>11} {cells[3]:>16} {cells[4]:>6} {cells[5]:>8}")
    n = total["epochs"]
    print(
        f"{len(logs)} captures: {total['matched']:.0f} / {n:.0f} epochs matched ({100 * total['matched'] / n:.1f} %), "
        f"{total['valid']:.0f} by a valid row ({100 * total['valid'] / n:.1f} %); "
        f"{total['extra']:.0f} valid rows where gpsd reports no fix; "
        f"{total['bytes'] / 1e6:.2f} MB parsed in {total['seconds']:.2f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
