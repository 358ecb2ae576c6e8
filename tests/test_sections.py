"""The section engine, scenario by scenario (seed 003's rules, fail-safe)."""

from __future__ import annotations

from console.analysis.events.detection import DOWN, UP, DetectionEvent, EventKind
from console.analysis.sections.engine import SectionEngine, run_sections
from console.analysis.sections.state import SectionState
from console.layout import load_layout

LAY = load_layout("example")  # 1G: WS1(+1) WS2(-1); B1: WS2(+1) WS3(-1); ...
S = 1_000_000_000


def axle(t: float, head: str, direction: int = UP) -> DetectionEvent:
    return DetectionEvent(int(t * S), EventKind.AXLE, head, direction)


def ev(t: float, kind: EventKind, head: str, channel: int | None = None) -> DetectionEvent:
    return DetectionEvent(int(t * S), kind, head, 0, channel)


def train_through_1g(t0: float, n: int = 4) -> list[DetectionEvent]:
    return [axle(t0 + k, "WS1") for k in range(n)] + [axle(t0 + 60 + k, "WS2") for k in range(n)]


def test_counts_in_and_out_make_occupied_then_clear() -> None:
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    events = train_through_1g(0)
    for e in events[:4]:
        eng.step(e)
    assert (eng.state("1G"), eng.count("1G")) == (SectionState.OCCUPIED, 4)
    for e in events[4:]:
        eng.step(e)
    assert (eng.state("1G"), eng.count("1G")) == (SectionState.CLEAR, 0)
    assert eng.state("B1") is SectionState.OCCUPIED  # the train went on into B1


def test_ledger_records_every_count() -> None:
    r = run_sections(LAY, train_through_1g(0), initial=SectionState.CLEAR)
    led = r.ledger[r.ledger.section == "1G"]
    assert led["delta"].tolist() == [1, 1, 1, 1, -1, -1, -1, -1]
    assert r.final["1G"][:4] == ("clear", 0, 4, 4)


def test_underflow_is_disturbed_not_clear() -> None:
    # An axle counted out of 1G (down past WS1) that was never counted in.
    r = run_sections(LAY, [axle(0, "WS1", DOWN)], initial=SectionState.CLEAR)
    assert r.final["1G"][0] == "disturbed" and "underflow" in r.final["1G"][4]


def test_power_loss_disturbs_and_restoring_power_does_not_clear() -> None:
    events = [ev(0, EventKind.POWER_LOSS, "WS2"), ev(30, EventKind.POWER_RESTORED, "WS2")]
    r = run_sections(LAY, events, initial=SectionState.CLEAR)
    assert r.final["1G"][0] == "disturbed" and r.final["B1"][0] == "disturbed"
    assert r.final["B2"][0] == "clear"  # WS2 does not bound B2


def test_dead_channel_disturbs_the_sections_it_bounds() -> None:
    r = run_sections(LAY, [ev(5, EventKind.CHANNEL_FAULT, "WS3", channel=2)], initial=SectionState.CLEAR)
    assert r.final["B1"][0] == "disturbed" and r.final["B2"][0] == "disturbed"
    assert "channel 2 faulty at WS3" in r.final["B1"][4]


def test_isolated_pulse_holds_occupied_until_confirmed_accidental() -> None:
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    eng.step(ev(0, EventKind.CHANNEL_OK, "WS2", 1))  # WS2 heard: 1G's other bound is in the log
    eng.step(ev(0, EventKind.INTERFERENCE, "WS1", 1))
    assert eng.state("1G") is SectionState.OCCUPIED
    eng.step(ev(60, EventKind.ACCIDENTAL, "WS1", 1))
    assert eng.state("1G") is SectionState.CLEAR


def test_reset_refused_while_a_head_is_damped() -> None:
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    eng.step(ev(0, EventKind.POWER_LOSS, "WS1"))
    eng.step(ev(10, EventKind.POWER_RESTORED, "WS1"))
    eng.step(ev(20, EventKind.HEAD_DAMPED, "WS2"))
    eng.step(ev(30, EventKind.RESET, "1G"))
    assert eng.state("1G") is SectionState.DISTURBED
    assert eng.resets[-1].accepted is False and "WS2 is damped" in eng.resets[-1].reason
    eng.step(ev(40, EventKind.HEAD_FREE, "WS2"))
    eng.step(ev(50, EventKind.RESET, "1G"))
    assert eng.resets[-1].accepted and eng.state("1G") is SectionState.PREPARATORY


def test_reset_refused_during_a_fault_or_power_loss() -> None:
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    eng.step(ev(0, EventKind.CHANNEL_FAULT, "WS1", 1))
    eng.step(ev(5, EventKind.RESET, "1G"))
    assert "channel fault at WS1" in eng.resets[-1].reason
    eng.step(ev(6, EventKind.CHANNEL_OK, "WS1", 1))
    eng.step(ev(7, EventKind.POWER_LOSS, "WS2"))
    eng.step(ev(8, EventKind.RESET, "1G"))
    assert "no power or contact at WS2" in eng.resets[-1].reason
    assert eng.state("1G") is SectionState.DISTURBED


def test_preparatory_reset_cleared_by_a_sweep_train() -> None:
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    eng.step(ev(0, EventKind.SINGLE_CHANNEL, "WS1", 2))
    assert eng.state("1G") is SectionState.DISTURBED
    eng.step(ev(10, EventKind.RESET, "1G"))
    assert eng.state("1G") is SectionState.PREPARATORY
    sweep = train_through_1g(100)
    for e in sweep[:4]:
        eng.step(e)
        assert eng.state("1G") is SectionState.PREPARATORY  # in: still not clear
    for e in sweep[4:]:
        eng.step(e)
    assert eng.state("1G") is SectionState.CLEAR


def test_preparatory_section_with_a_train_left_inside_goes_disturbed() -> None:
    # A reset while a stopped train is inside: when it leaves, the count underflows.
    eng = SectionEngine(LAY, initial=SectionState.CLEAR)
    for e in [axle(k, "WS1") for k in range(4)]:
        eng.step(e)
    eng.step(ev(10, EventKind.COUNT_ERROR, "WS1"))
    eng.step(ev(20, EventKind.RESET, "1G"))
    eng.step(axle(30, "WS2"))
    assert eng.state("1G") is SectionState.DISTURBED


def test_unknown_direction_is_disturbed() -> None:
    r = run_sections(LAY, [DetectionEvent(0, EventKind.AXLE, "WS1", 0)], initial=SectionState.CLEAR)
    assert r.final["1G"][0] == "disturbed"


def test_start_of_log_is_preparatory_until_a_sweep() -> None:
    r = run_sections(LAY, train_through_1g(0))
    assert r.timeline.iloc[0]["state"] == "preparatory"
    assert r.final["1G"][0] == "clear"
    assert r.final["2G"][0] == "preparatory"  # no train has swept it


def test_timeline_holds_state_changes_only() -> None:
    r = run_sections(LAY, train_through_1g(0), initial=SectionState.CLEAR)
    states = r.timeline[r.timeline.section == "1G"]["state"].tolist()
    assert states == ["clear", "occupied", "clear"]
