"""trackside query."""

from __future__ import annotations

import itertools
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, Annotated, Any

import typer

from console import exit_codes
from console.cli.commands.ingest import ArchiveOpt
from console.cli.common import fail, guard
from console.sinks.query_text import ResultWriter, plain_rows

if TYPE_CHECKING:
    from pathlib import Path

    import pyarrow as pa

    from console.archive.query import QueryResult
    from console.archive.store import Manifest

FORMATS = ("table", "csv", "json", "jsonl")
# A result's first this many rows are written from Python values, the rest (if any) column by column from Arrow
# batches: a head's hour (a few thousand rows) never imports pyarrow, millions of rows are written at Arrow's
# speed (console.sinks.query_text; the same text either way, tests/test_query_text.py).
ARROW_AFTER_ROWS = 5_000


def query(
    sql: Annotated[
        str | None, typer.Argument(metavar="SQL", help="One SELECT (or WITH, DESCRIBE, SHOW, EXPLAIN) statement.")
    ] = None,
    archive: ArchiveOpt = None,
    fmt: Annotated[
        str,
        typer.Option(
            "--format",
            metavar="table|csv|json|jsonl",
            help="table (DuckDB's box fitted to the terminal: long values cut with …, the first and last 20 of"
            " more than 40 rows), or csv, json, jsonl (every row, every value whole; in JSON a NaN or an infinity is"
            " null).",
        ),
    ] = "table",
    show_schema: Annotated[bool, typer.Option("--schema", help="List the tables and their columns.")] = False,
    preset: Annotated[
        str | None,
        typer.Option("--preset", metavar="NAME", help="A named query (see --list-presets).", show_default=False),
    ] = None,
    list_presets: Annotated[
        bool, typer.Option("--list-presets", help="List the named queries (--preset NAME) and what each shows.")
    ] = False,
) -> None:
    """SQL (DuckDB) over the archive, read-only: one view per table."""
    from console.archive.presets import PRESETS
    from console.archive.query import QueryError, run_query_batches, show_query
    from console.archive.store import ArchiveError, archive_dir
    from console.archive.views import require_archive, schema

    computed = {"forecasts": _forecasts}

    root = archive_dir(archive)

    def body() -> int:
        if fmt not in FORMATS:
            raise fail(f"--format: expected table, csv, json or jsonl, found {fmt!r}")
        if list_presets:
            _emit(["preset", "what it shows"], [(k, v.doc) for k, v in PRESETS.items()], fmt)
            return exit_codes.OK
        given = sum(x for x in (sql is not None, preset is not None, show_schema))
        if given != 1:
            raise fail("give one of: SQL, --preset NAME, --schema")
        try:
            manifest = require_archive(root)
            if show_schema:
                _emit(["table", "column", "type"], schema(root), fmt)
                return exit_codes.OK
            text = sql
            if preset is not None:
                if preset not in PRESETS:
                    raise fail(f"--preset: unknown {preset!r}; known: {', '.join(PRESETS)}")
                text = PRESETS[preset].sql
            assert text is not None
            if fmt == "table":
                sys.stdout.write(show_query(root, text, manifest, computed=computed))
                sys.stdout.flush()
                return exit_codes.OK
            # In batches, each written before the next is read: millions of rows in bounded memory, and a
            # reader that leaves (| head) stops the query.
            _emit_results(run_query_batches(root, text, manifest, computed, arrow_after_rows=ARROW_AFTER_ROWS), fmt)
        except (ArchiveError, QueryError) as exc:
            raise fail(str(exc)) from None
        return exit_codes.OK

    raise typer.Exit(guard(body))


def _forecasts(root: Path, manifest: Manifest) -> pa.Table:
    """The ``forecasts`` view: every series' forecast (console.archive.health_days), made when a query names it."""
    from console.archive.health_days import query_forecasts  # pandas and the fit: only for a query that needs them

    return query_forecasts(root, manifest)


def _emit(names: list[str], rows: list[tuple[Any, ...]] | list[tuple[str, str, str]], fmt: str) -> None:
    """Rows whose values are already plain (see query_text.plain_value)."""
    if fmt == "table":
        from console.archive.box import render_rows

        sys.stdout.write(render_rows(names, rows))
    else:
        writer = ResultWriter(sys.stdout, names, fmt)
        writer.rows(rows)
        writer.close()
    sys.stdout.flush()


def _emit_results(results: Iterator[QueryResult], fmt: str) -> None:
    """A result's parts (csv, json, jsonl), each written as it comes."""
    first = next(results)
    writer = ResultWriter(sys.stdout, first.names, fmt)
    for part in itertools.chain([first], results):
        if part.arrow is None:
            writer.rows(plain_rows(part.rows or [], part.ns_columns))
        else:
            for batch in part.arrow.to_batches():
                writer.batch(batch, part.ns_columns)
    writer.close()
