"""Diagnostic records as they reach a maintainer by other hands: tabs turned into spaces (copied from an e-mail,
a PDF or a terminal) and a decimal comma in the time (an export in a German locale).  Each reads as the export
itself does: the same records at the same times, the same passages (`analyze --json`)."""

from __future__ import annotations

import json
import random
import re
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from benchmarks.gen_realistic_diag import generate
from console.cli.app import app
from parsers.diag.read import read_diag
from tests.conftest import SAMPLES

runner = CliRunner()
KEPT = ["time", "device_id", "counting_head", "channel", "address", "label", "value", "subsecond", "line"]


def _spaced(line: str, rng: random.Random) -> str:
    """Each tab as 1-4 spaces (or kept: a line half copied)."""
    return re.sub("\t", lambda _: rng.choice(["\t", " ", "  ", "    "]), line)


def _comma(line: str) -> str:
    return re.sub(r"(Time:\d\d:\d\d:\d\d)\.", r"\1,", line)


@pytest.mark.parametrize("shape", ["spaces", "comma", "both"])
def test_a_copied_export_reads_as_the_export(tmp_path: Path, shape: str) -> None:
    log = tmp_path / "export.log"
    generate(4000, log, boards=6, resolution="mixed", seed=48, corrupt=False, block_s=120)
    rng = random.Random(48)
    lines = log.read_text(encoding="utf-8").splitlines()
    if shape in ("comma", "both"):
        lines = [_comma(line) for line in lines]
    if shape in ("spaces", "both"):
        lines = [_spaced(line, rng) for line in lines]
    copied = tmp_path / "copied.log"
    copied.write_text("\r\n".join(lines) + "\r\n", encoding="utf-8")  # and CRLF, as a Windows mailer writes

    want, want_report = read_diag([log])
    got, got_report = read_diag([copied])
    assert got_report.rejected == want_report.rejected == 0
    assert want["subsecond"].any() and not want["subsecond"].all()
    pd.testing.assert_frame_equal(got[KEPT].reset_index(drop=True), want[KEPT].reset_index(drop=True))

    def passages(path: Path) -> list[dict[str, object]]:
        res = runner.invoke(app, ["analyze", str(path), "--json"])
        assert res.exit_code == 0, res.output
        return list(json.loads(res.stdout)["passages"])

    assert passages(copied) == passages(log) != []


def test_the_papers_excerpt_pasted_with_spaces_gives_its_speed(tmp_path: Path) -> None:
    """The Osong excerpt (Kim et al.) as a PDF gives it: spaces for tabs.  15.9 km/h as from the tab-separated
    sample (v = 0.13 m × 34 records/s)."""
    text = (SAMPLES / "osong_ws4_0932_detection.log").read_text(encoding="utf-8")
    pasted = tmp_path / "pasted.log"
    pasted.write_text(re.sub("\t", " ", text), encoding="utf-8")
    res = runner.invoke(app, ["analyze", str(pasted), "--json"])
    assert res.exit_code == 0, res.output
    (p,) = json.loads(res.stdout)["passages"]
    assert p["records_in_detection_second"] == 34
    assert round(p["speed_kmh_per_second_method"], 1) == 15.9


def test_spaces_do_not_make_a_record_of_a_line_that_is_none(tmp_path: Path) -> None:
    """Fields out of order, one missing or an unknown key: still rejected, with the shape's reason."""
    good = (SAMPLES / "osong_ws4_0932_passage.log").read_text(encoding="utf-8").splitlines()[0].replace("\t", " ")
    bad = [
        good.replace("Device:IM ", ""),  # a field missing
        good.replace("ch:1 Adr:018", "Adr:018 ch:1"),  # two swapped
        good.replace("GS:", "Gs:"),  # a key misspelt
    ]
    log = tmp_path / "bad.log"
    log.write_text("\n".join([good, *bad]) + "\n", encoding="utf-8")
    df, report = read_diag([log])
    assert len(df) == 1 and report.rejected == 3
    assert all("tab-separated Key:Value fields" in r.reason for r in report.rejections)
