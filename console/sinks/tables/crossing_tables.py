"""Rich views for `trackside crossing`: violations first, then the timelines."""

from __future__ import annotations

from rich import box
from rich.console import Group, RenderableType
from rich.padding import Padding
from rich.table import Table
from rich.text import Text

from console.analysis.crossing.timeline import TimelineRow
from console.analysis.crossing.values import CrossingEvent
from console.analysis.timefmt import display, time_of_day
from console.safe_text import inert
from parsers.units import NS_PER_DAY


def _t(ns: int | None, day0: int = 0) -> Text:
    """A time of day; ``+N`` when it falls N days after the table's first day (a log over midnight)."""
    if ns is None:
        return Text("–", style="dim")
    return Text(time_of_day(ns, day0))


def _s(x: float | None, warn_below: float | None = None) -> Text:
    if x is None:
        return Text("–", style="dim")
    style = "bold red" if warn_below is not None and x < warn_below else ""
    return Text(f"{x:.0f}", style=style)


def violations_view(rows: list[TimelineRow]) -> Group | None:
    # Late warnings first (each row lists its late warning first), then the other violations.
    bad = sorted((r for r in rows if r.violations), key=lambda r: r.late_by_s is None)
    if not bad:
        return None
    parts: list[RenderableType] = [Text(f"SAFETY VIOLATIONS ({len(bad)})", style="bold white on red")]
    for r in bad:
        for v in r.violations:
            head = Text("!! ", style="bold red")
            head.append_text(inert(f"{r.crossing}  train {r.train}: {v}"))
            parts.append(head)
            when = (
                f"on {display(r.t_on_ns)}, head {display(r.t_head_arrival_ns)}, "
                f"tail clear {display(r.t_tail_clear_ns)}, off {display(r.t_off_ns)}"
            )
            parts.append(Padding(Text(when), (0, 0, 0, 4)))
            if v.startswith("late") and r.late_cause:
                parts.append(Padding(inert(f"cause: {r.late_cause}"), (0, 0, 0, 4)))
    return Group(*parts)


def timeline_table(rows: list[TimelineRow]) -> Table:
    # Times of day, of the first day: one of a later day is marked +N (they were all read as the first's).
    times = [x for r in rows for x in (r.t_on_ns, r.t_head_arrival_ns, r.t_tail_clear_ns, r.t_off_ns) if x]
    day0 = min(times) // NS_PER_DAY if times else 0
    day = f" {display(min(times))[:10]}" if times else ""
    later = " (+N: N days later)" if any(x // NS_PER_DAY != day0 for x in times) else ""
    t = Table(
        title=f"Level crossings (LC){day}: times of day{later}; lead, excess (Exc) and baseline in s",
        title_justify="left",
        box=box.SIMPLE_HEAD,
        pad_edge=False,
        title_style="bold",
        padding=(0, 0),  # nine columns of times must fit 80 columns
    )
    for c in ("LC", "Train", "On", "Head", "Tail", "Off", "Lead", "Exc", "Baseline"):
        t.add_column(
            c,
            justify="right" if c in ("Lead", "Exc", "Baseline") else "left",
            no_wrap=True,
            min_width=8 if c in ("On", "Head", "Tail", "Off") else None,
        )
    for r in rows:
        if r.baseline_early_s:
            base = Text(f"{r.baseline_early_s:.0f} early", style="bold yellow")
        elif r.baseline_excess_s is not None:
            base = Text(f"+{r.baseline_excess_s:.0f}")
        else:
            base = Text("–", style="dim")
        off = _t(r.t_off_ns, day0) if r.t_off_ns is not None else Text("held on", style="bold yellow")
        t.add_row(
            inert(r.crossing),
            inert(r.train),
            _t(r.t_on_ns, day0),
            _t(r.t_head_arrival_ns, day0),
            _t(r.t_tail_clear_ns, day0),
            off,
            _s(r.lead_s, warn_below=r.warning_time_s),
            _s(r.excess_s),
            base,
        )
    t.caption = (
        "Baseline: a fixed-time switch-off at head arrival + length / speed + 10 s; "
        "'early' = it would have opened the road with the train on it."
    )
    return t


def reasons_view(rows: list[TimelineRow], events: list[CrossingEvent]) -> Group:
    parts: list[RenderableType] = [Text("Why", style="bold")]
    for r in rows:
        parts.append(inert(f"{r.crossing} train {r.train}: on: {r.reason_on or '–'}; off: {r.reason_off}"))
    alarms = [e for e in events if e.kind == "alarm"]
    for e in alarms:
        line = Text("! ", style="yellow")
        line.append_text(inert(f"{display(e.t_ns)} {e.crossing} train {e.train}: {e.reason}"))
        parts.append(line)
    return Group(*parts)


def spare_text(r: TimelineRow) -> str | None:
    """One warning's lead against the time required, and its spare split into physics and doubt."""
    if r.lead_s is None or r.spare is None:
        return None
    sp = r.spare
    text = f"lead {r.lead_s:.0f} s, {r.warning_time_s:g} s required"
    if sp.spare_s >= 0:
        causes = ", ".join(f"{k} {v:.0f} s" for k, v in sorted(sp.doubt_s.items(), key=lambda kv: -kv[1]) if v >= 0.5)
        # Whole seconds that add up as shown (170.4 + 11.4 = 181.8 reads 182 = 170 + 12, not + 11).
        spare, physics = round(sp.spare_s), round(sp.physics_s)
        text += f": spare {spare} s = physics {physics} s + doubt {spare - physics} s"
        text += f" ({causes})" if causes else ""
    if r.released:
        text += f"; released {r.released}× before it arrived (proven out of reach)"
    return text


def spare_view(rows: list[TimelineRow]) -> Group | None:
    """Per warning: the lead, the time required, and how much of the spare came from doubt."""
    lines = [(r, t) for r in rows if (t := spare_text(r)) is not None]
    if not lines:
        return None
    parts: list[RenderableType] = [
        Text("Spare warning: physics (the bounds, knowing the motion) and doubt", style="bold")
    ]
    for r, t in lines:
        parts.append(inert(f"{r.crossing} train {r.train}: {t}"))
    return Group(*parts)
