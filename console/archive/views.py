"""DuckDB over the archive, read-only: one view per table, over the current manifest's parts only.

The connection is in memory.  Before the user's SQL runs, file access is
limited to the archive's data directory (``allowed_directories`` +
``enable_external_access = false``; the views name the manifest's parts) and the
configuration is locked, so ``COPY … TO``, ``ATTACH``, ``INSTALL`` or
reading other files fail; besides, only one SELECT-like statement is
accepted (console.archive.query checks the statement).
A query that started before an ingest published keeps reading the parts
of the manifest it opened (the next ingest keeps them, see store.KEEP_MANIFESTS).
Here too: the columns the views show (:func:`schema`), and :func:`require_archive`.
"""

from __future__ import annotations

import threading
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from console.archive.duck import DUCKDB_CONFIG, NO_PROGRESS_BAR, engine
from console.archive.partition_filter import partition_filter
from console.archive.store import DATA, ArchiveError, Manifest, read_current
from console.archive.tables import COLUMN_TYPES, EMPTY_COLUMNS, HIVE_TYPES, TABLES
from console.safe_text import one_line

if TYPE_CHECKING:
    import duckdb
    import pyarrow as pa


def _quote(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


# The ingest's own reads (derived tables) sort every record: bounded memory, spilled under tmp/.
INTERNAL_MEMORY_LIMIT = "160MB"


def connect(
    root: Path,
    manifest: Manifest | None = None,
    *,
    spill_dir: Path | None = None,
    tables: Collection[str] | None = None,
    sql: str | None = None,
    computed: dict[str, pa.Table] | None = None,
    engine_only: bool = False,
) -> tuple[duckdb.DuckDBPyConnection, Manifest]:
    """An in-memory DuckDB connection with a view per archive table, locked read-only.

    ``spill_dir``: the ingest's own connection, memory-bounded, sorting through that directory.
    ``tables``: only these views read their parts (the rest are empty): a view over
    thousands of parts costs a few hundred ms to create.
    ``sql``: the one query the connection is for: where it keeps only some days or devices of
    a partitioned table (see :func:`~console.archive.partition_filter.partition_filter`), that view lists
    only their parts.
    ``engine_only``: the caller uses only ``execute``/``description``/``fetch*`` until it imports the package
    itself (see :func:`~console.archive.duck.engine`).
    """
    if engine_only and not computed:
        duckdb = engine()
    else:
        import duckdb

    m = manifest if manifest is not None else read_current(root)
    if spill_dir is None and sql is None and not computed:
        shared = _SHARED.get(root.resolve())
        cursor = shared.cursor(m, TABLES if tables is None else tables) if shared is not None else None
        if cursor is not None:
            return cursor, m
    config: dict[str, Any] = dict(DUCKDB_CONFIG)
    if spill_dir is not None:
        config.update(memory_limit=INTERNAL_MEMORY_LIMIT, temp_directory=str(spill_dir), threads=2)
    con = duckdb.connect(":memory:", config=config)
    con.execute(NO_PROGRESS_BAR)
    # Zone-aware values (old fix parts, a user's now()) in UTC, the archive's one zone, whatever the machine's.
    con.execute("SET TimeZone = 'UTC'")
    base = root.resolve()
    only = partition_filter(con, sql) if sql is not None else {}
    try:
        for table in TABLES:
            rels = m.parts(table) if tables is None or table in tables else []
            if table in only:
                # The query's WHERE drops every other partition anyway; one part stays to give the view its columns.
                rels = [r for r in rels if all(f"/{k}={only[table][k]}/" in r for k in only[table])] or rels[:1]
            _make_view(con, root, table, rels)
    except ArchiveError:
        con.close()
        raise
    for name, table in (computed or {}).items():  # views computed in Python (the forecasts), before the lock
        con.register(name, table)
    _lock(con, base)
    return con, m


def _make_view(con: Any, root: Path, table: str, rels: list[str]) -> None:
    """``table``'s view over its parts; a part deleted or cut short on disk is an ArchiveError saying so (it was
    "internal error: IOException" with the statement that made the view)."""
    base = root.resolve()
    try:
        con.execute(_view(table, TABLES[table], [str(base / rel) for rel in rels]))
    except engine().Error as exc:
        missing = next((rel for rel in rels if not (base / rel).is_file()), None)
        why = one_line(exc).split(" LINE 1:")[0]  # not the statement that made the view
        what = f"{missing} is missing" if missing else f"its {table} cannot be read ({why})"
        raise ArchiveError(f"{root}: the archive is damaged: {what}") from None


def _view(table: str, keys: tuple[str, ...], parts: list[str]) -> str:
    """The statement that makes ``table``'s view over ``parts`` (none: an empty view with its columns)."""
    if parts:
        files = "[" + ", ".join(_quote(p) for p in parts) + "]"
        hive = ""
        if keys:
            types = ", ".join(f"{_quote(k)}: {HIVE_TYPES[k]}" for k in keys)
            hive = f", hive_partitioning = true, hive_types = {{{types}}}"
        else:
            hive = ", hive_partitioning = false"
        # Partitioned tables share one schema: binding reads one footer, not thousands.
        union = "" if keys else ", union_by_name = true"
        casts = ", ".join(f"CAST({c} AS {t}) AS {c}" for c, t in COLUMN_TYPES.get(table, {}).items())
        star = f"* REPLACE ({casts})" if casts else "*"
        return f"CREATE OR REPLACE VIEW {table} AS SELECT {star} FROM read_parquet({files}{union}{hive})"
    cols = EMPTY_COLUMNS.get(table, (("file", "VARCHAR"), ("line", "BIGINT")))
    select = ", ".join(f"NULL::{typ} AS {name}" for name, typ in cols)
    return f"CREATE OR REPLACE VIEW {table} AS SELECT {select} WHERE false"


def _lock(con: duckdb.DuckDBPyConnection, base: Path) -> None:
    # Reading stays inside data/ (a list of thousands of allowed paths costs a quarter second to set); writing
    # anywhere is excluded by the statement check (only SELECT-like statements run).
    con.execute(f"SET allowed_directories = [{_quote(str(base / DATA) + '/')}]")
    con.execute("SET enable_external_access = false")
    con.execute("SET lock_configuration = true")


@dataclass
class _Shared:
    """One DuckDB database for every read of an archive in a scope (:func:`one_connection`): each
    :func:`connect` gets a cursor on it, and each table's view is made once, when first asked for."""

    root: Path
    con: Any = None
    generation: int | None = None
    full: set[str] = field(default_factory=set)  # views over their parts (the others are empty)
    guard: threading.Lock = field(default_factory=threading.Lock)

    def cursor(self, m: Manifest, tables: Collection[str]) -> duckdb.DuckDBPyConnection | None:
        """A cursor whose views of ``tables`` read their parts (None: ``m`` is another generation than the
        database's, published meanwhile: that read gets a connection of its own, as outside the scope)."""
        import duckdb

        with self.guard:
            if self.con is None:
                con = duckdb.connect(":memory:", config=dict(DUCKDB_CONFIG))
                con.execute(NO_PROGRESS_BAR)
                con.execute("SET GLOBAL TimeZone = 'UTC'")  # global: every cursor's
                for table, keys in TABLES.items():
                    con.execute(_view(table, keys, []))
                _lock(con, self.root)
                self.con, self.generation = con, m.generation
            elif m.generation != self.generation:
                return None
            for table in set(tables) - self.full:
                if table in TABLES:
                    _make_view(self.con, self.root, table, m.parts(table))
                    self.full.add(table)
            return self.con.cursor()  # a cursor takes the database's session settings


_SHARED: dict[Path, _Shared] = {}


@contextmanager
def one_connection(root: Path) -> Iterator[None]:
    """Within, the reads of ``root`` (:func:`connect`, but the ingest's spilling one and a query's own) share one
    DuckDB database: a report opens one, not one per part it computes (each costs tens of ms)."""
    key = root.resolve()
    if key in _SHARED:  # nested: the outer scope's
        yield
        return
    shared = _SHARED[key] = _Shared(key)
    try:
        yield
    finally:
        del _SHARED[key]
        if shared.con is not None:
            shared.con.close()


def schema(root: Path) -> list[tuple[str, str, str]]:
    """(table, column, type) of every view (an empty table shows the columns it will have)."""
    con, _ = connect(root)
    try:
        out: list[tuple[str, str, str]] = []
        for table in TABLES:
            for name, typ, *_ in con.execute(f"DESCRIBE {table}").fetchall():
                out.append((table, str(name), str(typ)))
        return out
    finally:
        con.close()


def require_archive(root: Path) -> Manifest:
    m = read_current(root)
    if m.generation == 0:
        raise ArchiveError(f"{root}: no archive here yet (run `trackside ingest FILES --archive {root}`)")
    return m
