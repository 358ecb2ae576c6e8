"""A report from the archive scoped to a counting head or a device (``report --archive --head H / --device D``).

Such a report is about that head (or the device's heads): its verdict and
findings are the head's health findings and the sections it bounds; its
inputs are the archived files that hold its records or sensor frames; its
sections are the ones it bounds, with the axles it counted.  Level
crossings are judged from the trains' GNSS, not from a counting head: a
scoped report leaves them out and says so.  The section engine itself still
runs over every head (a section's state needs the counts at all its
bounds); only what the report shows is cut.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from console.archive.reader import Window, parse_reports
from console.archive.store import Manifest
from console.archive.views import connect

if TYPE_CHECKING:
    import pandas as pd

    from console.sinks.report.model import ReportData


def scope_heads(data: ReportData, window: Window) -> set[str]:
    """The counting heads a head- or device-scoped window is about (a device: the heads of its records)."""
    heads: set[str] = set()
    if data.job is not None:
        heads = {
            str(h)
            for d, h in data.job.analysis.heads
            if h is not None and (window.device_id is None or int(d) == window.device_id)
        }
    if window.head is not None:
        heads = {window.head}
    return heads


def describe(window: Window, heads: set[str], bounded: list[str]) -> str:
    who = f"counting head {window.head}" if window.head is not None else f"device {window.device_id}"
    if window.head is not None and window.device_id is not None:
        who += f" of device {window.device_id}"
    elif window.device_id is not None:
        who += f" (counting heads {', '.join(sorted(heads)) or 'none in the window'})"
    return f"{who}: its inputs, findings and the sections it bounds ({', '.join(bounded) or 'none'})"


def _about_scope(warning: str, heads: set[str]) -> bool:
    """Whether a report's warning concerns the scope: one about another counting head does not, nor one about
    the trains' GNSS units (a scoped report judges no crossing)."""
    if warning.startswith("GNSS: no head or EOT device found"):
        return False
    if warning.startswith("counting head "):
        return warning[len("counting head ") :].split(":", 1)[0] in heads
    return True


def window_text(window: Window) -> str:
    """``--from``/``--to`` as the report says them ("" for the whole archive)."""
    start = "" if window.start is None else f" from {window.start.isoformat(sep=' ')}"
    end = "" if window.end is None else f" until {window.end.isoformat(sep=' ')} (excluded)"
    return start + end


def scope_report(root: Path, manifest: Manifest, data: ReportData, window: Window) -> None:
    """Cut ``data`` (the whole archive's report for the window) to the window's head or device, in place; the
    report says what it covers."""
    when = window_text(window)
    if window.head is None and window.device_id is None:
        if when:
            data.scope = f"the archive's history{when}"
        return
    heads = scope_heads(data, window)
    lay = data.layout
    bounded = [s.id for s in lay.sections if heads & set(s.heads)] if lay is not None else []
    data.scope = describe(window, heads, bounded) + when

    data.findings = [f for f in data.findings if f.counting_head in heads]
    data.warnings = [w for w in data.warnings if _about_scope(w, heads)]
    if data.sections is not None:
        data.sections = _cut_sections(data.sections, set(bounded), heads)
        if not bounded:
            scope = ", ".join(sorted(heads)) or "the scope"
            data.notes["sections"] = f"No section states: {scope} bounds no section of the layout."
    if data.frames is not None:
        data.frames = data.frames[data.frames["sensor"].astype(str).isin(heads)].reset_index(drop=True)
        data.frame_events = [e for e in data.frame_events if e.head in heads]
    data.fixes, data.crossing = None, None
    data.notes["crossings"] = (
        "No level-crossing timelines in a report on a counting head or device: crossings are judged from the "
        "trains' GNSS (report without --head/--device)."
    )
    _cut_inputs(root, manifest, data, window, heads)


def _cut_sections(sections: Any, bounded: set[str], heads: set[str]) -> Any:
    def rows(df: pd.DataFrame | None, *, by_head: bool = False) -> pd.DataFrame | None:
        if df is None or "section" not in df.columns:
            return df
        keep = df["section"].astype(str).isin(bounded)
        if by_head and "head" in df.columns:
            keep &= df["head"].astype(str).isin(heads)
        return df[keep].reset_index(drop=True)

    return replace(
        sections,
        timeline=rows(sections.timeline),
        ledger=rows(sections.ledger, by_head=True),
        resets=rows(sections.resets),
        final={sid: v for sid, v in sections.final.items() if sid in bounded},
        summary=rows(sections.summary, by_head=True),
    )


def _cut_inputs(root: Path, manifest: Manifest, data: ReportData, window: Window, heads: set[str]) -> None:
    """Only the archived files that hold the scope's records, frames or voltages; their parse reports alone."""
    seqs: set[int] = set()
    if manifest.parts("records") and heads:
        con, _ = connect(root, manifest, tables=("records",))
        try:
            marks = ", ".join("?" for _ in heads)
            where, params = replace(window, head=None).where()
            cond = f"counting_head IN ({marks})"
            where = f"{where} AND {cond}" if where else f" WHERE {cond}"
            rows = con.execute(f"SELECT DISTINCT file_seq FROM records{where}", [*params, *sorted(heads)]).fetchall()
        finally:
            con.close()
        seqs |= {int(r[0]) for r in rows}
    by_path = {str(e["path"]): int(e["file_seq"]) for e in manifest.files if e.get("active", True)}
    if data.frames is not None:
        seqs |= {by_path[f] for f in set(data.frames["file"].astype(str)) if f in by_path}
    for rel in manifest.parts("voltages"):
        import pyarrow.parquet as pq

        t = pq.read_table(root / rel, columns=["sensor", "file_seq"])
        if heads & {str(s) for s in t.column("sensor").to_pylist()}:
            seqs |= {int(s) for s in t.column("file_seq").to_pylist()}
    if not seqs:
        from console.inputs.recognise import ReportInputError
        from console.safe_text import clean

        what = f"--head {clean(window.head)}" if window.head is not None else f"--device {window.device_id}"
        # A report about nothing would say OK: say instead that nothing is known of it.
        raise ReportInputError(f"{what}: no record, frame or voltage of it in the archive (in the window asked)")
    others = sum(1 for i in data.inputs if by_path.get(i.path) not in seqs)
    data.inputs = [i for i in data.inputs if by_path.get(i.path) in seqs]
    if others:
        scope = ", ".join(sorted(heads)) or "the scope"
        data.warnings.append(f"{others} other archived files hold nothing of {scope}: not listed")
    wanted = set(data.reports)
    data.reports = {k: v for k, v in parse_reports(root, manifest, only=seqs).items() if k in wanted and v.files}
