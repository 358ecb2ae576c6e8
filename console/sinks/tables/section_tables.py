"""Rich tables for `trackside sections`: final states, timeline, ledger, resets."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rich import box
from rich.table import Table
from rich.text import Text

from console import plural
from console.analysis.sections.engine import SectionsResult
from console.analysis.sections.state import STATE_MARK, SectionState
from console.analysis.timefmt import display, iso
from console.safe_text import inert

if TYPE_CHECKING:
    import pandas as pd

STATE_STYLE = {
    SectionState.CLEAR: "green",
    SectionState.OCCUPIED: "yellow",
    SectionState.DISTURBED: "bold red",
    SectionState.PREPARATORY: "magenta",
}


def _table(title: str) -> Table:
    return Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False, title_style="bold")


def state_text(state: str) -> Text:
    """A state with its mark, so it reads without colour: '! disturbed'."""
    st = SectionState(state)
    return Text(f"{STATE_MARK[st]} {st.value}", style=STATE_STYLE[st])


def _t(ns: Any) -> str:
    return display(int(ns))


def final_states_table(result: SectionsResult) -> Table:
    return final_states_view(result.final)


def final_states_view(final: dict[str, tuple[str, int, int, int, str]]) -> Table:
    """Each section's state at the end: section → (state, count, in, out, reason)."""
    t = _table("Sections now (· clear  # occupied  ! disturbed  ? preparatory)")
    for c in ("Section", "State", "Count", "In", "Out", "Why"):
        t.add_column(c, justify="right" if c in ("Count", "In", "Out") else "left")
    for sid, (state, count, n_in, n_out, reason) in final.items():
        t.add_row(inert(sid), state_text(state), Text(str(count)), Text(str(n_in)), Text(str(n_out)), inert(reason))
    if any(count != n_in - n_out for _, count, n_in, n_out, _ in final.values()):
        # A reset or a sweep restarts the count; In and Out keep every axle since the log began.
        t.caption = "In, Out: axles since the log began; Count: since the last sweep or reset"
    return t


def timeline_table(result: SectionsResult, limit: int = 200) -> Table:
    tl = result.timeline
    t = _table(f"State timeline ({plural.count(len(tl), 'change')})")
    for c in ("Time", "Section", "State", "Count", "Why"):
        t.add_column(c, no_wrap=c == "Time")
    r: Any
    for r in tl.head(limit).itertuples(index=False):
        t.add_row(Text(_t(r.time_ns)), inert(r.section), state_text(r.state), Text(str(r.count)), inert(r.reason))
    if len(tl) > limit:
        t.caption = f"first {limit} of {len(tl)}; --json has all"
    return t


def ledger_summary_table(result: SectionsResult) -> Table:
    """Counts in and out per section and head (the full ledger is in --json)."""
    t = _table("Count ledger (axles in / out per head)")
    for c in ("Section", "Head", "In", "Out", "First", "Last"):
        t.add_column(c, justify="right" if c in ("In", "Out") else "left", no_wrap=c in ("First", "Last"))
    r: Any
    for r in result.ledger_summary().itertuples(index=False):
        t.add_row(
            inert(r.section),
            inert(r.head),
            Text(str(r.count_in)),
            Text(str(r.count_out)),
            Text(_t(r.first_ns)),
            Text(_t(r.last_ns)),
        )
    return t


def resets_table(result: SectionsResult) -> Table | None:
    if result.resets.empty:
        return None
    t = _table("Reset requests")
    for c in ("Time", "Section", "Result", "Why"):
        t.add_column(c)
    r: Any
    for r in result.resets.itertuples(index=False):
        verdict = Text("accepted", style="green") if r.accepted else Text("refused", style="bold red")
        t.add_row(Text(_t(r.time_ns)), inert(r.section), verdict, inert(r.reason))
    return t


def sections_json(result: SectionsResult) -> dict[str, Any]:
    """The JSON form (schema trackside.sections/1)."""

    def rows(frame: pd.DataFrame) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        for raw in frame.to_dict("records"):
            rec: dict[str, Any] = {str(k): v for k, v in raw.items()}
            rec["time"] = iso(int(rec.pop("time_ns")))
            out.append({k: (v.item() if hasattr(v, "item") else v) for k, v in rec.items()})
        return out

    return {
        **sections_summary(result.final),
        "timeline": rows(result.timeline),
        "ledger": rows(result.ledger),
        "resets": rows(result.resets),
    }


def sections_summary(final: dict[str, tuple[str, int, int, int, str]]) -> dict[str, Any]:
    """``{"sections": [...]}``: each section's state at the end, as every JSON document gives it."""
    return {
        "sections": [
            {"section": sid, "state": st, "count": c, "count_in": i, "count_out": o, "reason": why}
            for sid, (st, c, i, o, why) in final.items()
        ]
    }
