"""The section engine's states and the records it keeps: what a section is in, each change of it,
each axle counted and each reset asked for (:mod:`console.analysis.sections.engine` is the state machine over them)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from console.layout import Section


class SectionState(StrEnum):
    CLEAR = "clear"
    OCCUPIED = "occupied"
    DISTURBED = "disturbed"
    PREPARATORY = "preparatory"


# One letter each, so a state reads without colour.
STATE_MARK = {
    SectionState.CLEAR: "·",
    SectionState.OCCUPIED: "#",
    SectionState.DISTURBED: "!",
    SectionState.PREPARATORY: "?",
}


@dataclass
class EngineSection:
    """Mutable state of one section inside the engine."""

    section: Section
    state: SectionState
    count: int = 0
    count_in: int = 0
    count_out: int = 0
    reason: str = ""
    since_ns: int = 0
    held_by: set[str] = field(default_factory=set)  # heads with a suspected interference pulse
    swept_in: bool = False  # preparatory: the sweep train has entered


@dataclass(frozen=True)
class Transition:
    time_ns: int
    section: str
    state: SectionState
    count: int
    reason: str


@dataclass(frozen=True)
class LedgerEntry:
    time_ns: int
    section: str
    head: str
    delta: int  # +1 counted in, -1 counted out
    count: int  # after this axle


@dataclass(frozen=True)
class ResetRecord:
    time_ns: int
    section: str
    accepted: bool
    reason: str
