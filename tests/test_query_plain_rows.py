"""`query`'s row formatting: the values passed through as they are (text, integers, flags, nulls) give what
_plain gives them, and every other kind still goes through _plain, with or without a time column."""

from __future__ import annotations

import datetime as dt
import decimal
import enum
import math
import random

from console.analysis.timefmt import iso
from console.sinks.query_text import plain_rows as _plain_rows
from console.sinks.query_text import plain_value as _plain


class _Code(enum.IntEnum):
    A = 7


class _Text(str):
    pass


VALUES: list[object] = [
    "WS1",
    "",
    "é\ud800",
    _Text("x"),
    0,
    -(1 << 70),
    True,
    False,
    None,
    _Code.A,
    1.5,
    math.nan,
    -0.0,
    decimal.Decimal("2.50"),
    dt.date(2026, 3, 2),
    dt.time(1, 2, 3),
    dt.datetime(2026, 3, 2, 8, 0, 0, 250_000),
    dt.datetime(2026, 3, 2, 10, tzinfo=dt.timezone(dt.timedelta(hours=2))),
    dt.timedelta(seconds=1.25),
    b"\x01\xff",
    [1, "a", dt.date(2026, 1, 1)],
    ("t", None),
    {"a": dt.datetime(2026, 1, 1), 3: math.nan},
]


def _same(a: object, b: object) -> bool:
    return type(a) is type(b) and repr(a) == repr(b)  # NaN-safe, and 1 is not True


def test_rows_are_plain_values_value_for_value() -> None:
    rng = random.Random(28)
    rows = [tuple(rng.choice(VALUES) for _ in range(6)) for _ in range(2_000)]
    got = _plain_rows(rows, frozenset())
    assert len(got) == len(rows)
    for g, r in zip(got, rows, strict=True):
        assert all(_same(x, _plain(v)) for x, v in zip(g, r, strict=True))


def test_rows_with_a_time_column_format_it_and_the_rest_as_plain() -> None:
    rng = random.Random(29)
    rows = [(rng.choice([None, rng.randrange(-(1 << 62), 1 << 62)]), *rng.sample(VALUES, 4)) for _ in range(2_000)]
    got = _plain_rows(rows, frozenset({0}))
    for g, r in zip(got, rows, strict=True):
        assert g[0] == iso(r[0])  # type: ignore[arg-type]
        assert all(_same(x, _plain(v)) for x, v in zip(g[1:], r[1:], strict=True))
