"""The sections and trains panels."""

from __future__ import annotations

from dataclasses import dataclass

from rich.text import Text
from textual import events
from textual.coordinate import Coordinate
from textual.message import Message
from textual.widgets import DataTable

from console.analysis.sections import STATE_MARK, SectionState
from console.safe_text import inert
from console.tui.model import Snapshot
from console.tui.sources import STALE_S
from console.tui.widgets.track import STYLE


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
                    if self.get_cell_at(Coordinate(r, c)) != cell:
                        self.update_cell_at(Coordinate(r, c), cell, update_width=True)
            return
        self.clear()
        for key, cells in rows:
            self.add_row(*cells, key=key)


class SectionsTable(PickableTable):
    """State (with its mark), counts in and out, why; with the truth view, the true count."""

    def render_snapshot(self, snap: Snapshot, selected: str | None, differences: set[str]) -> None:
        truth = any(s.true_count is not None for s in snap.sections)
        cols = ["Section", "State", "Cnt", "In", "Out", *(["Truth"] if truth else []), "Why"]
        rows = []
        for s in snap.sections:
            st = SectionState(s.state)
            state = Text(f"{STATE_MARK[st]} {s.state}", style=STYLE[s.state])
            sid = inert(s.id, style="underline" if s.id in differences else "")
            row = [sid, state, Text(str(s.count)), Text(str(s.count_in)), Text(str(s.count_out))]
            if truth:
                row.append(Text(str(s.true_count), style="bold red" if s.id in differences else "dim"))
            row.append(inert(s.reason, style="dim"))
            rows.append((s.id, row))
        self.show_rows(cols, rows)
        self.border_title = "Sections"
        chosen = next((s for s in snap.sections if s.id == selected), None)
        if chosen is not None:
            if self.cursor_row != snap.sections.index(chosen):
                self.move_cursor(row=snap.sections.index(chosen), animate=False)
            # The reason in full, where a narrow panel would cut the Why column.
            self.border_subtitle = inert(f"{chosen.id}: {chosen.reason}")


class TrainsTable(PickableTable):
    """Each train: speed, next stop, controller, where its head and tail are."""

    def render_snapshot(self, snap: Snapshot, selected: str | None, differences: set[str] | None = None) -> None:
        diffs = differences or set()
        truth = any(t.true_head_m is not None for t in snap.trains)
        cols = ["Train", "km/h", "Head m", *(["True head"] if truth else []), "Units", "Next stop", "Tail m", "Ctrl"]
        rows = []
        for t in snap.trains:
            units, bad = unit_health(t.head_age_s, t.eot_age_s)
            row = [
                inert(t.id, style="bold cyan underline" if t.id in diffs else "bold cyan"),
                Text(f"{t.speed_kmh:.0f}"),
                Text(f"{t.head_m:.0f}"),
            ]
            if truth:
                row.append(Text(f"{t.true_head_m:.0f}", style="bold red" if t.id in diffs else "dim"))
            row += [
                Text(units, style="bold red" if bad else "green"),
                inert(t.next_stop),
                Text(f"{t.tail_m:.0f}"),
                inert(t.controller),
            ]
            rows.append((t.id, row))
        self.show_rows(cols, rows)
        self.border_title = f"Trains ({len(snap.trains)})"
        ids = [t.id for t in snap.trains]
        self.border_subtitle = ""
        if selected in ids:
            if self.cursor_row != ids.index(selected):
                self.move_cursor(row=ids.index(selected), animate=False)
            t = snap.trains[ids.index(selected)]
            self.border_subtitle = inert(f"{t.id}: {unit_health(t.head_age_s, t.eot_age_s)[0]}, {t.controller}")


def unit_health(head_age_s: float | None, eot_age_s: float | None) -> tuple[str, bool]:
    """How the train's GNSS units are heard: 'ok', or which is stale or never heard."""
    problems = []
    for name, age in (("head", head_age_s), ("EOT", eot_age_s)):
        if age is None:
            problems.append(f"{name} unheard")
        elif age > STALE_S:
            problems.append(f"{name} {age:.0f}s old")
    return (", ".join(problems), True) if problems else ("ok", False)
