"""An archive checked against its own manifest: every part there and readable, every file's lines all stored.

The manifest names each table's Parquet parts and, per input file, the
records and rejected lines read from it.  A disk that failed, a copy cut
short or a hand that deleted a part leaves an archive that reads wrong or not
at all; :func:`verify_archive` finds that before a report does:

* each part: present, a regular file, with a Parquet footer that reads (a
  part cut short has none); ``deep``: every column of every row decoded too;
* each input file: the rows stored under its ``file_seq`` (the ``records`` of
  a diagnostic log, the rows written to the parts of any other file, the
  ``rejected`` lines of both) equal the counts its ledger entry holds.  An
  NMEA file's fixes are fewer than its sentences (RMC and GGA of an epoch
  make one): a ledger from before its ``rows`` were kept is checked for no
  more rows than records.  A lost part, or rows stored
  twice, shows here even when every part reads;
* files under ``data/`` that no kept manifest names: what a killed ingest
  left, removed by the next ingest; counted, not damage.

Read-only: nothing is written or removed.
"""

from __future__ import annotations

import os
import stat
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq

from console.archive.store import DATA, Manifest, kept_parts, read_current
from console.inputs.recognise import DIAGNOSTIC
from console.safe_text import one_line

# Tables whose rows carry the input file they came from (file_seq): counted per file against the ledger.
RECORDS = "records"
REJECTED = "rejected"
BATCH_ROWS = 1 << 18  # rows decoded at a time: memory bounded whatever a part's size


@dataclass(frozen=True)
class Damage:
    """A part the manifest names that is not there or does not read."""

    table: str
    part: str  # relative to the archive
    problem: str


@dataclass(frozen=True)
class CountMismatch:
    """An input file whose rows stored differ from what its ledger entry says was read."""

    file: str
    table: str
    ledger: int
    stored: int


@dataclass
class Verification:
    root: Path
    generation: int
    deep: bool
    parts: Counter[str] = field(default_factory=Counter)  # per table, parts checked
    rows: Counter[str] = field(default_factory=Counter)  # per table, rows in its readable parts
    damaged: list[Damage] = field(default_factory=list)
    mismatches: list[CountMismatch] = field(default_factory=list)
    unlisted: int = 0  # files under data/ no kept manifest names
    files_checked: int = 0

    @property
    def intact(self) -> bool:
        return not self.damaged and not self.mismatches

    def to_json(self) -> dict[str, Any]:
        return {
            "archive": str(self.root),
            "generation": self.generation,
            "deep": self.deep,
            "intact": self.intact,
            "tables": {t: {"parts": self.parts[t], "rows": self.rows[t]} for t in sorted(self.parts)},
            "files_checked": self.files_checked,
            "damaged": [{"table": d.table, "part": d.part, "problem": d.problem} for d in self.damaged],
            "mismatches": [
                {"file": m.file, "table": m.table, "ledger": m.ledger, "stored": m.stored} for m in self.mismatches
            ],
            "unlisted_files": self.unlisted,
        }


def verify_archive(root: Path, deep: bool = False, on_part: Callable[[int, int], None] | None = None) -> Verification:
    """Check the archive at ``root`` (its current manifest; ArchiveError: none, or one that does not read).

    ``on_part(done, total)``: told after each part (a progress bar).
    """
    m = read_current(root)
    out = Verification(root, m.generation, deep)
    per_file: dict[str, Counter[int]] = {RECORDS: Counter(), REJECTED: Counter()}
    part_rows: dict[str, int] = {}
    todo = [(table, rel) for table, rels in sorted(m.tables.items()) for rel in rels]
    for done, (table, rel) in enumerate(todo, start=1):
        out.parts[table] += 1
        rows = _check_part(out, root, table, rel, per_file.get(table))
        if rows is not None:
            out.rows[table] += rows
            part_rows[rel] = rows
        if on_part is not None:
            on_part(done, len(todo))
    _check_counts(out, m, per_file, part_rows)
    out.unlisted = _unlisted(root, m)
    return out


def _check_part(out: Verification, root: Path, table: str, rel: str, by_file: Counter[int] | None) -> int | None:
    """One part: its rows (None: damaged, said in ``out``); ``by_file``: its rows added per file_seq."""
    path = root / rel
    try:
        st = path.lstat()
    except FileNotFoundError:
        out.damaged.append(Damage(table, rel, "missing"))
        return None
    except OSError as exc:
        out.damaged.append(Damage(table, rel, f"cannot be looked at ({one_line(exc)})"))
        return None
    if not stat.S_ISREG(st.st_mode):
        out.damaged.append(Damage(table, rel, "not a regular file"))
        return None
    try:
        pf = pq.ParquetFile(path)
        rows = int(pf.metadata.num_rows)
        if out.deep:
            decoded = sum(batch.num_rows for batch in pf.iter_batches(batch_size=BATCH_ROWS))
            if decoded != rows:
                out.damaged.append(Damage(table, rel, f"its footer says {rows:,} rows, {decoded:,} decode"))
                return None
        if by_file is not None and "file_seq" in pf.schema_arrow.names:
            # A batch at a time: a part of millions of rows is never held whole.
            for batch in pf.iter_batches(batch_size=BATCH_ROWS, columns=["file_seq"]):
                for entry in pc.value_counts(batch.column(0)).to_pylist():
                    if entry["values"] is not None:
                        by_file[int(entry["values"])] += int(entry["counts"])
    except (OSError, pa.ArrowException) as exc:
        out.damaged.append(Damage(table, rel, f"cannot be read ({one_line(exc)})"))
        return None
    return rows


def _check_counts(out: Verification, m: Manifest, per_file: dict[str, Counter[int]], part_rows: dict[str, int]) -> None:
    """Each input file's rows stored against its ledger entry (where the parts holding them read)."""
    damaged = {d.part for d in out.damaged}
    table_of = {rel: table for table, rels in m.tables.items() for rel in rels}
    records_whole = not any(d.table == RECORDS for d in out.damaged)
    rejected_whole = not any(d.table == REJECTED for d in out.damaged)
    for e in m.files:
        seq = int(e["file_seq"])
        active = bool(e.get("active", True))
        shown = str(e["path"])
        out.files_checked += 1
        if e["kind"] == DIAGNOSTIC:
            if records_whole:
                _compare(out, shown, RECORDS, int(e.get("records", 0)) if active else 0, per_file[RECORDS][seq])
        elif active:
            parts = [str(p) for p in e.get("parts", [])]
            if not damaged & set(parts):
                stored = sum(part_rows.get(p, 0) for p in parts)
                table = table_of.get(parts[0], "parts") if parts else "parts"
                if "rows" in e:  # the rows written to its parts (ingests since stop 46)
                    _compare(out, shown, table, int(e["rows"]), stored)
                elif stored > int(e.get("records", 0)):  # an older ledger: a row is made of one record or more
                    out.mismatches.append(CountMismatch(shown, table, int(e.get("records", 0)), stored))
        if rejected_whole:
            _compare(out, shown, REJECTED, int(e.get("rejected", 0)) if active else 0, per_file[REJECTED][seq])


def _compare(out: Verification, shown: str, table: str, ledger: int, stored: int) -> None:
    if ledger != stored:
        out.mismatches.append(CountMismatch(shown, table, ledger, stored))


def _unlisted(root: Path, m: Manifest) -> int:
    """Files under data/ that neither the current manifest nor the kept earlier ones name."""
    _names, _kept, listed = kept_parts(root, m)
    n = 0
    for dirpath, _dirs, files in os.walk(root / DATA):
        for f in files:
            if os.path.relpath(os.path.join(dirpath, f), root) not in listed:
                n += 1
    return n
