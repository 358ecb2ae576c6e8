"""The integrity timeline per train as a Rich table (crossing, report's terminal face)."""

from __future__ import annotations

import datetime as dt
from typing import Any

from rich import box
from rich.table import Table
from rich.text import Text

from console.safe_text import inert

STATE_STYLE = {"whole": "green", "doubtful": "bold yellow", "parted": "bold white on red"}


def integrity_table(timelines: list[dict[str, Any]]) -> Table:
    """One row per change of a train's integrity state: when, to what, on whose evidence."""
    # Times of day of the first day, a later day's marked +N (as the crossing timelines): they had no date.
    days = sorted({dt.date.fromisoformat(ch["time"][:10]) for tl in timelines for ch in tl["changes"] if ch["time"]})

    def when(iso: str | None) -> str:
        if not iso:
            return ""
        later = (dt.date.fromisoformat(iso[:10]) - days[0]).days
        return iso[11:19] + (f"+{later}" if later else "")

    on = f" ({days[0].isoformat()}{', +N: N days later' if len(days) > 1 else ''})" if days else ""
    t = Table(
        title=f"Train integrity{on}: every change, with its evidence",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        title_style="bold",
    )
    for c in ("Train", "Time", "State", "Witness", "Evidence"):
        t.add_column(c, overflow="fold")
    for tl in timelines:
        for ch in tl["changes"]:
            t.add_row(
                inert(tl["train"], style="bold cyan"),
                Text(when(ch["time"])),
                Text(ch["state"], style=STATE_STYLE.get(ch["state"], "")),
                Text(", ".join(ch["witnesses"])),
                inert("; ".join(ch["evidence"])),
            )
    return t
