"""Shared fixtures: paths to the shipped samples and a helper to write logs."""

from __future__ import annotations

import compileall
import os
import re
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# The fuzz suite's long run (tests/test_fuzz_*.py): pytest -m fuzz --hypothesis-profile long
settings.register_profile("long", max_examples=2000, deadline=None, suppress_health_check=list(HealthCheck))
# Hypothesis's per-example deadline (200 ms) measures the machine's load, not the code: on a shared
# 2-core CI runner an example that takes 40 ms alone took 279 ms and failed the run.
settings.register_profile("default", deadline=None)
settings.load_profile("default")

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_logs"

# Bytecode caches, where the environment says not to write them (PYTHONDONTWRITEBYTECODE): every `trackside`
# subprocess and Dask worker the suite starts would compile the package's modules from source again (about
# 0.06 s of CPU each, hundreds of them), and each xdist worker would parse and rewrite every test module again
# (about 5 s each). The package is compiled once here, by the process that starts the run (it is quick when
# nothing changed), and this process and its xdist workers write their caches; __pycache__ is ignored by git.
if "PYTEST_XDIST_WORKER" not in os.environ:
    for package in ("console", "parsers", "benchmarks"):
        compileall.compile_dir(ROOT / package, quiet=2)
sys.dont_write_bytecode = False

RECORD = (
    "Diag_id:00002\tID:4083\tDevice:IM\tType:013\tGS:GS03\tTrackinfo:WS4\tch:{ch}\tAdr:{adr}\t"
    "Label:{label}\tData:{data}\tDate:{date}\tTime:{time}"
)


def record(
    ch: int | str = 1,
    adr: str = "080",
    label: str = "Summenzä",
    data: str = "18",
    date: str = "2015-10-31",
    time: str = "09:32:24",
) -> str:
    """One diagnostic record line (no newline)."""
    return RECORD.format(ch=ch, adr=adr, label=label, data=data, date=date, time=time)


@pytest.fixture
def samples() -> Path:
    return SAMPLES


# -- how many xdist workers `-n auto` starts (pyproject's addopts) ----------------------------------------------
#
# One more than the cores this process may run on: about a fifth of a worker's time is spent waiting, not
# computing (servers starting, `trackside` subprocesses, live feeds polled in real time), so as many workers as
# cores left them ~80 % busy. On 2 cores the suite took 6 min 10 s with 2 workers, 5 min 07 s with 3 (same tree,
# one run each); `-n N` on the command line still chooses N.
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    return len(os.sched_getaffinity(0)) + 1


# -- how the suite is shared between xdist workers (pyproject: --dist loadgroup --no-loadscope-reorder) --------
#
# A test file is one unit, run on one worker in its order (its module fixtures are built once), except:
# files whose tests are independent and long are cut into one unit per test, and a file with independent
# parts is cut into those parts. The units go out longest first (seconds of one worker, measured on 2 cores),
# so the two workers end together rather than one finishing a long file alone.

# Files cut into one unit per test: no test reads what another wrote, no module fixture worth sharing.
PER_TEST = {"tests/test_one_engine.py"}
# Files cut into one unit per test function (its parametrized cases stay together, in order).
PER_FUNCTION = {"tests/test_examples.py"}
# Functions of those files kept in one unit: the two tests of every command's --help read one run of it
# (test_examples.help_text, cached per process).
SAME_UNIT = {
    "test_every_help_ends_with_two_or_three_examples_one_per_line": "help texts",
    "test_usage_lines_name_no_python_types": "help texts",
}
# The units to send first, longest first (nodeid prefixes; a unit takes the place of its first match).
# Figures: seconds per unit in a 2-worker run at load ~10 (tests/test_one_engine.py 250 s in all, each of its
# cases 44-81 s); the other units follow in the collection's order.
LONGEST_FIRST = (
    "tests/test_sim_parting.py",  # 105 s
    "tests/test_fleet_archive.py",  # 82
    "tests/test_one_engine.py::test_every_mode_gives_the_batch_result[simulated-100]",  # 81
    "tests/test_integrity_faces.py",  # 77
    "tests/test_station_archive.py",  # 74
    "tests/test_replay_engine.py",  # 69
    "tests/test_crossing_runs.py",  # 61
    "tests/test_crossing_ticks.py",  # 57
    "tests/test_one_engine.py::test_every_mode_gives_the_batch_result[simulated-101]",  # 55
    "tests/test_counting_bank.py",  # 55
    "tests/test_examples.py::test_help_example_runs",  # 55
    "tests/test_archive_crash.py",  # 54
    "tests/test_one_engine.py::test_every_mode_gives_the_batch_result[realistic-200]",  # 53
    "tests/test_integrity_runs.py",  # 48
    "tests/test_report.py",  # 46
    "tests/test_one_engine.py::test_the_simulators_console_shows_what_batch_finds_in_the_files_it_wrote",  # 46
    "tests/test_one_engine.py::test_every_mode_gives_the_batch_result[realistic-201]",  # 44
    "tests/test_live_sim.py",  # 40
    "tests/test_live_follow_formats.py",  # 39
    "tests/test_whole_second.py",  # 39
    "tests/test_archive_incremental.py",  # 35
    "tests/test_examples.py::test_readme_example_runs",  # 34
    "tests/test_metrics.py",  # 31
    "tests/test_archive_equality.py",  # 30
    "tests/test_live_gpsd.py",  # 30
    "tests/test_stream_sections.py",  # 30
    "tests/test_fleet_group_ingest.py",  # 26
    "tests/test_archive_derive.py",  # 24
    "tests/test_integrity_brake_mqtt.py",  # 23
)


def _unit(nodeid: str) -> str:
    path, _, rest = nodeid.partition("::")
    if path in PER_TEST:
        # One simulated and one realistic case of the cross-mode test per unit (seeds 100+k and 200+k): a
        # worker starts the module's two Dask clusters once for both, where a unit per case started them for
        # each (a worker's module fixtures end when it turns to another file's unit).
        paired = re.fullmatch(r"(test_every_mode_gives_the_batch_result)\[(?:simulated|realistic)-\d*?(\d\d)\]", rest)
        return f"{path}::{paired[1]}-{paired[2]}" if paired else nodeid
    if path in PER_FUNCTION:
        function = rest.split("[")[0]
        return f"{path}::{SAME_UNIT.get(function, function)}"
    return path


@pytest.hookimpl(tryfirst=True)  # before xdist's own hook reads the group markers
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # On an xdist worker ``dist`` reads "no": xdist keeps the controller's choice in ``option.loadgroup``.
    if not getattr(config.option, "loadgroup", False):
        return

    def rank(item: pytest.Item) -> int:
        return next((k for k, p in enumerate(LONGEST_FIRST) if item.nodeid.startswith(p)), len(LONGEST_FIRST))

    items.sort(key=rank)  # stable: the rest keep the collection's order
    for item in items:
        unit = _unit(item.nodeid)
        if unit != item.nodeid:
            item.add_marker(pytest.mark.xdist_group(unit))
