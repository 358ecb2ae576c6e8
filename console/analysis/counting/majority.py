"""Seed 002's intelligent sensor: three elements S1, S2, S3 and the majority rule.

Each wheel interrupts S1, S2, S3 in turn (15 cm apart: 3 ms at 200 km/h, about
1 s at 1 km/h).  Pulses are grouped per wheel: a group ends when an element
fires again or the wheel window has passed.  Then, as in the paper:

* the axle counts when at least two of the three elements saw it (the
  majority); ERR (here COUNT_ERROR) when the vote was not unanimous;
* the working units CINT (wheels since the last clearing), MARKS1..3 (the
  element answered) and C1..C3 (its count) identify a faulty element: once
  CINT ≥ 3, an element whose mark is still 0 is faulty, and its counter must
  be 0 too;
* direction: S1 before S3 is S1→S3 ("up" unless the layout says otherwise);
* soft timing: a lone pulse with nothing else at the sensor within the
  isolation time is an "accidental" event (lightning, tampering): the
  section is held occupied first (INTERFERENCE) and released when the quiet
  time confirms it (ACCIDENTAL).  A lone pulse among other activity is
  doubt (SINGLE_CHANNEL).

The working units clear after ``clear_after_s`` of quiet, standing in for the
paper's "reset during section clearing".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from console.analysis.counting.wheels import CountingSettings, soft_timing
from console.analysis.events.detection import DetectionEvent, EventKind
from parsers.units import NS


@dataclass(frozen=True)
class MajoritySettings:
    element_spacing_m: float = 0.15
    # The slowest wheel the sensor counts: 1 km/h (seed 002).
    min_speed_mps: float = 1 / 3.6
    isolation_s: float = 60.0  # see console.analysis.counting.wheels.CountingSettings
    clear_after_s: float = 90.0

    @property
    def wheel_window_ns(self) -> int:
        """Time for one wheel to cross S1..S3 at the slowest speed."""
        return int(2 * self.element_spacing_m / self.min_speed_mps * NS)


def majority_events(
    head: str,
    element: np.ndarray,
    time_ns: np.ndarray,
    *,
    up_is_s1_to_s3: bool = True,
    settings: MajoritySettings | None = None,
    source: str = "diag",
) -> list[DetectionEvent]:
    """Axle and fault events from one three-element sensor's pulses (element 1..3)."""
    s = settings or MajoritySettings()
    order = np.argsort(time_ns, kind="stable")
    el, t = element[order].astype(int).tolist(), time_ns[order].astype(np.int64).tolist()
    timing = CountingSettings(isolation_s=s.isolation_s)
    all_t = np.asarray(t, dtype=np.int64)

    events: list[DetectionEvent] = []
    cint, marks, counts = 0, [0, 0, 0], [0, 0, 0]
    faulty: set[int] = set()
    last_t: int | None = None
    group: dict[int, int] = {}  # element → first pulse time in this wheel

    def close(g: dict[int, int]) -> None:
        nonlocal cint
        if not g:
            return
        if len(g) == 1:
            ((e1, t0),) = g.items()
            events.extend(soft_timing(head, [(t0, e1)], all_t, timing, source))
            return
        cint += 1
        for e in g:
            marks[e - 1] = 1
            counts[e - 1] += 1
            if e in faulty:
                faulty.discard(e)
                events.append(DetectionEvent(g[e], EventKind.CHANNEL_OK, head, 0, e, source, f"S{e} answers again"))
        # Direction from the outermost elements that fired.
        first, last = min(g), max(g)
        order_sign = 0 if g[first] == g[last] else (1 if g[first] < g[last] else -1)
        direction = order_sign if up_is_s1_to_s3 else -order_sign
        t_axle = max(g.values())
        events.append(DetectionEvent(t_axle, EventKind.AXLE, head, direction, None, source, f"S{sorted(g)}"))
        if len(g) == 2:
            missing = ({1, 2, 3} - set(g)).pop()
            events.append(
                DetectionEvent(
                    t_axle, EventKind.COUNT_ERROR, head, 0, missing, source, f"majority 2 of 3: S{missing} silent"
                )
            )
        if cint >= 3:
            for e in (1, 2, 3):
                if marks[e - 1] == 0 and counts[e - 1] == 0 and e not in faulty:
                    faulty.add(e)
                    events.append(
                        DetectionEvent(
                            t_axle, EventKind.CHANNEL_FAULT, head, 0, e, source, f"S{e}: MARKS=0 after CINT={cint}"
                        )
                    )

    for e, ti in zip(el, t, strict=True):  # per pulse of one sensor: the paper's interrupt handler
        if last_t is not None and ti - last_t > int(s.clear_after_s * NS):
            close(group)
            group = {}
            cint, marks, counts = 0, [0, 0, 0], [0, 0, 0]
        if group and (e in group or ti - min(group.values()) > s.wheel_window_ns):
            close(group)
            group = {}
        group.setdefault(e, ti)
        last_t = ti
    close(group)
    return events
