"""Seed 000's edge rule on the two logic signals of one sensor.

The receiver gives two signals: **A** ("clear": receiver in phase with the
transmitter at full amplitude) and **B** ("occupied": anti-phase at full
amplitude).  A wheel fully over the sensor raises B; as it leaves, A comes
back.  An axle is confirmed by a rising edge of B followed by a rising edge
of A.  A metal object that is not a wheel lowers A without ever raising B
(the "uncertain" state) and is not an axle.

A counting head is a pair of such sensors a known distance apart; the order
of their confirmations gives the direction, their delay the speed.  The
pairing itself is the two-channel rule of :mod:`console.analysis.counting.wheels`.
"""

from __future__ import annotations

import numpy as np

from console.analysis.counting.bank import two_channel_events
from console.analysis.counting.wheels import CountingSettings
from console.analysis.events.detection import DetectionEvent, EventKind

SIGNAL_A, SIGNAL_B = 0, 1


def confirmed_axles(signal: np.ndarray, level: np.ndarray, time_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(confirmation times, uncertain times) for one sensor's A/B edges.

    A confirmation is the first rising A after a rising B.  An A that falls
    and rises again with no rising B in between is an uncertain episode,
    reported at its falling edge.
    """
    order = np.argsort(time_ns, kind="stable")
    sig, lev, t = signal[order].tolist(), level[order].tolist(), time_ns[order].tolist()
    confirmed, uncertain = [], []
    b_seen = False
    a_fell_at: int | None = None
    state = {SIGNAL_A: 1, SIGNAL_B: 0}  # at rest: clear
    for s, lv, ti in zip(sig, lev, t, strict=True):  # per edge of one sensor
        rising = lv == 1 and state[s] == 0
        falling = lv == 0 and state[s] == 1
        state[s] = lv
        if s == SIGNAL_A and falling:
            a_fell_at = ti
        elif s == SIGNAL_B and rising:
            b_seen = True
        elif s == SIGNAL_A and rising:
            if b_seen:
                confirmed.append(ti)
            elif a_fell_at is not None:
                uncertain.append(a_fell_at)
            b_seen, a_fell_at = False, None
    return np.asarray(confirmed, np.int64), np.asarray(uncertain, np.int64)


def edge_rule_events(
    head: str,
    sensor: np.ndarray,
    signal: np.ndarray,
    level: np.ndarray,
    time_ns: np.ndarray,
    *,
    up_is_sensor1_first: bool = True,
    settings: CountingSettings | None = None,
    source: str = "edges",
) -> list[DetectionEvent]:
    """Detection events for a head of two A/B sensors (sensor 1 and 2)."""
    chans, times = [], []
    uncertain_events = []
    for k in (1, 2):
        m = sensor == k
        ok, unsure = confirmed_axles(signal[m], level[m], time_ns[m])
        chans.append(np.full(len(ok), k))
        times.append(ok)
        uncertain_events += [
            DetectionEvent(int(u), EventKind.SINGLE_CHANNEL, head, 0, k, source, "A dropped without B: not a wheel?")
            for u in unsure
        ]
    channel = np.concatenate(chans).astype(np.int64)
    t_all = np.concatenate(times).astype(np.int64)
    events = two_channel_events(
        head,
        channel,
        t_all,
        np.ones(len(t_all), np.int64),
        up_is_sys1_first=up_is_sensor1_first,
        settings=settings,
        source=source,
    )
    return events + uncertain_events
