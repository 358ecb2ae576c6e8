"""A data table whose rows are picked with one click: the base of the sections and trains panels."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text
from textual import events
from textual.coordinate import Coordinate
from textual.message import Message
from textual.widgets import DataTable

from console.tui.widgets.quiet import same


class PickableTable(DataTable[Text]):
    """A table whose rows are picked by a single click (or enter), not a second one."""

    DEFAULT_CSS = """
    PickableTable { height: 1fr; width: 1fr; border: round $secondary; scrollbar-size-horizontal: 0; }
    """

    def on_mount(self) -> None:
        self.cursor_type = "row"
        self.zebra_stripes = True

    @dataclass
    class Picked(Message):
        table: PickableTable
        key: str

    def on_click(self, event: events.Click) -> None:
        row = event.style.meta.get("row")
        if isinstance(row, int) and 0 <= row < self.row_count:
            key = self.coordinate_to_cell_key(Coordinate(row, 0)).row_key.value
            if key is not None:
                self.post_message(self.Picked(self, key))

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        if event.row_key.value is not None:
            self.post_message(self.Picked(self, event.row_key.value))

    def show_rows(self, columns: list[str], rows: list[tuple[str, list[Text]]]) -> None:
        """Show these rows; cells are updated in place while the rows stay the same,
        so a redraw ten times a second does not re-lay out the table."""
        if [str(c.label) for c in self.columns.values()] != columns:
            self.clear(columns=True)
            self.add_columns(*columns)
        keys = [str(k.value) for k in self.rows]
        if keys == [k for k, _ in rows]:
            for r, (_, cells) in enumerate(rows):
                for c, cell in enumerate(cells):
                    if not same(self.get_cell_at(Coordinate(r, c)), cell):
                        self.update_cell_at(Coordinate(r, c), cell, update_width=True)
            return
        self.clear()
        for key, cells in rows:
            self.add_row(*cells, key=key)
