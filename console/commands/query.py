"""trackside query."""

from __future__ import annotations

import csv
import datetime as dt
import json
import sys
from typing import Annotated, Any

import typer

from console import exit_codes
from console.commands.common import Console, fail, guard
from console.commands.ingest import ArchiveOpt

FORMATS = ("table", "csv", "json", "jsonl")


def query(
    sql: Annotated[str | None, typer.Argument(help="One SELECT (or WITH, DESCRIBE, SHOW, EXPLAIN) statement.")] = None,
    archive: ArchiveOpt = None,
    fmt: Annotated[str, typer.Option("--format", help="table, csv, json or jsonl.")] = "table",
    show_schema: Annotated[bool, typer.Option("--schema", help="List the tables and their columns.")] = False,
    preset: Annotated[
        str | None, typer.Option("--preset", help="A named query (see --list-presets).", show_default=False)
    ] = None,
    list_presets: Annotated[bool, typer.Option("--list-presets", help="List the named queries.")] = False,
) -> None:
    """SQL (DuckDB) over the archive, read-only: one view per table."""
    from console.archive.presets import PRESETS
    from console.archive.store import ArchiveError, archive_dir
    from console.archive.views import QueryError, require_archive, run_query, schema

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
            require_archive(root)
            if show_schema:
                _emit(["table", "column", "type"], schema(root), fmt)
                return exit_codes.OK
            text = sql
            if preset is not None:
                if preset not in PRESETS:
                    raise fail(f"--preset: unknown {preset!r}; known: {', '.join(PRESETS)}")
                text = PRESETS[preset].sql
            assert text is not None
            names, rows = run_query(root, text)
        except (ArchiveError, QueryError) as exc:
            raise fail(str(exc)) from None
        _emit(names, rows, fmt)
        return exit_codes.OK

    raise typer.Exit(guard(body))


def _plain(value: Any) -> Any:
    if isinstance(value, dt.datetime | dt.date | dt.time):
        return value.isoformat()
    if isinstance(value, dt.timedelta):
        return value.total_seconds()
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float) and value != value:
        return None
    if hasattr(value, "as_tuple"):  # Decimal
        return float(value)
    return value


def _emit(names: list[str], rows: list[tuple[Any, ...]] | list[tuple[str, str, str]], fmt: str) -> None:
    out = sys.stdout
    if fmt == "csv":
        w = csv.writer(out, lineterminator="\n")
        w.writerow(names)
        for r in rows:
            w.writerow(["" if v is None else _plain(v) for v in r])
    elif fmt == "json":
        json.dump([dict(zip(names, map(_plain, r), strict=True)) for r in rows], out, ensure_ascii=False, default=str)
        out.write("\n")
    elif fmt == "jsonl":
        for r in rows:
            out.write(json.dumps(dict(zip(names, map(_plain, r), strict=True)), ensure_ascii=False, default=str) + "\n")
    else:
        from rich.table import Column, Table

        from console.safe_text import inert

        table = Table(*[Column(inert(n)) for n in names], show_lines=False)
        for r in rows:
            table.add_row(*[inert("" if v is None else _plain(v)) for v in r])
        con = Console(highlight=False)
        con.print(table)
        con.print(f"{len(rows)} rows", markup=False)
    out.flush()
