"""Inputs for looking at the HTML report's plots over 1 day, 2 years and 10 years of data (run by hand).

A simulated run's diagnostic log (``trackside simulate``) copied onto dates spread over the span, one copy
every ``--every`` days; its layout beside it.  Then, e.g.::

    python benchmarks/report_spans.py /tmp/span10 --years 10 --every 14
    trackside report /tmp/span10 --format html -o /tmp/span10.html
    chromium --headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run \\
        --screenshot=/tmp/span10.png --window-size=1200,2000 file:///tmp/span10.html
"""

from __future__ import annotations

import argparse
import datetime as dt
import shutil
import subprocess
import sys
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--years", type=float, default=0.0, help="span of the copies (0: the run alone, one day)")
    ap.add_argument("--every", type=int, default=7, help="days between copies")
    ap.add_argument("--duration", default="2h", help="the simulated run's length")
    a = ap.parse_args()
    run = a.out.with_name(a.out.name + "-run")
    shutil.rmtree(run, ignore_errors=True)
    trackside = Path(sys.executable).with_name("trackside")
    cmd = [str(trackside), "simulate", "-o", str(run), "--duration", a.duration, "--fault", "dead_channel:WS3:90m"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    a.out.mkdir(parents=True, exist_ok=True)
    shutil.copy(run / "layout.toml", a.out / "layout.toml")
    text = (run / "diagnostic.log").read_text(encoding="utf-8")
    first = dt.date(2026, 3, 2)
    days = int(a.years * 365.25)
    with (a.out / "diagnostic.log").open("w", encoding="utf-8") as out:
        for k in range(-days, 1, a.every):
            out.write(text.replace("Date:2026-03-02", f"Date:{first + dt.timedelta(days=k)}"))
    print(a.out)


if __name__ == "__main__":
    main()
