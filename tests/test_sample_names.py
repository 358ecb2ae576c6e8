"""The shipped samples are named and described for what they are, never by a paper's internal number."""

from __future__ import annotations

import re
from pathlib import Path

from parsers.kinds import classify_file

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_logs"
CENTRE_TABLE = SAMPLES / "co_nhu_van_2026_centre_table.tsv"
SEED = re.compile(r"seed[ _]?0\d\d", re.IGNORECASE)


def test_the_monitoring_centre_table_is_named_for_what_it_is() -> None:
    # Co Nhu Van, TCSJ 2026, Table 1: the monitoring-centre table, 9 rows.
    assert CENTRE_TABLE.is_file()
    assert classify_file(CENTRE_TABLE).kind == "centre"
    assert not [p.name for p in SAMPLES.iterdir() if SEED.search(p.name)]


def test_what_users_read_names_no_paper_by_number() -> None:
    # Users read the README, docs/, the samples and their README; the make scripts write the samples.
    texts = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted(SAMPLES.iterdir())]
    found = []
    for path in texts:
        if path.is_file():
            for n, line in enumerate(path.read_text("utf-8", errors="replace").splitlines(), 1):
                if SEED.search(line):
                    found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not found, "\n".join(found)
