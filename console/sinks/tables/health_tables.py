"""Rich tables for `trackside health` (and the health summary of `analyze`)."""

from __future__ import annotations

from collections import Counter

from rich.console import Group, RenderableType
from rich.padding import Padding
from rich.text import Text

from console.analysis.health.findings import Finding, Severity, channel_name
from console.analysis.timefmt import display
from console.plural import count
from console.safe_text import inert

# A mark each, so severities read without colour.
SEVERITY_MARK = {
    Severity.CRITICAL: ("!!", "bold red"),
    Severity.WARNING: ("! ", "yellow"),
    Severity.INFO: ("· ", "dim"),
}


def severity_text(sev: Severity) -> Text:
    mark, style = SEVERITY_MARK[sev]
    return Text(f"{mark} {sev.value}", style=style)


def findings_view(findings: list[Finding], *, show_info: bool = True, title: str = "Health findings") -> Group:
    """Each finding as a header line and its message, indented: reads at 80 columns."""
    counts = Counter(f.severity for f in findings)
    summary = ", ".join(f"{counts[s]} {s.value}" for s in (Severity.CRITICAL, Severity.WARNING, Severity.INFO))
    parts: list[RenderableType] = [Text(f"{title}: {summary}", style="bold")]
    hidden = 0
    for f in findings:
        if f.severity is Severity.INFO and not show_info:
            hidden += 1
            continue
        head = severity_text(f.severity)
        where = f.counting_head or "–"
        if f.channel is not None:
            where += f" {channel_name(f.channel)}"
        head.append("  ")
        head.append_text(inert(where, style="bold"))
        head.append(f"  {f.rule}", style="cyan")
        if f.time_ns is not None:
            head.append(f"  since {display(f.time_ns)}", style="dim")
        parts.append(head)
        parts.append(Padding(inert(f.message), (0, 0, 0, 4)))
    if hidden:
        parts.append(Text(f"{count(hidden, 'info finding')} not shown (trackside health lists them)", style="dim"))
    return Group(*parts)
