"""The brake pipe's witness of train integrity (console.analysis.integrity.brake_pipe): its rules.

The rear pipe vented while the front stayed charged is a parting; a front
that vented too (an emergency of the whole train), or whose status is not
known, is doubt; no pressure reported, nothing said.
"""

from __future__ import annotations

import math

from console.analysis.integrity.brake_pipe import BRAKE_PIPE, BrakePipeWitness
from console.analysis.integrity.monitor import IntegrityMonitor
from console.analysis.integrity.values import DOUBTFUL, EOT, HEAD, PARTED, ConsistSpec, IntegrityEvent
from parsers.units import NS

T0 = 1_772_438_400 * NS
LENGTH_M = 576.0  # a 40-wagon freight train


def monitor() -> IntegrityMonitor:
    mon = IntegrityMonitor()
    mon.add_train(ConsistSpec("T1", LENGTH_M, 166))
    return mon


def at(s: float) -> int:
    return T0 + int(s * NS)


def feed(mon: IntegrityMonitor, readings: list[tuple[float, str, float]], latency_s: float = 0.5) -> list:
    """(measured at s, role, bar) in the order the console receives them."""
    out: list[IntegrityEvent] = []
    for t, role, bar in sorted(readings, key=lambda r: r[0] + latency_s):
        out += mon.brake_pipe(at(t + latency_s), at(t), "T1", role, bar)
    return out


def charged_until(t_end: float, period_s: float = 1.0) -> list[tuple[float, str, float]]:
    out = []
    t = 0.0
    while t < t_end:
        out += [(t, HEAD, 5.0), (t + 0.3, EOT, 4.95)]
        t += period_s
    return out


def test_the_rear_vented_while_the_front_stayed_charged_is_a_parting_with_its_evidence() -> None:
    mon = monitor()
    events = feed(mon, [*charged_until(20.0), (20.5, EOT, 1.2), (21.5, HEAD, 5.0)])
    assert [e.state for e in events] == [DOUBTFUL, PARTED]
    parted = events[-1]
    assert parted.witnesses == (BRAKE_PIPE,)
    text = " ".join(parted.evidence)
    assert "rear brake pipe vented (1.2 bar" in text and "front stayed charged (5.0 bar" in text
    assert "the cab did not make" in text
    # The doubt came first, from the rear's vent alone: the front's reading after it was not in yet.
    assert "not yet told from an emergency" in " ".join(events[0].evidence)


def test_a_front_reading_from_before_the_vent_left_the_cab_does_not_part_the_train() -> None:
    # Front charged 0.1 s after the rear's first vented reading: a cab's emergency made just
    # before could not have reached the rear of a 576 m pipe yet... but with the clocks 0.2 s
    # off each, and a short train, "after" is not sure: doubt.
    mon = IntegrityMonitor()
    mon.add_train(ConsistSpec("T1", 35.0, 8))
    events = feed(mon, [*charged_until(20.0), (20.5, EOT, 1.2), (20.6, HEAD, 5.0)])
    assert [e.state for e in events] == [DOUBTFUL]


def test_a_front_reading_still_falling_after_the_cab_vented_is_not_charged_enough() -> None:
    # A short train: the cab vents at 20.0 s, the EOT unit sees its pipe falling at 20.2 s (its
    # emergency status, by the rate of fall), the front's reading is still 4.0 bar at 20.6 s (falling
    # from 5 bar): that reading does not prove the front charged.
    mon = IntegrityMonitor()
    mon.add_train(ConsistSpec("T1", 35.0, 8))
    out = feed(mon, charged_until(20.0))
    out += mon.brake_pipe(at(20.5), at(20.2), "T1", EOT, 4.6, emergency=True)
    out += feed(mon, [(20.6, HEAD, 4.0), (21.6, HEAD, 0.0)])
    assert out and all(e.state == DOUBTFUL for e in out)


def test_a_whole_train_emergency_vents_the_front_first_doubt_never_parted() -> None:
    mon = monitor()
    readings = charged_until(20.0)
    # The cab's emergency at 20.0 s: the front vents at once, the rear 2.5 s later; held 30 s after
    # the stop (at 40 s), then the front recharges (the rear much more slowly).
    for k in range(0, 100):
        t = 20.0 + k
        front = 0.0 if t < 70.0 else min(5.0, (t - 70.0) * 1.0)
        rear = 4.9 if t < 22.5 else (0.0 if t < 72.0 else min(5.0, (t - 72.0) * 0.2))
        readings += [(t + 0.2, HEAD, front), (t + 0.5, EOT, rear)]
    events = feed(mon, readings)
    assert events and all(e.state != PARTED for e in events)
    assert any("the front too" in " ".join(e.evidence) for e in events)


def test_the_front_charged_again_long_after_the_rear_vented_proves_nothing() -> None:
    # A front recharged after a whole-train emergency whose vented readings were all lost: the
    # rule only looks at front readings within the emergency's hold of the rear's last charged one.
    mon = monitor()
    events = feed(mon, [*charged_until(20.0), (22.5, EOT, 0.5), (60.0, HEAD, 5.0), (61.0, EOT, 0.6)])
    assert events and all(e.state == DOUBTFUL for e in events)


def test_a_rear_recharging_about_the_vented_level_is_no_new_vent() -> None:
    # After a whole-train emergency the front is charged again while the rear recharges slowly; its
    # readings chatter about 2.5 bar (noise, resolution): 2.50 then 2.45 is no new vent, the front
    # charged beside it no parting.
    mon = monitor()
    readings = charged_until(20.0)
    readings += [(t + 0.2, HEAD, 0.0) for t in range(20, 60)] + [(t + 0.5, EOT, 0.0) for t in range(20, 60)]
    readings += [(t + 0.2, HEAD, 5.0) for t in range(60, 90)]
    rear = [2.0, 2.2, 2.4, 2.5, 2.45, 2.55, 2.5, 2.45, 2.6, 2.8, 3.0, 3.2, 3.4]
    readings += [(60 + k + 0.5, EOT, bar) for k, bar in enumerate(rear)]
    events = feed(mon, readings)
    assert events and all(e.state != PARTED for e in events)


def test_the_rear_vented_with_no_front_pressure_is_doubt() -> None:
    mon = monitor()
    readings = [(t, EOT, 5.0) for t in range(20)] + [(20.5, EOT, 0.8), (21.5, EOT, 0.4)]
    events = feed(mon, readings)
    assert [e.state for e in events] == [DOUBTFUL]
    assert "the front's status unknown" in events[0].evidence[0]


def test_the_rear_vented_at_its_first_reading_is_doubt() -> None:
    mon = monitor()
    events = feed(mon, [(0.0, EOT, 0.3), (0.5, HEAD, 5.0), (1.5, HEAD, 5.0)])
    assert [e.state for e in events] == [DOUBTFUL]
    assert "not seen charged before" in events[0].evidence[0]


def test_service_braking_says_nothing() -> None:
    # A full service application: 5.0 -> 3.5 bar, the rear lagging; no state at all from the pipe.
    mon = monitor()
    readings = charged_until(10.0)
    for k in range(30):
        t = 10.0 + k
        readings += [(t, HEAD, max(3.5, 5.0 - 0.5 * k)), (t + 0.3, EOT, max(3.5, 5.0 - 0.5 * max(0, k - 3)))]
    assert feed(mon, readings) == []


def test_parted_is_latched_whatever_the_pipe_says_after() -> None:
    mon = monitor()
    events = feed(mon, [*charged_until(20.0), (20.5, EOT, 1.2), (21.5, HEAD, 5.0)])
    assert events[-1].state == PARTED
    later = feed(mon, [(t, EOT, 5.0) for t in range(30, 60)] + [(t + 0.5, HEAD, 0.0) for t in range(30, 60)])
    assert later == [] and mon.state("T1") == PARTED


def test_no_pressure_reported_changes_nothing() -> None:
    # The same fixes with and without NaN pressures give the same events: the witness is silent.
    def run(with_nan: bool) -> list[tuple[str, tuple[str, ...]]]:
        mon = monitor()
        out = []
        for k in range(40):
            t = float(k)
            for role, s in ((HEAD, 1000.0 + 20 * t), (EOT, 1000.0 + 20 * t - LENGTH_M)):
                bar = math.nan if with_nan else None
                if bar is None:
                    evs = mon.fix(at(t + 0.5), at(t), "T1", role, s, 20.0)
                else:
                    evs = mon.fix(at(t + 0.5), at(t), "T1", role, s, 20.0, brake_pipe_bar=bar)
                out += [(e.state, e.witnesses) for e in evs]
        return out

    assert run(True) == run(False)
    assert all(BRAKE_PIPE not in w for _, w in run(True))


def test_an_alarm_repeated_is_one_reading() -> None:
    w = BrakePipeWitness()
    for _ in range(3):
        w.report(True, at(5.0), 0.4)
    assert w.rear == [(at(5.0), 0.4)]
