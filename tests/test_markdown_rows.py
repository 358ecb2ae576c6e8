"""Markdown table rows: the per-row check for text with nothing to escape writes what escaping every cell writes."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from console.sinks.report.blocks import Styled, Table
from console.sinks.report.markdown import _cell, _table

_TEXT = st.text(alphabet=st.sampled_from("aZ09 .:-→←–|*_<&\x1b\u202e#`é"), max_size=6)
_CELL = st.one_of(_TEXT, st.builds(Styled, _TEXT, st.sampled_from(["", "strong", "muted", "verdict-ok"])))


def _reference(t: Table) -> str:
    lines = [f"\n| {' | '.join(_cell(c) or ' ' for c in row)} |" for row in t.rows]
    return "".join(lines)


@settings(max_examples=400, deadline=None)
@given(st.lists(st.lists(_CELL, min_size=3, max_size=3), max_size=6))
def test_rows_written_as_escaping_each_cell_writes_them(rows: list[list[str | Styled]]) -> None:
    t = Table(("a", "b", "c"), (False, True, False), rows)
    out: list[str] = []
    _table(t, out.append)
    text = "".join(out)
    header, rule = text.split("\n", 2)[:2]
    assert text[len(header) + 1 + len(rule) :] == _reference(t)
    for row in rows:  # nothing from a cell is left live
        for c in row:
            text = c.text if isinstance(c, Styled) else c
            if "\x1b" in text or "\u202e" in text:
                assert "\x1b" not in "".join(out) and "\u202e" not in "".join(out)
