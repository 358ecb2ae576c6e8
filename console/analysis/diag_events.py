"""A diagnostic log's wheel-sensor records → the section engine's event stream.

Per counting head of the layout: two-channel heads use the overlap rule
(:func:`console.analysis.wheels.two_channel_events`), three-element heads
the majority rule (:func:`console.analysis.majority.majority_events`).  A
gap in a head's records longer than ``power_gap_s`` is a power or contact
loss: it only makes sense where the device writes records continuously
(a heartbeat), so it is off unless set.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from console.analysis.diagnostics import DiagAnalysis
from console.analysis.events import DetectionEvent, EventKind, sort_events
from console.analysis.majority import MajoritySettings, majority_events
from console.analysis.timefmt import NS
from console.analysis.wheels import CountingSettings, two_channel_events
from console.layout import Layout


@dataclass(frozen=True)
class DiagEventSettings:
    counting: CountingSettings = field(default_factory=CountingSettings)
    majority: MajoritySettings = field(default_factory=MajoritySettings)
    power_gap_s: float | None = None  # record gap that means power loss; None: off


def diag_detection_events(
    analysis: DiagAnalysis, layout: Layout, settings: DiagEventSettings | None = None
) -> tuple[list[DetectionEvent], list[str]]:
    """(events in time order, warnings about log heads the layout does not know)."""
    s = settings or DiagEventSettings()
    events: list[DetectionEvent] = []
    warnings: list[str] = []
    wr = analysis.wheel_records
    for key, (device_id, name) in enumerate(analysis.heads):
        if not layout.has_head(name):
            warnings.append(f"counting head {name} (device {device_id}) is in the log but not in the layout")
            continue
        head = layout.head(name)
        if head.device_id is not None and head.device_id != device_id:
            warnings.append(f"counting head {name}: the log's device {device_id} is not the layout's {head.device_id}")
            continue
        rows = wr[wr["head"] == key] if len(wr) else wr
        if len(rows):
            ch = rows["channel"].to_numpy(np.int64)
            t = rows["time_ns"].to_numpy(np.int64)
            v = rows["value"].to_numpy(np.int64)
            whole_second = "subsecond" in rows and not bool(rows["subsecond"].all())
            if head.channels == 3:
                on = v == 1
                events += majority_events(
                    name, ch[on], t[on], up_is_s1_to_s3=head.up_is_first_channel_first, settings=s.majority
                )
            else:
                events += two_channel_events(
                    name,
                    ch,
                    t,
                    v,
                    up_is_sys1_first=head.up_is_first_channel_first,
                    settings=s.counting,
                    whole_second=whole_second,
                )
        if s.power_gap_s is not None and len(analysis.activity):
            act = analysis.activity[analysis.activity["head"] == key].sort_values("t_first_ns")
            first, last = act["t_first_ns"].to_numpy(), act["t_last_ns"].to_numpy()
            gap = first[1:] - last[:-1]
            for i in np.flatnonzero(gap > int(s.power_gap_s * NS)).tolist():
                lost = int(last[i]) + int(s.power_gap_s * NS)
                events.append(
                    DetectionEvent(
                        lost, EventKind.POWER_LOSS, name, 0, None, "diag", f"no records for {gap[i] / NS:.0f} s"
                    )
                )
                events.append(DetectionEvent(int(first[i + 1]), EventKind.POWER_RESTORED, name, 0, None, "diag"))
    return sort_events(events), warnings
