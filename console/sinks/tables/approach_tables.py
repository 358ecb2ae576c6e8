"""Rich table for `trackside approach`: both alarm methods side by side."""

from __future__ import annotations

from rich import box
from rich.table import Table
from rich.text import Text

from console.analysis.crossing.approach import ApproachRow
from console.analysis.timefmt import display, time_of_day
from console.safe_text import inert
from parsers.units import NS_PER_DAY


def _s(x: float | None) -> Text:
    return Text("–", style="dim") if x is None else Text(f"{x:.0f}")


def approach_table(rows: list[ApproachRow]) -> Table:
    t = Table(
        title="Work-site approach warnings: alarm from detection vs from the measured speed (lead and saved in s)",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        title_style="bold",
    )
    for c in ("Site", "Detected", "km/h", "Arrives", "Lead fixed", "Lead speed", "Saved", "Note"):
        t.add_column(
            c,
            justify="right" if c in ("km/h", "Lead fixed", "Lead speed", "Saved") else "left",
            no_wrap=c not in ("Note", "Site"),
        )
    for r in rows:
        t.add_row(
            inert(r.site),
            Text(display(r.t_detect_ns)),
            Text("–" if r.speed_kmh is None else f"{r.speed_kmh:.1f}"),
            # The time of day, on the detection's date (shown beside it); +1 past midnight.
            Text("–" if r.t_arrival_ns is None else time_of_day(r.t_arrival_ns, r.t_detect_ns // NS_PER_DAY)),
            _s(r.lead_fixed_s),
            _s(r.lead_speed_s),
            _s(r.saved_s),
            inert(r.note, style="yellow" if r.note else ""),
        )
    return t
