"""What the archive's pipeline computes, and the fingerprint the manifest keeps of it.

A derivation whose fingerprint differs from the manifest's (another layout, another version of trackside)
does not resume: its tables are made again from the archived records (:mod:`console.archive.derive`).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

from console.analysis.diag_events import DiagEventSettings
from console.analysis.passages.speed_settings import SpeedSettings
from console.archive.derive_sink import DERIVE_VERSION
from console.archive.reader import speed_settings
from console.archive.store import Manifest
from console.engine.pipeline import PipelineSettings

if TYPE_CHECKING:
    from console.layout import Layout


def derive_settings(manifest: Manifest, layout: Layout | None) -> PipelineSettings:
    """What the archive's pipeline computes: passages and axles; events and sections on the layout."""

    speed: SpeedSettings = speed_settings(manifest, layout)
    return PipelineSettings(
        speed=speed,
        events=DiagEventSettings(),
        layout=layout,
        sections=layout if layout is not None and layout.sections else None,
        axles=True,
    )


def fingerprint(settings: PipelineSettings, layout_spec: str | None) -> dict[str, Any]:
    """What the derived rows were made with, as the manifest keeps it (JSON): another one, and the next
    ingest makes them again from the records."""
    speed = dataclasses.asdict(settings.speed)
    # Heads' own spacings only where a layout gives some: an archive made before they existed (one spacing
    # for every head) keeps its fingerprint, and resumes.
    own = speed.pop("head_spacing_m")
    if own:
        speed["head_spacing_m"] = [[head, m] for head, m in own]
    return {"version": DERIVE_VERSION, "settings": speed, "layout": layout_spec}


def fingerprint_of(settings: PipelineSettings, derived: dict[str, Any]) -> dict[str, Any]:
    return fingerprint(settings, derived.get("layout"))
