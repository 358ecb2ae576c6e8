"""Sensor and channel health: findings a maintainer can act on.

Four rules, each a pure function over data the parsers already produced:

* :func:`analog_band_findings`: each channel's analog receiver value
  (``Analogwert``, Adr 134/136) against a band, given by the layout or
  learned from the log;
* :func:`voltage_margin_findings`: seed 000's rule, in-phase minus
  anti-phase receiver voltage must exceed 150 mV for reliable counting;
* :func:`disturbance_rate_findings`: how fast each channel's 1-edge counter
  (``Zähler 1-Flanken``, disturbances) grows, per hour;
* :func:`channel_fault_findings`: what the detection-event stream says about
  faulty channels and single-channel damping.

:func:`health_report` runs them all and sorts the findings critical first.
Everything here is vectorized per counting head and channel: the only Python
loops run once per head/channel (or per finding), never once per record.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING

from console.analysis.events.detection import DetectionEvent
from console.analysis.health.band import analog_band_findings
from console.analysis.health.channel_faults import channel_fault_findings
from console.analysis.health.disturbance import disturbance_rate_findings
from console.analysis.health.findings import Finding, sort_findings
from console.analysis.health.voltage import voltage_margin_findings

if TYPE_CHECKING:
    import pandas as pd


def health_report(
    records: pd.DataFrame | None,
    *,
    bands: Mapping[str, tuple[float, float]] | None = None,
    events: Iterable[DetectionEvent] = (),
    voltages: pd.DataFrame | None = None,
) -> list[Finding]:
    """All health rules over one log (and optional events and voltage table), critical first.

    ``records`` None: no record of the health registers (what an empty table gives, without making one)."""
    findings = [
        *(analog_band_findings(records, bands) if records is not None else []),
        *(disturbance_rate_findings(records) if records is not None else []),
        *channel_fault_findings(events),
    ]
    if voltages is not None:
        findings += voltage_margin_findings(voltages)
    return sort_findings(findings)
