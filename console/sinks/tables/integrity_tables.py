"""The integrity timeline per train as a Rich table (crossing, report's terminal face)."""

from __future__ import annotations

from typing import Any

from rich import box
from rich.table import Table
from rich.text import Text

from console.safe_text import inert

STATE_STYLE = {"whole": "green", "doubtful": "bold yellow", "parted": "bold white on red"}


def integrity_table(timelines: list[dict[str, Any]]) -> Table:
    """One row per change of a train's integrity state: when, to what, on whose evidence."""
    t = Table(
        title="Train integrity: every change, with its evidence",
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
                Text((ch["time"] or "")[11:19]),
                Text(ch["state"], style=STATE_STYLE.get(ch["state"], "")),
                Text(", ".join(ch["witnesses"])),
                inert("; ".join(ch["evidence"])),
            )
    return t
