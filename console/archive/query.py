"""Read-only queries over the archive: the statement checked, run on a connection of console.archive.views.

Only one SELECT-like statement is accepted (SELECT, WITH, FROM, VALUES, DESCRIBE, SHOW, SUMMARIZE, EXPLAIN);
its result comes as Python rows or Arrow (whole, or in batches), or in DuckDB's box (console.archive.box).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from console.archive.duck import engine
from console.archive.store import Manifest, read_current
from console.archive.tables import TABLES
from console.archive.views import connect
from console.interrupt import interruptible
from console.safe_text import one_line

if TYPE_CHECKING:
    import duckdb
    import pyarrow as pa

# A view computed in Python when a statement names it (the forecasts): (the archive, its manifest) → the table.
# The command that offers one passes it in; the archive's views know only the stored tables.
ComputedView = Callable[[Path, Manifest], "pa.Table"]

ALLOWED_STATEMENTS = ("SELECT", "EXPLAIN")


class QueryError(Exception):
    """Bad SQL or a statement the archive does not run: DuckDB's message, one line."""


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
    :func:`~console.archive.duck.engine`); None: a column needs Arrow, or ``DESCRIBE`` cannot type the statement
    (EXPLAIN) or fails, or the statement cannot be read as a subquery (then the package's relations answer, and
    raise its error)."""
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
    checked read-only (``engine_only``: see :func:`~console.archive.views.connect`)."""
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
