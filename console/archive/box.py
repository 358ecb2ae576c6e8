"""``query --format table``: DuckDB's own box renderer, fitted to the terminal, log text kept inert.

DuckDB's renderer (the duckdb shell's ``.mode duckbox``) fits the table to a
width: it cuts long values with ``…``, hides middle columns when they cannot
fit, and shows the first and last rows of a long result with the count.  It
escapes C0 controls itself but not DEL, C1 or bidi controls, and shows them
as ``\\e`` where every other trackside output shows ``\\x1b``: text columns
go through :data:`INERT_SQL` first, the SQL twin of
:func:`console.safe_text.clean`, so a cell reads the same here as in
``analyze`` or a report.
"""

from __future__ import annotations

import contextlib
import io
import shutil
from collections.abc import Sequence
from typing import TYPE_CHECKING

from console.safe_text import clean

if TYPE_CHECKING:
    import duckdb

# A long result shows its first and last rows, as the duckdb shell does (.maxrows 40).
MAX_ROWS = 40
# What console.safe_text.clean escapes, in RE2 syntax (C0, DEL, C1, line/paragraph separators, bidi controls,
# the invisible characters).
_CONTROL_RE2 = (
    r"[\x00-\x1f\x7f-\x9f\x{61c}\x{180e}\x{200b}-\x{200f}\x{2028}-\x{202e}\x{2060}-\x{206f}\x{feff}"
    r"\x{e0000}-\x{e007f}]"
)
# Rare: a whole-value regexp test first; only values that hold a control character are split and rebuilt.
INERT_SQL = (
    f"CASE WHEN regexp_matches({{v}}, '{_CONTROL_RE2}') THEN array_to_string(list_transform(string_split({{v}}, ''),"
    f" lambda c: CASE WHEN regexp_matches(c, '{_CONTROL_RE2}') THEN printf(CASE WHEN unicode(c) < 256"
    " THEN '\\x%02x' WHEN unicode(c) < 65536 THEN '\\u%04x' ELSE '\\U%08x' END, unicode(c)) ELSE c END), '')"
    " ELSE {v} END"
)
# Times as every trackside output writes them (console.analysis.timefmt.iso): ISO 8601, UTC, Z, milliseconds at
# least, microseconds or nanoseconds when they are not zero.  A zone-aware time is UTC (the connection's zone).
_NS = "epoch_ns(try_cast({v} AS TIMESTAMP_NS))"
_FRAC = f"((({_NS}) % 1000000000) + 1000000000) % 1000000000"
_DIGITS = f"lpad(CAST({_FRAC} AS VARCHAR), 9, '0')"
ISO_SQL = (
    f"CASE WHEN {{v}} IS NULL THEN NULL WHEN {_NS} IS NULL"
    f" THEN strftime(CAST({{v}} AS TIMESTAMP), '%Y-%m-%dT%H:%M:%S.%fZ')"
    f" ELSE strftime(CAST(try_cast({{v}} AS TIMESTAMP_NS) AS TIMESTAMP), '%Y-%m-%dT%H:%M:%S') || '.' ||"
    f" CASE WHEN {_FRAC} % 1000000 = 0 THEN left({_DIGITS}, 3) WHEN {_FRAC} % 1000 = 0 THEN left({_DIGITS}, 6)"
    f" ELSE {_DIGITS} END || 'Z' END"
)
# Types whose text DuckDB writes itself (numbers, times, booleans, bytes as \xNN): shown as they are.
_SAFE_TYPES = frozenset(
    [
        "BOOLEAN",
        "TINYINT",
        "SMALLINT",
        "INTEGER",
        "BIGINT",
        "HUGEINT",
        "UTINYINT",
        "USMALLINT",
        "UINTEGER",
        "UBIGINT",
        "UHUGEINT",
        "FLOAT",
        "DOUBLE",
        "DATE",
        "TIME",
        "TIME_NS",
        "INTERVAL",
        "BLOB",
        "UUID",
    ]
)


def terminal_width() -> int:
    """Columns of the terminal ($COLUMNS first, as the shell sets it; 80 in a pipe)."""
    return shutil.get_terminal_size((80, 24)).columns


def _safe(typ: str) -> bool:
    return typ in _SAFE_TYPES or typ.startswith("DECIMAL")


def _quoted(name: str) -> str:
    return '"' + name.replace('"', '""') + '"'


def inert_relation(rel: duckdb.DuckDBPyRelation) -> duckdb.DuckDBPyRelation:
    """The relation with every column that can hold log text escaped (lists and structs as their text)."""
    exprs = []
    for i, (name, typ) in enumerate(zip(rel.columns, rel.types, strict=True), start=1):
        alias = _quoted(clean(name))
        t = str(typ).upper()
        if t.startswith("TIMESTAMP"):
            iso = ISO_SQL.replace("{v}", f"#{i}")
            exprs.append(f"{iso} AS {alias}")
        elif _safe(t):
            exprs.append(f"#{i} AS {alias}")
        else:
            value = f"#{i}" if t == "VARCHAR" else f"CAST(#{i} AS VARCHAR)"
            inert = INERT_SQL.replace("{v}", value)
            exprs.append(f"{inert} AS {alias}")
    return rel.project(", ".join(exprs)) if exprs else rel


def render(rel: duckdb.DuckDBPyRelation, width: int | None = None, max_rows: int = MAX_ROWS) -> str:
    """DuckDB's box of the relation, at most ``width`` columns wide (the terminal's by default)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):  # DuckDB writes the box through Python's print
        inert_relation(rel).show(max_width=width or terminal_width(), max_rows=max_rows)
    return out.getvalue()


def render_rows(names: Sequence[str], rows: Sequence[Sequence[object]], width: int | None = None) -> str:
    """A short list of text rows (presets, the schema) in the same box, every row shown."""
    import duckdb

    con = duckdb.connect(":memory:")
    try:
        columns = ", ".join(f"{_quoted(n)} VARCHAR" for n in names)
        con.execute(f"CREATE TABLE t ({columns})")
        if rows:
            marks = ", ".join("?" for _ in names)
            con.executemany(
                f"INSERT INTO t VALUES ({marks})", [[None if v is None else str(v) for v in r] for r in rows]
            )
        return render(con.table("t"), width, max_rows=max(len(rows), 1))
    finally:
        con.close()
