"""Logs damaged the ways loggers and boards damage them never show a section clear with an axle inside.

Checked by hand (2026-11-29) on the example log and on simulated hours, against the simulator's truth of where
the axles are; each kept here as a property so that it stays so:

* a logger that wrote a buffer twice (a block of lines repeated within one file: up to 2 s of records the
  counting reads as the same records, more is a clock step);
* a board whose date is wrong on some of its records (1970 or 2000 after a battery loss, a day off),
  interleaved with its good ones;
* a head's id with stray whitespace or another case (``ws3``: a head the layout does not know, so the
  layout's WS3 is not heard and its sections hold);
* a block of lines lost mid-file is not here: a head's records missing without a trace are axles missed, as
  a real counter misses them (the count shows it at the next head: underflow, or occupied for good).

``LOG_FAULT_EXAMPLES`` runs more examples by hand.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import random
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from console.cli.app import app
from console.layout import load_layout

_STAMP = re.compile(r"Date:(\S+)\tTime:(\S+)")
HEADS = ["WS1", "WS2", "WS3", "WS4", "WS5"]


def _ns(iso_text: str) -> int:
    return int(np.datetime64(iso_text.rstrip("Z"), "ns").astype(np.int64))


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> list[tuple[Path, dict[str, list[tuple[int, int]]], int]]:
    """Simulated hours (trains both ways, the example layout): each run's directory, its true axles per section
    (a step function in ns) and its end."""
    from console.sim.line_values import SimConfig
    from console.sim.station import StationSim
    from console.sim.writers import write_run

    root = tmp_path_factory.mktemp("faults")
    out = []
    for seed in range(1, 4):
        sim = StationSim(load_layout("example"), SimConfig(seed=seed, trains_per_hour=12))
        sim.run(3600)
        write_run(sim, root / f"run{seed}")
        truth = json.loads((root / f"run{seed}" / "truth.json").read_text("utf-8"))
        inside = {s: [(_ns(t), int(n)) for t, n in rows] for s, rows in truth["sections"].items()}
        out.append((root / f"run{seed}", inside, _ns(truth["end"])))
    return out


def _redated(line: str, how: str) -> str:
    m = _STAMP.search(line)
    assert m is not None
    day = dt.date.fromisoformat(m[1])
    day = {"1970": day.replace(year=1970), "2000": day.replace(year=2000)}.get(how) or day + dt.timedelta(
        days=1 if how == "+1d" else -1
    )
    return line.replace(m[0], f"Date:{day}\tTime:{m[2]}")


def _damaged(lines: list[str], fault: str, head: str, rng: random.Random) -> list[str]:
    if fault == "buffer_twice":
        i, n = rng.randrange(len(lines)), rng.choice([1, 4, 8, 16, 40, 120])
        return lines[: i + n] + lines[i : i + n] + lines[i + n :]
    if fault.startswith("date"):
        how = fault.split(":")[1]
        return [_redated(x, how) if f"Trackinfo:{head}\t" in x and rng.random() < 0.1 else x for x in lines]
    name = {"case": head.lower(), "space_after": head + " ", "space_before": " " + head}[fault]
    return [x.replace(f"Trackinfo:{head}\t", f"Trackinfo:{name}\t") for x in lines]


FAULTS = ["buffer_twice", "date:1970", "date:2000", "date:+1d", "date:-1d", "case", "space_after", "space_before"]


@settings(max_examples=int(os.environ.get("LOG_FAULT_EXAMPLES", "16")), deadline=None)
@given(pick=st.integers(0, 2), head=st.sampled_from(HEADS), fault=st.sampled_from(FAULTS), seed=st.integers(0, 999))
def test_a_damaged_log_never_shows_a_section_clear_with_an_axle_inside(
    runs: list[tuple[Path, dict[str, list[tuple[int, int]]], int]],
    tmp_path_factory: pytest.TempPathFactory,
    pick: int,
    head: str,
    fault: str,
    seed: int,
) -> None:
    run, inside, end_ns = runs[pick]
    lines = (run / "diagnostic.log").read_text("utf-8").splitlines(keepends=True)
    log = tmp_path_factory.mktemp("damaged") / "diagnostic.log"
    log.write_text("".join(_damaged(lines, fault, head, random.Random(seed))), "utf-8")
    res = CliRunner().invoke(app, ["sections", str(log), "--layout", str(run / "layout.toml"), "--json"])
    assert res.exit_code == 0, res.output
    timeline = json.loads(res.stdout)["timeline"]
    for sid, steps in inside.items():
        rows = sorted((_ns(r["time"]), r["state"]) for r in timeline if r["section"] == sid)
        for (t0, state), (t1, _) in zip(rows, [*rows[1:], (end_ns + 1, "")], strict=True):
            if state != "clear" or t0 > end_ns:
                continue  # rows a day late (a board's date a day ahead) are past the truth's end
            held = [n for t, n in steps if t <= t0][-1:] + [n for t, n in steps if t0 < t < min(t1, end_ns + 1)]
            assert max(held, default=0) == 0, f"{sid} clear from {t0} to {t1} with axles inside ({fault} {head})"
