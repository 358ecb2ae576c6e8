"""A query's result as CSV, JSON and JSONL text: Python rows value by value, Arrow batches column by column.

Both give the same text.  Python rows are a short result's (no pyarrow to import); a long result comes in Arrow
batches, each turned into text by Arrow's compute kernels a column at a time (tests/test_query_text.py holds
the two to the same bytes).  The text rules:

- times: ISO 8601 UTC with Z, nanoseconds kept (console.analysis.timefmt);
- floats as Python writes them (``repr``), a NaN as no value;
- CSV: the csv module's (minimal quoting), text values made inert (console.safe_text.clean): a log line's
  escape sequences must not act on the terminal or the spreadsheet that shows the CSV;
- JSON: ``json.dumps`` of the row as an object (JSON escapes C0 itself), strict: an infinity is null.
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import math
from collections.abc import Sequence
from typing import IO, TYPE_CHECKING, Any, cast

from console.safe_text import clean

if TYPE_CHECKING:
    import pyarrow as pa

# Exact types plain_value returns unchanged (a subclass, a float's NaN, go through plain_value).
AS_IS = frozenset((str, int, bool, type(None)))


def plain_rows(rows: list[tuple[object, ...]], ns_columns: frozenset[int]) -> list[tuple[Any, ...]]:
    """Rows of Python values as output values (plain_value's); ``ns_columns`` hold epoch ns, written as
    arrow_values writes times."""
    # Most values (text, integers, flags, nulls) are their own output: tested by exact type before _plain's
    # checks, which took most of a head's hour query's formatting (1,881 rows × 20 columns: 22 → 8 ms).
    as_is = AS_IS
    if not ns_columns or not rows:
        return [tuple(v if type(v) in as_is else plain_value(v) for v in r) for r in rows]
    # Times one by one (timefmt.iso): rows come here a few thousand at most (a longer result is written from
    # Arrow batches, its times by iso_array; the same text, tests/test_query_times.py), and a head's hour
    # never imports numpy, a tenth of a second of its start-up.
    from console.analysis.timefmt import iso

    return [
        tuple(
            iso(cast(int | None, v)) if i in ns_columns else v if type(v) in as_is else plain_value(v)
            for i, v in enumerate(r)
        )
        for r in rows
    ]


def plain_value(value: Any) -> Any:
    """A Python value as JSON and CSV can hold it (top-level times are formatted per column, see arrow_values)."""
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
        return [plain_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain_value(v) for k, v in value.items()}
    return value


def _utc_text(value: dt.datetime) -> str:
    """A datetime inside a nested value: ISO in UTC with Z (a naive time is the logs' own, read as UTC)."""
    if value.tzinfo is not None:
        value = value.astimezone(dt.UTC).replace(tzinfo=None)
    return value.isoformat(timespec="milliseconds" if not value.microsecond % 1000 else "microseconds") + "Z"


def arrow_values(col: pa.ChunkedArray | pa.Array) -> list[Any]:
    """One Arrow column as output values (plain_value's); timestamps as ISO 8601 UTC with Z, nanoseconds kept.

    The archive's times are the logs' (naive, read as UTC like every other trackside command,
    console.analysis.timefmt); a zone-aware timestamp is stored as UTC by Arrow.
    """
    import pyarrow as pa

    typ = col.type
    if pa.types.is_timestamp(typ):
        return _iso_texts(col.cast(pa.timestamp("ns", typ.tz)).cast(pa.int64())).tolist()
    if typ == pa.month_day_nano_interval():
        # Seconds, as a timedelta was; an interval of months has no fixed length: its text.
        return [
            None if v is None else str(v) if v.months else v.days * 86_400 + v.nanoseconds / 1e9
            for v in col.to_pylist()
        ]
    return [plain_value(v) for v in col.to_pylist()]


def _iso_texts(ns: pa.ChunkedArray | pa.Array) -> Any:
    """Epoch ns (int64, maybe with nulls) as timefmt.iso's text, None for a null: an object array."""
    import numpy as np
    import pyarrow as pa

    from console.analysis.timefmt import iso_array

    if isinstance(ns, pa.ChunkedArray):
        ns = ns.combine_chunks()
    # Straight from the Arrow buffers: to_numpy/fill_null on an array with nulls import pandas (0.3 s).
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
    return text


class ResultWriter:
    """A result written as ``fmt`` (csv, json, jsonl) text as its parts come: Python rows or Arrow batches."""

    def __init__(self, out: IO[str], names: list[str], fmt: str) -> None:
        self.out, self.names, self.fmt = out, names, fmt
        self.rows_written = 0
        if fmt == "csv":
            out.write(_csv_header(names))

    def rows(self, rows: Sequence[Sequence[Any]]) -> None:
        """Rows of plain values (see plain_value)."""
        out, names = self.out, self.names
        if self.fmt == "csv":
            w = csv.writer(out, lineterminator="\n")
            for r in rows:
                w.writerow(["" if v is None else clean(v) if isinstance(v, str) else v for v in r])
        else:
            for r in rows:
                line = json_text(dict(zip(names, r, strict=True)))
                out.write(self._json_sep() + line if self.fmt == "json" else line + "\n")
                self.rows_written += 1
        if self.fmt == "csv":
            self.rows_written += len(rows)

    def batch(self, batch: pa.RecordBatch, ns_columns: frozenset[int]) -> None:
        """An Arrow batch; ``ns_columns``: its columns of times as epoch ns."""
        if batch.num_rows:
            self.out.write(_batch_text(batch, self.names, ns_columns, self.fmt, self._json_sep()))
            self.rows_written += batch.num_rows

    def close(self) -> None:
        if self.fmt == "json":
            self.out.write("[]\n" if not self.rows_written else "]\n")
        self.out.flush()

    def _json_sep(self) -> str:
        return "[" if not self.rows_written else ", "


# ---- Arrow batches -----------------------------------------------------------------------------------------

# Characters that make the csv module quote a cell (minimal quoting, "," and '"', the line ends).
_CSV_QUOTED = r'[,"\n\r]'
# What safe_text.clean escapes, in RE2's syntax (Arrow text is valid UTF-8: no lone surrogates).
_CLEANED = (
    r"[\x00-\x1f\x7f-\x9f\x{061c}\x{180e}\x{200b}-\x{200f}\x{2028}-\x{202e}\x{2060}-\x{206f}\x{feff}"
    r"\x{e0000}-\x{e007f}]"
)
# What json.dumps escapes in a string (ensure_ascii=False): C0, the quote and the backslash.
_JSON_ESCAPED = r'[\x00-\x1f"\\]'


def _batch_text(batch: pa.RecordBatch, names: list[str], ns_columns: frozenset[int], fmt: str, sep: str) -> str:
    """One batch (with rows) as ``fmt`` text, the same as ResultWriter.rows gives for its rows as Python values;
    ``sep``: what comes before a JSON array's first row here."""
    import pyarrow.compute as pc

    n = batch.num_rows
    if fmt == "csv":
        cells = [_csv_cells(batch.column(i), i in ns_columns) for i in range(batch.num_columns)]
        if len(cells) == 1:  # the csv module quotes a row's only cell when it is empty
            cells[0] = pc.if_else(pc.equal(cells[0], ""), _text_scalar('""'), cells[0])
        lines = pc.binary_join_element_wise(*cells, _text_scalar(",")) if len(cells) > 1 else cells[0]
        return _joined(lines, "\n", n)
    # A dict keeps a repeated name once, at its first place, with its last value.
    last = {name: i for i, name in enumerate(names)}
    parts: list[Any] = []
    for k, name in enumerate(dict.fromkeys(names)):
        i = last[name]
        parts.append(("{" if k == 0 else ", ") + json.dumps(name, ensure_ascii=False) + ": ")
        parts.append(_json_values(batch.column(i), i in ns_columns))
    parts.append("}")
    rows = pc.binary_join_element_wise(*[_text_scalar(p) if isinstance(p, str) else p for p in parts], _text_scalar(""))
    if fmt == "json":
        return sep + _joined(rows, ", ", n)[: -len(", ")]
    return _joined(rows, "\n", n)


def _text_scalar(text: str) -> pa.Scalar:
    import pyarrow as pa

    return pa.scalar(text, pa.large_string())


def _csv_header(names: list[str]) -> str:
    import io

    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(names)
    return buf.getvalue()


def _joined(rows: pa.Array, end: str, n: int) -> str:
    """Every row's text followed by ``end``, as one string."""
    import pyarrow as pa
    import pyarrow.compute as pc

    ended = pc.binary_join_element_wise(rows.cast(pa.large_string()), _text_scalar(end), _text_scalar(""))
    data = ended.buffers()[2]
    if data is None:
        return ""
    import numpy as np

    offsets = np.frombuffer(ended.buffers()[1], np.int64, count=ended.offset + n + 1)[ended.offset :]
    return bytes(memoryview(data)[offsets[0] : offsets[-1]]).decode()


def _csv_cells(col: pa.Array, is_ns: bool) -> pa.Array:
    """A column as the csv module's cells: text, no nulls, quoted where it must be."""
    import pyarrow as pa
    import pyarrow.compute as pc

    typ = col.type
    if is_ns or pa.types.is_timestamp(typ):
        text = _times(col, is_ns)
    elif pa.types.is_integer(typ) or pa.types.is_date32(typ):
        text = pc.cast(col, pa.string())
    elif pa.types.is_boolean(typ):
        text = pc.if_else(col, "True", "False")
    elif pa.types.is_floating(typ):
        text = _float_texts(col, for_json=False)
    elif _is_text(typ):
        text = _redone(pc.cast(col, pa.large_string()), _CLEANED, clean)
    else:
        text = pa.array([_csv_cell(v) for v in arrow_values(col)], pa.large_string())
    text = pc.fill_null(pc.cast(text, pa.large_string()), "")
    mark = _text_scalar('"')
    quoted = pc.binary_join_element_wise(mark, pc.replace_substring(text, '"', '""'), mark, _text_scalar(""))
    return pc.if_else(pc.match_substring_regex(text, _CSV_QUOTED), quoted, text)


def _csv_cell(value: Any) -> str:
    """A plain value as the csv module writes it (floats by repr, the rest by str), text made inert."""
    if value is None:
        return ""
    return clean(value) if isinstance(value, str) else repr(value) if isinstance(value, float) else str(value)


def _json_values(col: pa.Array, is_ns: bool) -> pa.Array:
    """A column as json.dumps writes its values (``null`` for none)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    typ = col.type
    if is_ns or pa.types.is_timestamp(typ) or pa.types.is_date32(typ):
        text = _quoted(_times(col, is_ns) if not pa.types.is_date32(typ) else pc.cast(col, pa.string()))
    elif pa.types.is_integer(typ):
        text = pc.cast(col, pa.string())
    elif pa.types.is_boolean(typ):
        text = pc.if_else(col, "true", "false")
    elif pa.types.is_floating(typ):
        text = _float_texts(col, for_json=True)
    elif _is_text(typ):
        text = _redone(pc.cast(col, pa.large_string()), _JSON_ESCAPED, _json_string, _quoted)
    else:
        dumped = [None if v is None else json_text(v) for v in arrow_values(col)]
        text = pa.array(dumped, pa.large_string())
    return pc.fill_null(pc.cast(text, pa.large_string()), "null")


def json_text(value: Any) -> str:
    """``json.dumps`` of a row or a value, strict JSON: an infinity is null, as a NaN is (JSON has neither, and
    a script's parser refuses ``Infinity``)."""
    try:
        return json.dumps(value, ensure_ascii=False, default=str, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(value), ensure_ascii=False, default=str, allow_nan=False)


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    return value


def _json_string(value: str) -> str:
    return json.dumps(value, ensure_ascii=False)


def _quoted(text: pa.Array) -> pa.Array:
    import pyarrow.compute as pc

    mark = _text_scalar('"')
    return pc.binary_join_element_wise(mark, pc.cast(text, mark.type), mark, _text_scalar(""))


def _is_text(typ: pa.DataType) -> bool:
    import pyarrow as pa

    return bool(pa.types.is_string(typ) or pa.types.is_large_string(typ) or pa.types.is_string_view(typ))


def _times(col: pa.Array, is_ns: bool) -> pa.Array:
    import pyarrow as pa

    ns = col if is_ns else col.cast(pa.timestamp("ns", col.type.tz)).cast(pa.int64())
    return pa.array(_iso_texts(ns), pa.large_string())


def _redone(text: pa.Array, pattern: str, redo: Any, plain: Any = None) -> pa.Array:
    """``plain(text)`` (as it is, by default), but the values ``pattern`` finds, redone one by one by ``redo``
    (rare: a log line's control characters, a quote in a label)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    found = pc.fill_null(pc.match_substring_regex(text, pattern), False)
    done = text if plain is None else plain(text)
    if not pc.any(found).as_py():
        return done
    rows = np.flatnonzero(found.to_numpy(zero_copy_only=False))
    values = done.to_pylist()
    originals = text.take(pa.array(rows)).to_pylist()
    for row, value in zip(rows.tolist(), originals, strict=True):
        values[row] = redo(value)
    return pa.array(values, pa.large_string())


def _float_texts(col: pa.Array, for_json: bool) -> pa.Array:
    """Floats as ``repr`` writes them (NaN: null; JSON: an infinity null too), Arrow's text where it is the same."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    values = pc.cast(col, pa.float64())
    nan = pc.fill_null(pc.is_nan(values), False)
    values = pc.if_else(nan, pa.scalar(None, pa.float64()), values)
    text = pc.cast(values, pa.large_string())
    # Arrow and repr write the same shortest digits; a whole number is "36" in Arrow's text, "36.0" in repr's.
    whole = pc.invert(pc.match_substring_regex(text, r"[.eEna]"))
    text = pc.if_else(whole, pc.binary_join_element_wise(text, _text_scalar(".0"), _text_scalar("")), text)
    # They differ where either uses an exponent, and for the infinities: those are written by repr (json.dumps
    # writes repr too), an infinity in JSON as null (json_text).
    arr = values.to_numpy(zero_copy_only=False)
    with np.errstate(invalid="ignore"):
        mag = np.abs(arr)
        odd = (mag >= 1e16) | ((mag < 1e-4) & (mag > 0)) | np.isinf(arr)
    odd |= pc.fill_null(pc.match_substring_regex(text, "[eE]"), False).to_numpy(zero_copy_only=False)
    odd &= ~np.isnan(arr)
    if not odd.any():
        return text
    values_text = text.to_pylist()
    for row in np.flatnonzero(odd).tolist():
        v = float(arr[row])
        values_text[row] = None if for_json and math.isinf(v) else repr(v)
    return pa.array(values_text, pa.large_string())
