"""The sections panel: state (with its mark), counts in and out, why."""

from __future__ import annotations

from rich.text import Text

from console.analysis.sections.state import STATE_MARK, SectionState
from console.safe_text import inert
from console.tui.model import Snapshot
from console.tui.widgets.pickable_table import PickableTable
from console.tui.widgets.quiet import retitle
from console.tui.widgets.track import STYLE


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
        retitle(self, title="Sections")
        chosen = next((s for s in snap.sections if s.id == selected), None)
        if chosen is not None:
            if self.cursor_row != snap.sections.index(chosen):
                self.move_cursor(row=snap.sections.index(chosen), animate=False)
            # The reason in full, where a narrow panel would cut the Why column.
            retitle(self, subtitle=inert(f"{chosen.id}: {chosen.reason}"))
