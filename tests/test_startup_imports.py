"""A first run on a small file pays for start-up, not for libraries it does not use: what `analyze`,
`gnss` and `query` import on tiny inputs.  Times are measured by benchmarks/bench_startup.py (not here:
no timed unit tests); this checks the imports that decide them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
# Heavy modules, and the one command face that may need each.
HEAVY = ("pandas", "pydantic", "duckdb", "rich.progress", "console.fleet.engine", "distributed", "shapely", "textual")
PROBE = """
import json, sys
from console.cli.app import app
sys.argv = ["trackside", *sys.argv[1:]]
try:
    app()
except SystemExit as exc:
    code = exc.code
sys.stdout = sys.__stdout__
print(json.dumps({"code": code, "loaded": sorted(m for m in %r if m in sys.modules)}))
"""


def _loaded(*args: str) -> tuple[int, list[str]]:
    out = subprocess.run(
        [sys.executable, "-c", PROBE % (HEAVY,), *args], capture_output=True, text=True, timeout=120, check=False
    )
    last = out.stdout.strip().splitlines()[-1]
    doc = json.loads(last)
    return doc["code"], doc["loaded"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("tiny")
    log = d / "tiny.log"
    log.write_bytes((SAMPLES / "osong_ws4_0932_passage.log").read_bytes())
    nmea = d / "tiny.nmea"
    nmea.write_bytes(b"$GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*44\n")
    archive = d / "archive"
    subprocess.run(
        [str(Path(sys.executable).with_name("trackside")), "ingest", str(log), "--archive", str(archive)],
        check=True,
        capture_output=True,
        timeout=120,
    )
    return {"log": log, "nmea": nmea, "archive": archive}


def test_help_imports_nothing_heavy() -> None:
    assert _loaded("--help") == (0, [])


def test_analyze_of_a_small_log_imports_no_pandas(tiny: dict[str, Path]) -> None:
    assert _loaded("analyze", str(tiny["log"])) == (0, [])


def test_analyze_json_of_a_big_log_imports_neither_arrow_nor_rich(tmp_path: Path) -> None:
    """A script's `analyze --json` (stderr no terminal) of a log big enough for a progress bar: the compiled
    tokenizer needs no Arrow, and no bar is shown, so neither is loaded (~50 ms of start-up)."""
    from parsers.diag.read import compiled_tokenizer

    if not compiled_tokenizer():
        pytest.skip("the numpy tokenizer reads through Arrow")
    from console.progress import MIN_BYTES_FOR_PROGRESS

    log = tmp_path / "big.log"
    one = (SAMPLES / "osong_ws4_0932_passage.log").read_bytes()
    log.write_bytes(one * (MIN_BYTES_FOR_PROGRESS // len(one) + 1))
    probe = PROBE.replace("%r", repr(("pyarrow", "rich", "pandas")))
    out = subprocess.run(
        [sys.executable, "-c", probe, "analyze", "--json", str(log)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert json.loads(out.stdout.strip().splitlines()[-1]) == {"code": 0, "loaded": []}


def test_gnss_of_a_small_capture_imports_no_pandas(tiny: dict[str, Path]) -> None:
    assert _loaded("gnss", str(tiny["nmea"])) == (0, [])


def test_query_imports_duckdb_and_nothing_else_heavy(tiny: dict[str, Path]) -> None:
    args = ("query", "--archive", str(tiny["archive"]), "SELECT count(*) FROM records")
    assert _loaded(*args) == (0, ["duckdb"])


def test_report_reads_gnss_fixes_before_it_imports_pandas() -> None:
    """The report's GNSS read ran under pandas once (~35 MB of a million-device CSV's peak): pandas is
    imported where the report uses it, after the fixes are read."""
    probe = """
import json, sys
import parsers.gnss_files as gnss_files
from console.cli.app import app
read = gnss_files.parse_gnss_columns
seen = []
def parse(*args, **kwargs):
    seen.append("pandas" in sys.modules)
    return read(*args, **kwargs)
gnss_files.parse_gnss_columns = parse
sys.argv = ["trackside", "report", "--format", "json", sys.argv[1]]
try:
    app()
except SystemExit as exc:
    code = exc.code
sys.stdout = sys.__stdout__
print(json.dumps({"code": code, "pandas_at_read": seen, "pandas_at_end": "pandas" in sys.modules}))
"""
    out = subprocess.run(
        [sys.executable, "-c", probe, str(SAMPLES / "gnss_devices.csv")],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    doc = json.loads(out.stdout.strip().splitlines()[-1])
    # Read once, without pandas; the unit table then loads it (the check that the probe sees the import).
    assert doc == {"code": 0, "pandas_at_read": [False], "pandas_at_end": True}


def test_crossing_and_the_report_of_its_fixes_import_no_scipy(tmp_path: Path) -> None:
    """The crossing timelines' hindsight smoother came from filterpy, whose package imports scipy.stats: 0.6 s of
    every `trackside crossing` and report with GNSS (1.2 s in all on the sample).  It is written out now."""
    probe = PROBE.replace("%r", repr(("scipy", "filterpy")))
    sample = str(SAMPLES / "crossing_example.csv")
    for args in (
        ("crossing", sample, "--layout", "example", "--json"),
        ("report", sample, "--layout", "example", "--format", "json", "-o", str(tmp_path / "r.json")),
    ):
        out = subprocess.run(
            [sys.executable, "-c", probe, *args], capture_output=True, text=True, timeout=120, check=False
        )
        doc = json.loads(out.stdout.strip().splitlines()[-1])
        assert doc["loaded"] == [] and doc["code"] in (0, 1), (args, doc)
