"""The pipeline's results as event objects: the lines of ``--jsonl`` and what the live views show.

One function per kind of result (the crossing stage, in the engine, makes its own:
:mod:`console.engine.crossings`), so ``follow --jsonl``, ``analyze --jsonl``,
the station's event log and the metrics read the same fields.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from console.analysis.timefmt import iso

if TYPE_CHECKING:
    from console.analysis.health.findings import Finding
    from console.analysis.sections.state import ResetRecord, Transition


def section_event(tr: Transition) -> dict[str, Any]:
    """A section's state change."""
    return {
        "type": "section",
        "section": tr.section,
        "state": str(tr.state),
        "count": tr.count,
        "reason": tr.reason,
        "time_ns": tr.time_ns,
        "time": iso(tr.time_ns),
    }


def reset_event(r: ResetRecord) -> dict[str, Any]:
    """An operator's reset request, accepted or refused, with the reason."""
    return {
        "type": "reset",
        "section": r.section,
        "accepted": r.accepted,
        "reason": r.reason,
        "time_ns": r.time_ns,
        "time": iso(r.time_ns),
    }


def health_event(f: Finding) -> dict[str, Any]:
    """A health finding."""
    return {"type": "health", **f.to_dict()}
