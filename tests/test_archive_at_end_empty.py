"""An ingest's at-end tables (health findings, crossing timelines) are skipped only where computing them would
find nothing (console.archive.at_end_empty), and a plain ingest's small tables are the ones pyarrow's
``from_pylist`` makes (console.archive.arrow_np), without importing pandas."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pyarrow as pa
import pytest

from benchmarks.gen_realistic_diag import generate
from console.archive import derive
from console.archive.arrow_np import table_from_rows
from console.archive.history import at_end_tables
from console.archive.ingest import run_ingest
from console.archive.store import read_current
from tests.conftest import SAMPLES

STATION = SAMPLES / "example_station.log"  # channel faults: findings with no health register
HEALTH = SAMPLES / "ws4_health.log"  # analog values and 1-edge counters: findings
VOLTS = SAMPLES / "am_thuong_2021-06-06_voltages.csv"


@pytest.fixture(scope="module")
def plain(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two realistic multi-board logs (wheel, diagnosis and counter registers, damaged lines): no health
    register, and no channel fault."""
    d = tmp_path_factory.mktemp("plain")
    logs = [d / "a.log", d / "b.log"]
    generate(6000, logs[0], boards=6, seed=3)
    generate(6000, logs[1], boards=6, seed=4, resolution="s")
    return logs


@pytest.mark.parametrize(
    ("ingests", "layout", "skipped"),
    [
        ([["a"]], None, [True]),
        ([["a"], ["b"]], None, [True, True]),
        ([["a", "b"]], None, [True]),
        ([[HEALTH]], None, [False]),
        ([[STATION]], None, [False]),
        ([["a"], [HEALTH]], None, [True, False]),
        # The health registers are in an earlier ingest's records only: the carried registry still knows them.
        ([[HEALTH], ["a"]], None, [False, False]),
        ([["a"]], "example", [False]),
        ([["a", VOLTS]], None, [False]),
    ],
)
def test_skipped_only_when_the_tables_would_be_empty(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    plain: list[Path],
    ingests: list[list[Path | str]],
    layout: str | None,
    skipped: list[bool],
) -> None:
    calls: list[int] = []

    def counted(*args: Any, **kwargs: Any) -> dict[str, Any]:
        calls.append(1)
        return at_end_tables(*args, **kwargs)

    monkeypatch.setattr(derive, "at_end_tables", counted)
    root = tmp_path / "arc"
    seen: list[bool] = []
    for named in ingests:
        paths = [plain["ab".index(p)] if isinstance(p, str) else p for p in named]
        before = len(calls)
        run_ingest(paths, root, layout=layout)
        seen.append(len(calls) == before)
        m = read_current(root)
        # What the skipped step would have given, over the archive as published (its inputs are stored).
        made = {name: df for name, df in at_end_tables(root, m, layout, []).items() if df is not None and len(df)}
        if seen[-1]:
            assert made == {}
            assert not m.parts("health_findings") and not m.parts("crossing_timelines")
        elif HEALTH in paths:
            assert "health_findings" in made and m.parts("health_findings")
    assert seen == skipped


ROWS: list[list[dict[str, Any]]] = [
    [{"a": 1, "b": "x"}, {"a": -(1 << 63), "b": "é\U0001f686"}],
    [{"a": (1 << 63) - 1, "b": ""}],
    [{"a": 1 << 63, "b": "x"}],  # beyond int64: pyarrow's own error or type
    [{"a": None, "b": "x"}, {"a": 2, "b": None}],
    [{"a": True, "b": 1.5}],
    [{"a": 1, "b": "x"}, {"b": "y", "a": 2}],  # another key order
    [{"a": 1}, {"a": 2, "c": "z"}],  # a key the first row has not
    [{"a": 1.0, "b": b"x"}],
]


@pytest.mark.parametrize("rows", ROWS)
def test_table_from_rows_is_from_pylist(rows: list[dict[str, Any]]) -> None:
    try:
        want = pa.Table.from_pylist(rows)
    except (OverflowError, pa.ArrowException) as exc:
        with pytest.raises(type(exc)):
            table_from_rows(rows)
        return
    got = table_from_rows(rows)
    assert got.schema.equals(want.schema, check_metadata=True)
    assert got.equals(want)


def test_a_plain_ingest_imports_no_pandas(tmp_path: Path, plain: list[Path]) -> None:
    code = (
        "import sys\n"
        "from pathlib import Path\n"
        "from console.archive.ingest import run_ingest\n"
        f"run_ingest([Path({str(plain[0])!r})], Path({str(tmp_path / 'arc')!r}))\n"
        "print('pandas' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.strip() == "False"
