"""The channel rule: faulty channels and repeated single-channel damping, from the detection events."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

from console.analysis.events.detection import DetectionEvent, EventKind, events_to_frame
from console.analysis.health.findings import Finding, Severity, where_text
from console.analysis.timefmt import iso

if TYPE_CHECKING:
    pass


SINGLE_CHANNEL_REPEATS = 3


def channel_fault_findings(
    events: Iterable[DetectionEvent], single_channel_repeats: int = SINGLE_CHANNEL_REPEATS
) -> list[Finding]:
    """Faulty channels and repeated single-channel damping, per head/channel.

    * Every (head, channel) with CHANNEL_FAULT events → CRITICAL, with the
      first time and the count; a later CHANNEL_OK is mentioned but does not
      lower the verdict (an intermittent fault is still a fault).
    * SINGLE_CHANNEL events (one system damped, the other not): one is what a
      maintenance trolley or a dropped tool does; ``single_channel_repeats``
      (3) or more on the same head and channel in one log is a pattern, the
      sign of a channel that misses wheels or sees ghosts → WARNING.  Fewer
      → INFO.
    """
    kinds = (str(EventKind.CHANNEL_FAULT), str(EventKind.CHANNEL_OK), str(EventKind.SINGLE_CHANNEL))
    # Only these kinds, picked before the table is made (few: a few per fault; none: no table, no pandas).
    picked = [e for e in events if str(e.kind) in kinds]
    if not picked:
        return []
    frame = events_to_frame(picked)
    # A whole-head event has no channel: key it as -1 so it groups like any other.
    frame = frame.assign(channel_key=frame["channel"].fillna(-1).astype("int64"))
    stats = (
        frame.groupby(["head", "channel_key", "kind"], sort=True)["time_ns"]
        .agg(first="min", last="max", n="count")
        .reset_index()
    )
    table: dict[tuple[str, int, str], tuple[int, int, int]] = {
        (str(h), int(c), str(k)): (int(a), int(b), int(n))
        for h, c, k, a, b, n in zip(
            stats["head"].tolist(),
            stats["channel_key"].tolist(),
            stats["kind"].tolist(),
            stats["first"].tolist(),
            stats["last"].tolist(),
            stats["n"].tolist(),
            strict=True,
        )
    }
    findings = []
    for (head, key, kind), (first, last, count) in table.items():
        channel = None if key < 0 else key
        times = f"{count} time{'s' if count != 1 else ''}"
        if kind == EventKind.CHANNEL_FAULT:
            ok = table.get((head, key, str(EventKind.CHANNEL_OK)))
            cleared = (
                f"; it reported OK again at {iso(ok[1])}, so the fault may be intermittent"
                if ok is not None and ok[1] > last
                else ""
            )
            where = where_text(head, channel) if channel is not None else f"{head} (whole head)"
            findings.append(
                Finding(
                    Severity.CRITICAL,
                    "faulty_channel",
                    head,
                    channel,
                    f"{where}: channel fault reported {times}, first at {iso(first)}, last at {iso(last)}"
                    f"{cleared}; the head cannot count safely: repair the channel and reset the section only "
                    "after it is confirmed clear.",
                    float(count),
                    1.0,
                    first,
                )
            )
        elif kind == EventKind.SINGLE_CHANNEL:
            where = where_text(head, channel)
            if count >= single_channel_repeats:
                severity = Severity.WARNING
                text = (
                    f"{where}: damped alone {times} (first at {iso(first)}, last at {iso(last)}); "
                    f"{single_channel_repeats} or more is a pattern, not a trolley: check this channel's sensor "
                    "and its partner for missed or ghost detections."
                )
            else:
                severity = Severity.INFO
                text = f"{where}: damped alone {times}, first at {iso(first)}: likely a trolley or a metal object."
            findings.append(
                Finding(
                    severity,
                    "single_channel",
                    head,
                    channel,
                    text,
                    float(count),
                    float(single_channel_repeats),
                    first,
                )
            )
    return findings
