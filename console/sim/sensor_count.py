"""Each simulated head's own axle count, as an intelligent sensor keeps it (part of the device, not the console).

An intelligent sensor (seed 002's frames, ``sensor_frames.txt``) counts its
wheels itself and reports a count per axle.  The simulated device counts what
the head detects, after the faults (the records it reports), by the overlap
rule the console's counting uses (:class:`~console.analysis.counting.bank.CounterBank`),
so a head with a dead channel or missed detections counts as such a sensor
would.  The station's console never reads this: it counts the diagnostic
records itself.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from console.analysis.counting.bank import CounterBank
from console.analysis.counting.wheels import CountingSettings
from console.analysis.events.block import EventBlock
from console.analysis.events.detection import DetectionEvent, EventKind
from console.layout import Layout


class SensorCounts:
    """Feed the heads' reported wheel records a step at a time (time order); :attr:`axles` are the counted
    axles (time, head, direction) the frame writer writes."""

    def __init__(self, layout: Layout) -> None:
        names = [h.id for h in layout.heads]
        self._key = {name: k for k, name in enumerate(names)}
        self.bank = CounterBank(CountingSettings(), names=names, source="sensor")
        n = len(names)
        up = np.array([h.up_is_first_channel_first for h in layout.heads], bool)
        self.bank.configure(np.arange(n), up, np.zeros(n, bool), np.zeros(n, bool))
        self.axles: list[DetectionEvent] = []

    def feed(self, head: Sequence[str], channel: Sequence[int], time_ns: Sequence[int], value: Sequence[int]) -> None:
        if not len(head):
            return
        keys = np.fromiter((self._key[h] for h in head), np.int64, len(head))
        t = np.asarray(time_ns, np.int64)
        order = np.lexsort((t, keys))  # per head by time, ties in the order reported
        ch, v = np.asarray(channel, np.int64), np.asarray(value, np.int64)
        self._take(self.bank.feed(keys[order], ch[order], t[order], v[order]))

    def finish(self) -> None:
        """The run ends: what is still open is settled."""
        self._take(self.bank.flush())

    def _take(self, block: EventBlock) -> None:
        if len(block):
            self.axles += block.of_kinds(frozenset({EventKind.AXLE})).events()
