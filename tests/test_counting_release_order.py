"""An axle's system damped second must not be freed while the first is still damped.

A wheel crossing a head one way damps Sys1 then Sys2 and frees them in the same order. A pulse on one system
that begins just before a wheel's onset on the other (interference over a passing wheel) makes the onsets say
the opposite direction; the releases then come in the reverse order, and that order is the only sign of it.
The counter raises doubt there (SINGLE_CHANNEL), so the sections the head bounds are disturbed rather than
counted the wrong way (the case tests/test_sections_property.py's search found: a section shown clear with two
axles inside).
"""

from __future__ import annotations

import numpy as np
import pytest

from console.analysis.counting.bank import two_channel_events
from console.analysis.counting.wheels import REVERSED_RELEASE, CountingSettings, HeadCounter
from console.analysis.events.detection import DetectionEvent, EventKind

MS = 1_000_000


def _head_counter(rows: list[tuple[int, int, int]]) -> list[DetectionEvent]:
    hc = HeadCounter("WS3", settings=CountingSettings())
    out: list[DetectionEvent] = []
    for ch, t, v in sorted(rows, key=lambda r: r[1]):
        out += hc.feed(ch, t, v)
    return sorted(out + hc.flush(), key=lambda e: e.time_ns)


def _both(rows: list[tuple[int, int, int]]) -> list[DetectionEvent]:
    arr = np.array(rows, np.int64)
    bank = two_channel_events("WS3", arr[:, 0], arr[:, 1], arr[:, 2], settings=CountingSettings())
    assert bank == _head_counter(rows)
    return bank


def _wheel(first: int, t_ms: int, delay_ms: int = 5, zone_ms: int = 10) -> list[tuple[int, int, int]]:
    second = 3 - first
    t = t_ms * MS
    return [
        (first, t, 1),
        (first, t + zone_ms * MS, 0),
        (second, t + delay_ms * MS, 1),
        (second, t + (delay_ms + zone_ms) * MS, 0),
    ]


def _doubts(events: list[DetectionEvent]) -> list[DetectionEvent]:
    return [e for e in events if e.kind is EventKind.SINGLE_CHANNEL and e.detail == REVERSED_RELEASE]


@pytest.mark.parametrize("first", [1, 2])
def test_a_wheel_crossing_one_way_raises_no_doubt(first: int) -> None:
    events = _both(_wheel(first, 1_000) + _wheel(first, 2_000, delay_ms=60, zone_ms=125))
    axles = [e for e in events if e.kind is EventKind.AXLE]
    assert [e.direction for e in axles] == [1 if first == 1 else -1] * 2
    assert not [e for e in events if e.kind is EventKind.SINGLE_CHANNEL]


@pytest.mark.parametrize("first", [1, 2])
def test_a_pulse_over_a_wheel_that_turns_its_direction_raises_doubt(first: int) -> None:
    # The wheel damps `first` then the other system; a pulse on the other system began 15 ms before.
    other = 3 - first
    rows = [*_wheel(first, 1_000), (other, 985 * MS, 1), (other, 1_085 * MS, 0)]
    events = _both(rows)
    axle = next(e for e in events if e.kind is EventKind.AXLE)
    assert axle.direction == (-1 if first == 1 else 1)  # the onsets' order: the pulse's system first
    (doubt,) = _doubts(events)
    # Raised as the wheel frees `first` (damped second by the onsets) while the pulse still holds the other.
    assert doubt.time_ns == 1_010 * MS and doubt.channel == first and doubt.head == "WS3"


def test_equal_onsets_raise_no_second_doubt() -> None:
    # Same stamps: the axle's direction is unknown already (it disturbs the sections by itself).
    rows = [(1, 1_000 * MS, 1), (2, 1_000 * MS, 1), (2, 1_005 * MS, 0), (1, 1_010 * MS, 0)]
    events = _both(rows)
    assert [e.direction for e in events if e.kind is EventKind.AXLE] == [0]
    assert not _doubts(events)
