"""The track diagram: the line drawn to the terminal's width from the layout."""

from __future__ import annotations

from rich.text import Text
from textual.widgets import Static

from console.analysis.sections.state import STATE_MARK, SectionState
from console.layout import Layout
from console.safe_text import clean
from console.tui.model import Snapshot
from console.tui.sources import STALE_S
from console.tui.widgets.quiet import update_if_changed

STYLE = {"clear": "green", "occupied": "bold yellow", "disturbed": "bold white on red", "preparatory": "bold magenta"}


class TrackDiagram(Static):
    """Sections coloured *and* marked by state (· # ! ?), heads with their axle
    counts, crossings with their lights and countdown, trains with id and speed."""

    DEFAULT_CSS = """
    TrackDiagram {
        height: 7;
        padding: 0 1;
        border: round $primary;
    }
    """

    def __init__(self, layout: Layout, **kwargs: object) -> None:
        super().__init__("", **kwargs)  # type: ignore[arg-type]
        self.line_layout = layout
        self._last: tuple[Snapshot, str | None, str | None, set[str]] | None = None

    def render_snapshot(
        self, snap: Snapshot, selected_section: str | None, selected_train: str | None, differences: set[str]
    ) -> None:
        self._last = (snap, selected_section, selected_train, differences)
        width = max(20, self.size.width - 4 if self.size.width else 76)
        update_if_changed(self, draw(self.line_layout, snap, width, selected_section, selected_train, differences))

    def on_resize(self) -> None:
        # Redraw to the new width at once, not at the next tick (a paused view has none).
        if self._last is not None:
            self.render_snapshot(*self._last)


def draw(
    layout: Layout,
    snap: Snapshot,
    width: int,
    selected_section: str | None = None,
    selected_train: str | None = None,
    differences: set[str] | None = None,
) -> Text:
    """Five rows of text: platforms, sections, heads, crossings, trains."""
    lo, hi = snap.line_m
    span = max(hi - lo, 1.0)

    def col(m: float) -> int:
        return round((m - lo) / span * (width - 1))

    states = {s.id: s for s in snap.sections}
    diffs = differences or set()

    # Row 1: platforms and station names.
    plat = [" "] * width
    platforms = sorted(layout.platforms, key=lambda p: p.from_m)
    for n, p in enumerate(platforms):
        a, b = max(0, col(p.from_m)), min(width - 1, col(p.to_m))
        for i in range(a, b + 1):
            plat[i] = "▔"
        # The name may run past a short platform, up to the next one.
        room = (col(platforms[n + 1].from_m) - 1 if n + 1 < len(platforms) else width) - a
        name = clean(p.station)[: max(1, room)]
        for k, ch in enumerate(name):
            if a + k < width:
                plat[a + k] = ch
    # Row 2: sections.
    row = Text("─" * width, style="dim")
    for s in layout.sections:
        xs = [layout.head(h).chainage_m for h in s.heads]
        a, b = col(min(xs)), col(max(xs))
        sv = states.get(s.id)
        state = sv.state if sv else "clear"
        mark = STATE_MARK[SectionState(state)]
        style = STYLE[state]
        if s.id in diffs:
            style += " underline"
        if s.id == selected_section:
            style += " reverse"
        label = f"{s.id}{mark}"
        seg = mark * max(0, b - a - 1)
        mid = max(0, (len(seg) - len(label)) // 2)
        seg = seg[:mid] + label + seg[mid + len(label) :]
        row.stylize(style, a + 1, b)
        row = Text.assemble(row[: a + 1], Text(seg[: max(0, b - a - 1)], style=style), row[b:])
    # Row 3: counting heads and their counts.
    heads = [" "] * width
    for h in layout.heads:
        c = col(h.chainage_m)
        label = f"┃{clean(h.id)}:{snap.head_counts.get(h.id, 0)}"
        if c + len(label) > width:  # the last head's label turns back to stay on screen
            label = f"{clean(h.id)}:{snap.head_counts.get(h.id, 0)}┃"
            c = c - len(label) + 1
        for k, ch in enumerate(label):
            if 0 <= c + k < width:
                heads[c + k] = ch
    # Row 4: crossings.
    cross = Text(" " * width)
    for cv in snap.crossings:
        c = col(cv.chainage_m)
        if cv.warning_on:
            txt = f"╳{cv.code} ●●{'▼' if cv.barrier_down else '▲'}"
            if cv.countdown_s is not None:
                txt += f" {cv.countdown_s:.0f}s"
            style = "bold red"
        else:
            txt, style = f"╳{cv.code} ○▲", "green"
        if cv.alarm:
            txt += " ALARM"
            style = "bold white on red"
        start = max(0, min(c, width - len(txt)))
        cross = Text.assemble(cross[:start], Text(txt, style=style), cross[start + len(txt) :])
    # Row 5: trains.
    trains = Text(" " * width)
    for t in snap.trains:
        a, b = sorted((col(t.tail_m), col(t.head_m)))
        body = "=" * max(1, b - a + 1)
        arrow = "▶" if t.direction > 0 else "◀"
        label = f"{arrow}{clean(t.id)} {t.speed_kmh:.0f}"
        txt = body + label if t.direction > 0 else label + body
        start = a if t.direction > 0 else a - len(label)
        start = max(0, min(start, width - len(txt)))
        stale = t.head_age_s is None or t.head_age_s > STALE_S
        if stale:
            label += "?"  # placed from an old or inferred report
            txt = body + label if t.direction > 0 else label + body
        style = "bold red" if stale else "bold cyan"
        if t.id == selected_train:
            style += " reverse"
        if t.id in diffs:
            style += " underline"
        trains = Text.assemble(trains[:start], Text(txt, style=style), trains[start + len(txt) :])
    out = Text()
    out.append("".join(plat) + "\n", style="dim")
    out.append_text(row[:width])
    out.append("\n")
    out.append("".join(heads) + "\n", style="bold")
    out.append_text(cross[:width])
    out.append("\n")
    out.append_text(trains[:width])
    return out
