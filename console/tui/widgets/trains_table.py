"""The trains panel: speed, where the units place the train, next stop, controller."""

from __future__ import annotations

from rich.text import Text

from console.safe_text import inert
from console.tui.model import Snapshot
from console.tui.sources import STALE_S
from console.tui.widgets.pickable_table import PickableTable
from console.tui.widgets.quiet import retitle


class TrainsTable(PickableTable):
    """Each train: speed, next stop, controller, where its head and tail are."""

    def render_snapshot(self, snap: Snapshot, selected: str | None, differences: set[str] | None = None) -> None:
        diffs = differences or set()
        truth = any(t.true_head_m is not None for t in snap.trains)
        cols = ["Train", "km/h", "Head m", *(["True head"] if truth else []), "Units", "Whole?", "Next stop", "Tail m"]
        cols.append("Ctrl")
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
                integrity_cell(t.integrity),
                inert(t.next_stop),
                Text(f"{t.tail_m:.0f}"),
                inert(t.controller),
            ]
            rows.append((t.id, row))
        self.show_rows(cols, rows)
        ids = [t.id for t in snap.trains]
        subtitle: str | Text = ""
        if selected in ids:
            if self.cursor_row != ids.index(selected):
                self.move_cursor(row=ids.index(selected), animate=False)
            t = snap.trains[ids.index(selected)]
            whole = f", {t.integrity}" if t.integrity else ""
            subtitle = inert(f"{t.id}: {unit_health(t.head_age_s, t.eot_age_s)[0]}{whole}, {t.controller}")
        retitle(self, title=f"Trains ({len(snap.trains)})", subtitle=subtitle)


def unit_health(head_age_s: float | None, eot_age_s: float | None) -> tuple[str, bool]:
    """How the train's GNSS units are heard: 'ok', or which is stale or never heard."""
    problems = []
    for name, age in (("head", head_age_s), ("EOT", eot_age_s)):
        if age is None:
            problems.append(f"{name} unheard")
        elif age > STALE_S:
            problems.append(f"{name} {age:.0f}s old")
    return (", ".join(problems), True) if problems else ("ok", False)


INTEGRITY_CELL = {"whole": ("whole", "green"), "doubtful": ("doubt", "bold yellow"), "parted": ("PARTED", "bold red")}


def integrity_cell(state: str | None) -> Text:
    """The train's integrity in a word: whole, doubt, PARTED; a dash before anything is known."""
    word, style = INTEGRITY_CELL.get(state or "", ("–", "dim"))
    return Text(word, style=style)
