"""trackside query."""

from __future__ import annotations

import csv
import datetime as dt
import itertools
import json
import sys
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING, Annotated, Any, cast

import typer

from console import exit_codes
from console.cli.commands.ingest import ArchiveOpt
from console.cli.common import fail, guard
from console.safe_text import clean

if TYPE_CHECKING:
    from pathlib import Path

    import pyarrow as pa

    from console.archive.store import Manifest
    from console.archive.views import QueryResult

FORMATS = ("table", "csv", "json", "jsonl")
# Up to this many rows the times are formatted one by one (timefmt.iso), as the other values are: a query of a
# head's hour (a few thousand rows) then never imports numpy, a tenth of a second of its start-up; above it the
# vectorized iso_array is quicker than the import.  Both give the same text (tests/test_query_times.py).
SCALAR_TIMES_MAX_ROWS = 50_000


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
            " more than 40 rows), or csv, json, jsonl (every row, every value whole).",
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
    from console.archive.store import ArchiveError, archive_dir
    from console.archive.views import QueryError, require_archive, run_query_batches, schema, show_query

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
            batches = run_query_batches(root, text, manifest, computed)
            first = next(batches)
            rows = (_output_rows(b) for b in itertools.chain([first], batches))
            _emit_batches(first.names, rows, fmt)
        except (ArchiveError, QueryError) as exc:
            raise fail(str(exc)) from None
        return exit_codes.OK

    raise typer.Exit(guard(body))


def _forecasts(root: Path, manifest: Manifest) -> pa.Table:
    """The ``forecasts`` view: every series' forecast (console.archive.health_days), made when a query names it."""
    from console.archive.health_days import query_forecasts  # pandas and the fit: only for a query that needs them

    return query_forecasts(root, manifest)


def _plain_rows(rows: list[tuple[object, ...]], ns_columns: frozenset[int]) -> list[tuple[Any, ...]]:
    """Rows of Python values as output values; ``ns_columns`` hold epoch ns, written as _column writes times."""
    # Most values (text, integers, flags, nulls) are their own output: tested by exact type before _plain's
    # checks, which took most of a head's hour query's formatting (1,881 rows × 20 columns: 22 → 8 ms).
    as_is = _AS_IS
    if not ns_columns or not rows:
        return [tuple(v if type(v) in as_is else _plain(v) for v in r) for r in rows]
    if len(rows) <= SCALAR_TIMES_MAX_ROWS:
        from console.analysis.timefmt import iso

        return [
            tuple(
                iso(cast(int | None, v)) if i in ns_columns else v if type(v) in as_is else _plain(v)
                for i, v in enumerate(r)
            )
            for r in rows
        ]
    import numpy as np

    from console.analysis.timefmt import iso_array

    columns: list[list[Any]] = [list(c) for c in zip(*rows, strict=True)]
    for i, col in enumerate(columns):
        if i in ns_columns:
            present = np.array([v is not None for v in col], bool)
            values = np.array([v if v is not None else 0 for v in col], np.int64)
            text = iso_array(values)
            text[~present] = None
            columns[i] = text.tolist()
        else:
            columns[i] = [_plain(v) for v in col]
    return list(zip(*columns, strict=True))


# Exact types _plain returns unchanged (a subclass, a float's NaN, go through _plain).
_AS_IS = frozenset((str, int, bool, type(None)))


def _plain(value: Any) -> Any:
    """A Python value as JSON and CSV can hold it (times are formatted per column, see _column)."""
    if isinstance(value, dt.datetime):
        return _utc_text(value)
    if isinstance(value, dt.date | dt.time):
        return value.isoformat()
    if isinstance(value, dt.timedelta):
        return value.total_seconds()
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, float) and value != value:
        return None
    if hasattr(value, "as_tuple"):  # Decimal
        return float(value)
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value


def _utc_text(value: dt.datetime) -> str:
    """A datetime inside a nested value: ISO in UTC with Z (a naive time is the logs' own, read as UTC)."""
    if value.tzinfo is not None:
        value = value.astimezone(dt.UTC).replace(tzinfo=None)
    return value.isoformat(timespec="milliseconds" if not value.microsecond % 1000 else "microseconds") + "Z"


def _column(col: pa.ChunkedArray) -> list[Any]:
    """One result column as output values; timestamps as ISO 8601 UTC with Z, nanoseconds kept.

    The archive's times are the logs' (naive, read as UTC like every other
    trackside command, console.analysis.timefmt); a zone-aware timestamp is
    stored as UTC by Arrow.  Either way the text is timefmt.iso's.
    """
    import pyarrow as pa

    typ = col.type
    if pa.types.is_timestamp(typ):
        import numpy as np

        from console.analysis.timefmt import iso_array

        # Straight from the Arrow buffers: to_numpy/fill_null on an array with nulls import pandas (0.3 s).
        ns = col.combine_chunks().cast(pa.timestamp("ns", typ.tz)).cast(pa.int64())
        n, off = len(ns), ns.offset
        values = np.frombuffer(ns.buffers()[1], np.int64, count=off + n)[off:].copy()
        if ns.null_count:
            bits = np.unpackbits(np.frombuffer(ns.buffers()[0], np.uint8), bitorder="little")
            present = bits[off : off + n].astype(bool)
            values[~present] = 0
        else:
            present = np.ones(n, bool)
        text = iso_array(values)
        text[~present] = None
        return text.tolist()
    if typ == pa.month_day_nano_interval():
        # Seconds, as a timedelta was; an interval of months has no fixed length: its text.
        return [
            None if v is None else str(v) if v.months else v.days * 86_400 + v.nanoseconds / 1e9
            for v in col.to_pylist()
        ]
    return [_plain(v) for v in col.to_pylist()]


def _output_rows(result: QueryResult) -> list[tuple[Any, ...]]:
    """A batch of the result as output values (see _column and _plain_rows)."""
    if result.arrow is not None:
        columns = [_column(c) for c in result.arrow.columns]
        return list(zip(*columns, strict=True)) if columns else []
    return _plain_rows(result.rows or [], result.ns_columns)


def _emit(names: list[str], rows: list[tuple[Any, ...]] | list[tuple[str, str, str]], fmt: str) -> None:
    """Rows whose values are already plain (see _column)."""
    _emit_batches(names, iter([rows]), fmt)


def _emit_batches(names: list[str], batches: Iterator[Sequence[tuple[Any, ...]]], fmt: str) -> None:
    """Batches of rows whose values are already plain, each written as it comes (the table: all at once)."""
    out = sys.stdout
    if fmt == "csv":
        w = csv.writer(out, lineterminator="\n")
        w.writerow(names)
        # Text values inert, as in the table: a log line's or a file name's escape sequences and bidi
        # overrides must not act on the terminal or the spreadsheet that shows the CSV (JSON escapes C0 itself).
        for rows in batches:
            for r in rows:
                w.writerow(["" if v is None else clean(v) if isinstance(v, str) else v for v in r])
    elif fmt == "json":
        # One array, written row by row as json.dump writes a list: "[{…}, {…}]".
        sep = "["
        for rows in batches:
            for r in rows:
                out.write(sep + json.dumps(dict(zip(names, r, strict=True)), ensure_ascii=False, default=str))
                sep = ", "
        out.write("[]\n" if sep == "[" else "]\n")
    elif fmt == "jsonl":
        for rows in batches:
            for r in rows:
                out.write(json.dumps(dict(zip(names, r, strict=True)), ensure_ascii=False, default=str) + "\n")
    else:
        from console.archive.box import render_rows

        out.write(render_rows(names, [r for rows in batches for r in rows]))
    out.flush()
