"""The report's building blocks: headings, paragraphs, tables, bullets, figures, and the helpers that make them.

:func:`console.sinks.report.outline.outline` and the archive's parts (:mod:`console.sinks.report.trends`,
:mod:`console.sinks.report.forecast`) build the report from these; the Markdown and HTML faces render them.
Every string in a block is raw text (from a log or not): the renderers escape all of it for their format.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Styled:
    """Text with a style hint the HTML face shows (state, severity, verdict); Markdown shows the text."""

    text: str
    style: str = ""


Cell = str | Styled


@dataclass(frozen=True)
class Heading:
    level: int
    text: str
    anchor: str = ""


@dataclass(frozen=True)
class Para:
    parts: tuple[Cell, ...]


@dataclass(frozen=True)
class Table:
    columns: tuple[str, ...]
    numeric: tuple[bool, ...]  # right-aligned columns
    rows: Iterable[list[Cell]]  # a long table's rows are made as they are written (:class:`Lazy`)
    note: str = ""


class Lazy:
    """Rows made each time they are read, from the document's :class:`~console.sinks.report.jsonwrite.Rows`."""

    def __init__(self, make: Callable[[], Iterator[list[Cell]]]) -> None:
        self._make = make

    def __iter__(self) -> Iterator[list[Cell]]:
        return self._make()


@dataclass(frozen=True)
class Bullets:
    items: tuple[str, ...]


@dataclass(frozen=True)
class Figure:
    plot: str  # speeds | sections | crossings | analog: drawn by the HTML face from ReportData


Block = Heading | Para | Table | Bullets | Figure


def num_or_dash(x: Any, fmt: str = "{:.1f}") -> str:
    """A number in ``fmt``; none (or NaN) as ``–``."""
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else fmt.format(x)


def table_block(columns: list[tuple[str, bool]], rows: Iterable[list[Cell]], note: str = "") -> Table:
    """A table from (heading, numeric) columns and its rows."""
    return Table(tuple(c for c, _ in columns), tuple(n for _, n in columns), rows, note)
