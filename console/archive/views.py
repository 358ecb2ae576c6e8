"""DuckDB over the archive, read-only: one view per table, over the current manifest's parts only.

The connection is in memory.  Before the user's SQL runs, file access is
limited to the archive's data directory (``allowed_directories`` +
``enable_external_access = false``; the views name the manifest's parts) and the
configuration is locked, so ``COPY … TO``, ``ATTACH``, ``INSTALL`` or
reading other files fail; besides, only one SELECT-like statement is
accepted (SELECT, WITH, FROM, VALUES, DESCRIBE, SHOW, SUMMARIZE, EXPLAIN).
A query that started before an ingest published keeps reading the parts
of the manifest it opened (the next ingest keeps them, see store.KEEP_MANIFESTS).
"""

from __future__ import annotations

import importlib
import re
import threading
from collections.abc import Callable, Collection, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from console.archive.store import DATA, ArchiveError, Manifest, read_current
from console.interrupt import interruptible
from console.safe_text import one_line

if TYPE_CHECKING:
    import duckdb
    import pyarrow as pa

# A view computed in Python when a statement names it (the forecasts): (the archive, its manifest) → the table.
# The command that offers one passes it in; the archive's views know only the stored tables.
ComputedView = Callable[[Path, Manifest], "pa.Table"]

# Every table the archive knows, with the partition keys in its part paths.
TABLES: dict[str, tuple[str, ...]] = {
    "records": ("day", "device_id"),
    "fixes": (),
    "frames": (),
    "voltages": (),
    "passages": (),
    "axles": (),
    "section_states": (),
    "count_ledger": (),
    "crossing_timelines": (),
    "health_findings": (),
    "rejected": (),
    "ingests": (),
}
HIVE_TYPES = {"day": "DATE", "device_id": "INTEGER"}
ALLOWED_STATEMENTS = ("SELECT", "EXPLAIN")
# An empty table still has the columns the presets and scripts name (the
# derived tables' full columns come from the analyses, once there are rows).
_T = "TIMESTAMP_NS"
EMPTY_COLUMNS: dict[str, tuple[tuple[str, str], ...]] = {
    # Every column of a record part (an archive of GNSS fixes or frames alone has none, and the trends and
    # the forecast still query them).
    "records": (
        ("time", _T),
        ("diag_id", "INTEGER"),
        ("device", "VARCHAR"),
        ("type", "VARCHAR"),
        ("gs", "VARCHAR"),
        ("counting_head", "VARCHAR"),
        ("channel", "TINYINT"),
        ("address", "SMALLINT"),
        ("label", "VARCHAR"),
        ("label_canonical", "VARCHAR"),
        ("label_encoding", "VARCHAR"),
        ("data", "VARCHAR"),
        ("value", "BIGINT"),
        ("data_kind", "VARCHAR"),
        ("subsecond", "BOOLEAN"),
        ("file", "VARCHAR"),
        ("file_seq", "INTEGER"),
        ("line", "BIGINT"),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
    ),
    "axles": (
        ("time", _T),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
        ("counting_head", "VARCHAR"),
        ("direction", "VARCHAR"),
        ("speed_kmh", "DOUBLE"),
    ),
    "passages": (
        ("start", _T),
        ("day", "DATE"),
        ("device_id", "INTEGER"),
        ("counting_head", "VARCHAR"),
        ("axles", "BIGINT"),
    ),
    "crossing_timelines": (
        ("crossing", "VARCHAR"),
        ("train", "VARCHAR"),
        ("t_on", _T),
        ("t_head_arrival", _T),
        ("lead_s", "DOUBLE"),
        ("warning_time_s", "DOUBLE"),
        ("late_by_s", "DOUBLE"),
        ("late_cause", "VARCHAR"),
        ("violations", "VARCHAR"),
        ("late", "BOOLEAN"),
    ),
    "health_findings": (
        ("severity", "VARCHAR"),
        ("rule", "VARCHAR"),
        ("counting_head", "VARCHAR"),
        ("channel", "TINYINT"),
        ("message", "VARCHAR"),
        ("time_ns", "BIGINT"),
        ("time", _T),
    ),
    "section_states": (("time", _T), ("day", "DATE"), ("section", "VARCHAR"), ("state", "VARCHAR")),
    "count_ledger": (("time", _T), ("day", "DATE"), ("section", "VARCHAR"), ("head", "VARCHAR"), ("delta", "BIGINT")),
    "rejected": (
        ("file", "VARCHAR"),
        ("file_seq", "BIGINT"),
        ("line", "BIGINT"),
        ("reason", "VARCHAR"),
        ("text", "VARCHAR"),
    ),
    "ingests": (("generation", "BIGINT"), ("path", "VARCHAR"), ("action", "VARCHAR"), ("note", "VARCHAR")),
}


# The one type of each kind of value, whatever the parts hold: times are TIMESTAMP_NS (the logs' times, UTC),
# integers are integers.  Parts written before trackside 0.1 held zone-aware fix times, finding times as text
# and nullable integers as floats; the views cast them (and every new part is written with these types).
COLUMN_TYPES: dict[str, dict[str, str]] = {
    "fixes": {"time": _T},
    "health_findings": {"time": _T, "time_ns": "BIGINT", "channel": "TINYINT"},
    "passages": {"detection_second_ns": "BIGINT", "records_in_detection_second": "BIGINT"},
}


class QueryError(Exception):
    """Bad SQL or a statement the archive does not run: DuckDB's message, one line."""


def _quote(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


# The ingest's own reads (derived tables) sort every record: bounded memory, spilled under tmp/.
INTERNAL_MEMORY_LIMIT = "160MB"


# Every connection: no extension fetched or loaded behind the user's back.
DUCKDB_CONFIG: dict[str, Any] = {"autoinstall_known_extensions": False, "autoload_known_extensions": False}
# Every session (a connection, a cursor): no progress bar. DuckDB draws it on standard output after two seconds
# of a query, where it would land inside the JSON or CSV written there.
NO_PROGRESS_BAR = "SET enable_progress_bar = false"


def engine() -> Any:
    """DuckDB's compiled engine: the ``_duckdb`` module where DuckDB ships it apart (2.x), else the package.

    Connecting, running a statement and fetching its rows as Python values need only the engine; the package's
    Python layer (relations, expressions) takes ~60 ms to import, a fifth of a short ``trackside query``.  Its
    connections are the package's own class, which importing the package completes (``sql``, Arrow results).
    """
    try:
        return importlib.import_module("_duckdb")
    except ImportError:  # DuckDB 1.x: the engine is inside the package
        return importlib.import_module("duckdb")


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
    a partitioned table (see :func:`partition_filter`), that view lists only their parts.
    ``engine_only``: the caller uses only ``execute``/``description``/``fetch*`` until it imports the package
    itself (see :func:`engine`).
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


def partition_filter(con: duckdb.DuckDBPyConnection, sql: str) -> dict[str, dict[str, str]]:
    """The partition keys a query fixes, per table: ``{"records": {"day": "2026-03-02", "device_id": "5001"}}``.

    Only when it is certain, from DuckDB's own parse of the query: one SELECT whose only reference
    to the table is its FROM (no join, no CTE, no other mention anywhere, subqueries included), and
    ``day = DATE '…'`` / ``day = '…'`` or ``device_id = <integer>`` among the top-level AND terms of
    its WHERE.  Anything else gives nothing (every part is listed, as without this).
    """
    import json

    try:
        doc = json.loads(con.execute("SELECT json_serialize_sql(?)", [sql]).fetchone()[0])  # type: ignore[index]
    except (engine().Error, TypeError, ValueError):
        return {}
    statements = doc.get("statements") or []
    if doc.get("error") or len(statements) != 1:
        return {}
    node = statements[0].get("node") or {}
    source = node.get("from_table") or {}
    table = str(source.get("table_name", "")).lower()
    keys = TABLES.get(table) if source.get("type") == "BASE_TABLE" and not source.get("schema_name") else None
    if not keys or node.get("type") != "SELECT_NODE" or (node.get("cte_map") or {}).get("map"):
        return {}
    if _mentions(doc, table) != 1:
        return {}
    found: dict[str, str] = {}
    for term in _and_terms(node.get("where_clause")):
        if term.get("type") != "COMPARE_EQUAL":
            continue
        for col, other in ((term.get("left"), term.get("right")), (term.get("right"), term.get("left"))):
            name = _column_name(col, table, source.get("alias", ""))
            value = _key_value(name, other) if name in keys else None
            if name is not None and value is not None:
                found[name] = value
    return {table: found} if found else {}


def _mentions(node: object, table: str) -> int:
    """How many times the parsed query refers to ``table`` (as a table, anywhere)."""
    if isinstance(node, list):
        return sum(_mentions(x, table) for x in node)
    if not isinstance(node, dict):
        return 0
    here = int(node.get("type") == "BASE_TABLE" and str(node.get("table_name", "")).lower() == table)
    return here + sum(_mentions(v, table) for v in node.values())


def _and_terms(expr: object) -> list[dict[str, Any]]:
    if not isinstance(expr, dict):
        return []
    if expr.get("type") == "CONJUNCTION_AND":
        return [t for child in expr.get("children") or [] for t in _and_terms(child)]
    return [expr]


def _column_name(expr: object, table: str, alias: str) -> str | None:
    """``day``, ``records.day`` or ``r.day`` (the FROM's alias) as ``day``; anything else None."""
    if not isinstance(expr, dict) or expr.get("type") != "COLUMN_REF":
        return None
    names = [str(n) for n in expr.get("column_names") or []]
    if len(names) == 1 or (len(names) == 2 and names[0].lower() in {table, alias.lower()} - {""}):
        return names[-1].lower()
    return None


def _key_value(key: str, expr: object) -> str | None:
    """The partition directory's value for ``key = expr``, when expr is a literal of the key's type."""
    import datetime as dt

    if isinstance(expr, dict) and expr.get("type") == "OPERATOR_CAST":
        type_name = str((expr.get("type_expr") or {}).get("type_name", "")).upper()
        if key != "day" or type_name != "DATE":
            return None
        expr = expr.get("child")
    if not isinstance(expr, dict) or expr.get("type") != "VALUE_CONSTANT":
        return None
    literal = expr.get("literal") or {}
    text = str(literal.get("text", ""))
    if key == "day" and literal.get("kind") == "STRING" and len(text) == 10:
        try:
            return dt.date.fromisoformat(text).isoformat()
        except ValueError:
            return None
    if key == "device_id" and literal.get("kind") == "INTEGER" and text.lstrip("-").isdigit():
        return str(int(text))
    return None


def check_read_only(con: duckdb.DuckDBPyConnection, sql: str) -> None:
    """One SELECT-like statement, or QueryError."""
    try:
        statements = con.extract_statements(sql)
    except engine().Error as exc:
        raise QueryError(one_line(exc)) from None
    if len(statements) != 1:
        raise QueryError(f"give exactly one statement (found {len(statements)})")
    kind = statements[0].type.name
    if kind not in ALLOWED_STATEMENTS:
        raise QueryError(f"the archive is read-only: {kind} statements are not run (only SELECT-like queries)")


def run_query(
    root: Path, sql: str, computed: Mapping[str, ComputedView] | None = None
) -> tuple[list[str], list[tuple[object, ...]]]:
    """(column names, rows) of one read-only query over the archive (Python values, as DuckDB gives them)."""
    table = run_query_arrow(root, sql, computed)
    columns = [c.to_pylist() for c in table.columns]
    return list(table.column_names), list(zip(*columns, strict=True)) if columns else []


# Result columns of these types go through Arrow (nanosecond times, intervals of months, maps as pairs); the
# rest are fetched as Python values, which spares a short query pyarrow's import (a third of a second).
_ARROW_TYPE_WORDS = ("TIMESTAMP", "INTERVAL", "MAP(", "TIME_NS")
# Those that are a whole column (not nested in a list or struct) are fetched as integer nanoseconds instead.
_PLAIN_TIME_TYPES = frozenset(
    ("TIMESTAMP", "TIMESTAMP_NS", "TIMESTAMP_MS", "TIMESTAMP_S", "TIMESTAMP WITH TIME ZONE", "TIMESTAMPTZ")
)


@dataclass
class QueryResult:
    """One query's result: plain Python rows, or an Arrow table when a column needs Arrow's types."""

    names: list[str]
    rows: list[tuple[object, ...]] | None = None
    arrow: pa.Table | None = None
    # Columns of ``rows`` that hold times as integer nanoseconds since the epoch (UTC; a naive time is the logs').
    ns_columns: frozenset[int] = frozenset()


def run_query_result(
    root: Path, sql: str, manifest: Manifest | None = None, computed: Mapping[str, ComputedView] | None = None
) -> QueryResult:
    """One read-only query over the archive: Arrow only when the result holds times (see QueryResult).

    ``manifest``: the current one, when the caller has read it already (a year's manifest is megabytes).
    ``computed``: views computed in Python, by name, made when the statement names them.
    """
    con = _query_connection(root, sql, manifest, computed, engine_only=True)
    try:
        with interruptible(con):
            plain = plain_result(con, sql)
            if plain is not None:
                return plain
            import duckdb  # the package's relations: Arrow results and epoch_ns projections

            try:
                rel = con.sql(sql)
                if rel is None:  # a statement without a result (none passes check_read_only today)
                    raise QueryError("the statement returns no rows")
                names = list(rel.columns)
                types = [str(t).upper() for t in rel.types]
                times = frozenset(i for i, t in enumerate(types) if t in _PLAIN_TIME_TYPES)
                if any(word in t for i, t in enumerate(types) if i not in times for word in _ARROW_TYPE_WORDS):
                    return QueryResult(names, arrow=rel.to_arrow_table())
                if times:
                    # Top-level times as epoch nanoseconds (Python's datetime would drop them below the µs): no
                    # pyarrow to import for the commonest queries (records of a head in a time window).
                    rel = rel.project(
                        ", ".join(f"epoch_ns(#{i + 1})" if i in times else f"#{i + 1}" for i in range(len(types)))
                    )
                return QueryResult(names, rows=rel.fetchall(), ns_columns=times)
            except duckdb.Error as exc:
                raise QueryError(one_line(exc)) from None
    finally:
        con.close()


def plain_result(con: duckdb.DuckDBPyConnection, sql: str) -> QueryResult | None:
    """The result as Python rows, top-level times as epoch nanoseconds, by DuckDB's engine alone (see
    :func:`engine`); None: a column needs Arrow, or ``DESCRIBE`` cannot type the statement (EXPLAIN) or fails, or
    the statement cannot be read as a subquery (then the package's relations answer, and raise its error)."""
    found = _plain_cursor(con, sql)
    if found is None:
        return None
    names, times, cursor, _ = found
    try:
        rows = cursor.fetchall()
    except engine().Error as exc:
        raise QueryError(one_line(exc)) from None
    return QueryResult(names, rows=rows, ns_columns=times)


def _plain_cursor(con: duckdb.DuckDBPyConnection, sql: str) -> tuple[list[str], frozenset[int], Any, str] | None:
    """(column names, the columns of times as epoch ns, the statement's result, the statement) for
    :func:`plain_result`; None as there."""
    error = engine().Error
    try:
        columns = con.execute(f"DESCRIBE {sql}").fetchall()
    except error:
        return None
    types = [str(c[1]).upper() for c in columns]
    times = frozenset(i for i, t in enumerate(types) if t in _PLAIN_TIME_TYPES)
    if any(word in t for i, t in enumerate(types) if i not in times for word in _ARROW_TYPE_WORDS):
        return None
    statement = sql
    if times:
        # As the relations project them: the statement as a subquery (on lines of its own: a trailing comment
        # stays inside), whose order a projection keeps.
        picked = ", ".join(f"epoch_ns(#{i + 1})" if i in times else f"#{i + 1}" for i in range(len(types)))
        statement = f"SELECT {picked} FROM (\n{sql.rstrip().rstrip(';')}\n)"
    try:
        cursor = con.execute(statement)
    except error as exc:
        if times:
            return None
        raise QueryError(one_line(exc)) from None
    return [str(c[0]) for c in columns], times, cursor, statement


def run_query_batches(
    root: Path,
    sql: str,
    manifest: Manifest | None = None,
    computed: Mapping[str, ComputedView] | None = None,
    batch_rows: int = 100_000,
    arrow_after_rows: int | None = None,
) -> Iterator[QueryResult]:
    """:func:`run_query_result` in batches of at most ``batch_rows`` rows (at least one, maybe empty): a result of
    millions of rows is written as it is read, in bounded memory, and stops when its reader leaves (``| head``).
    A result that needs Arrow's types comes whole, as one batch.

    ``arrow_after_rows``: a result of more rows comes as Arrow batches (``QueryResult.arrow``, times still as
    epoch ns in ``ns_columns``), to be written column by column (console.sinks.query_text); a short one comes as
    Python rows, without importing pyarrow.
    """
    con = _query_connection(root, sql, manifest, computed, engine_only=True)
    try:
        with interruptible(con):
            found = _plain_cursor(con, sql)
            if found is not None:
                names, times, cursor, statement = found
                first = batch_rows if arrow_after_rows is None else min(batch_rows, arrow_after_rows + 1)
                while True:
                    try:
                        rows = cursor.fetchmany(first)
                    except engine().Error as exc:  # a cast or a division fails as the rows are made
                        raise QueryError(one_line(exc)) from None
                    if arrow_after_rows is not None and len(rows) > arrow_after_rows:
                        # Long: the statement again, every row from that run.  Its relation's Arrow reader streams,
                        # where this result's would first copy all of it (3 M archive records: 0.9 GB against
                        # 0.14); a second run costs a blocking statement's sort or grouping once more, against
                        # writing each row from Python values (5x slower).
                        del rows
                        if hasattr(cursor, "abort"):  # DuckDB 2 (1.x: the next statement ends this result)
                            cursor.abort()
                        yield from _arrow_batches(con, statement, names, times, batch_rows)
                        return
                    yield QueryResult(names, rows=rows, ns_columns=times)
                    if len(rows) < first:
                        return
                    first = batch_rows
    finally:
        con.close()
    yield run_query_result(root, sql, manifest, computed)


def _arrow_batches(
    con: duckdb.DuckDBPyConnection, statement: str, names: list[str], times: frozenset[int], batch_rows: int
) -> Iterator[QueryResult]:
    """A statement's rows as Arrow batches, streamed."""
    import duckdb  # the package: relations and their Arrow readers
    import pyarrow as pa

    try:
        reader = con.sql(statement).to_arrow_reader(batch_rows)
    except duckdb.Error as exc:
        raise QueryError(one_line(exc)) from None
    while True:
        try:
            batch = reader.read_next_batch()
        except StopIteration:
            return
        except (duckdb.Error, pa.ArrowException) as exc:  # a cast or a division fails as the rows are made
            raise QueryError(one_line(exc)) from None
        yield QueryResult(names, arrow=pa.Table.from_batches([batch]), ns_columns=times)


def show_query(
    root: Path,
    sql: str,
    manifest: Manifest | None = None,
    width: int | None = None,
    computed: Mapping[str, ComputedView] | None = None,
) -> str:
    """One read-only query's result in DuckDB's box, fitted to ``width`` (the terminal's) (console.archive.box)."""
    import duckdb

    from console.archive.box import render

    con = _query_connection(root, sql, manifest, computed)
    try:
        with interruptible(con):
            try:
                rel = con.sql(sql)
                if rel is None:  # a statement without a result (none passes check_read_only today)
                    raise QueryError("the statement returns no rows")
                return render(rel, width)
            except duckdb.Error as exc:
                raise QueryError(one_line(exc)) from None
    finally:
        con.close()


def _query_connection(
    root: Path,
    sql: str,
    manifest: Manifest | None = None,
    computed: Mapping[str, ComputedView] | None = None,
    *,
    engine_only: bool = False,
) -> duckdb.DuckDBPyConnection:
    """A connection with views for the tables ``sql`` names (and the computed views it names), the statement
    checked read-only (``engine_only``: see :func:`connect`)."""
    named = {t for t in TABLES if re.search(rf"\b{t}\b", sql, re.IGNORECASE)}
    wanted = [name for name in computed or {} if re.search(rf"\b{name}\b", sql, re.IGNORECASE)]
    tables = None
    if computed and wanted:
        m = manifest if manifest is not None else read_current(root)
        manifest, tables = m, {name: computed[name](root, m) for name in wanted}
    con, _ = connect(root, manifest, tables=named, sql=sql, computed=tables, engine_only=engine_only)
    try:
        check_read_only(con, sql)
    except BaseException:
        con.close()
        raise
    return con


def run_query_arrow(root: Path, sql: str, computed: Mapping[str, ComputedView] | None = None) -> pa.Table:
    """The result of one read-only query over the archive as an Arrow table: times keep their nanoseconds."""
    import duckdb

    con = _query_connection(root, sql, computed=computed)
    try:
        try:
            rel = con.sql(sql)
            if rel is None:  # a statement without a result (none passes check_read_only today)
                raise QueryError("the statement returns no rows")
            return rel.to_arrow_table()
        except duckdb.Error as exc:
            raise QueryError(one_line(exc)) from None
    finally:
        con.close()


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
