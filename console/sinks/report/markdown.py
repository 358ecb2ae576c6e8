"""The report as Markdown: the outline's headings, paragraphs and tables, for tickets and mail.

Every text is escaped for Markdown *and* for the HTML a Markdown viewer
may pass through: control characters become ``\\xNN`` (no terminal escape
reaches a terminal that prints the file), bidirectional overrides and
isolates ``\\u202e`` (no name or log line displays reversed), a file
name's bytes that are not UTF-8 ``\\xff``, ``& < >`` become entities, and
the characters that make Markdown structure (``\\ ` * _ [ ] | # ~``, and
a list or heading marker at the start of a text) are backslash-escaped.
A log's text therefore never becomes a link, emphasis, a heading, a table
cell boundary or live HTML.  Plots are HTML only; their data are the tables.
"""

from __future__ import annotations

import re
from typing import Any

from console.safe_text import PLAIN, clean
from console.sinks.report.blocks import Block, Bullets, Cell, Figure, Heading, Para, Styled, Table
from console.sinks.report.jsonwrite import Write
from console.sinks.report.outline import outline

_SPECIAL = re.compile(r"([\\`*_\[\]|#~])")
_LEADING = re.compile(r"^(\s*)([-+*]|\d+[.)])(?=\s|$)")
# Text md_escape returns unchanged (PLAIN, and the arrows and dash the tables show): checked once per row.
_ROW_INERT = re.compile(r"[A-Za-z0-9 .:,/%()+=\-\u2190\u2192\u2194\u2013]*")
_STRONG = ("strong", "verdict-unsafe", "verdict-failing", "verdict-ok", "unsafe")


def md_escape(value: object, line_start: bool = False) -> str:
    """Text made inert in Markdown: no structure, no HTML, no control characters.

    ``line_start``: the text begins a line (a paragraph, a list item), where
    ``- ``, ``+ ``, ``1. `` would start a list: escape that marker too.
    """
    if type(value) is str and not line_start and PLAIN.fullmatch(value):
        return value  # nothing to escape (most table cells): the escapes below would change nothing
    text = clean(value)
    text = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    text = _SPECIAL.sub(r"\\\1", text)
    return _LEADING.sub(lambda m: m.group(1) + "\\" + m.group(2), text) if line_start else text


def _cell(c: Cell, line_start: bool = False) -> str:
    if isinstance(c, Styled):
        text = md_escape(c.text)
        return f"**{text}**" if c.style in _STRONG and text else text
    return md_escape(c, line_start)


def _table(t: Table, write: Write) -> None:
    """The table, then its note as a paragraph of its own; rows written as they are made."""
    write("| " + " | ".join(md_escape(c) for c in t.columns) + " |\n")
    write("|" + "|".join("---:" if n else "---" for n in t.numeric) + "|")
    for row in t.rows:
        texts = [c.text if isinstance(c, Styled) else c for c in row]
        try:
            inert = _ROW_INERT.fullmatch("".join(texts)) is not None
        except TypeError:  # a cell that is not text: the escaping path says what it is
            inert = False
        if inert:  # no cell has anything to escape (most rows): one check per row, not per cell
            cells = [
                f"**{x}**" if x and isinstance(c, Styled) and c.style in _STRONG else x or " "
                for c, x in zip(row, texts, strict=True)
            ]
        else:
            cells = [_cell(c) or " " for c in row]
        write("\n| " + " | ".join(cells) + " |")
    if t.note:
        write(f"\n\n_{md_escape(t.note)}_")


def write_blocks(blocks: list[Block], write: Write) -> None:
    """The blocks as Markdown, a blank line between them (figures are the HTML face's)."""
    first = True
    for b in blocks:
        if isinstance(b, Figure):
            continue  # plots are drawn in the HTML report; the tables hold their data
        if not first:
            write("\n\n")
        first = False
        if isinstance(b, Heading):
            write("#" * b.level + " " + md_escape(b.text))
        elif isinstance(b, Para):
            write("".join(_cell(c, line_start=i == 0) for i, c in enumerate(b.parts)))
        elif isinstance(b, Table):
            _table(b, write)
        elif isinstance(b, Bullets):
            write("\n".join(f"- {md_escape(item, line_start=True)}" for item in b.items))
    write("\n")


def render_markdown(doc: dict[str, Any], write: Write) -> None:
    """The report document (:func:`console.sinks.report.document.document`) as Markdown, piece by piece."""
    write_blocks(outline(doc), write)
