"""Where the pipeline's results go: one interface, many sinks.

The pipeline hands every result to a :class:`Sink` as soon as it is made:
closed passages and their axles, section state changes, ledger rows, reset
records, crossing events and health findings.  A sink renders or stores
them (a table, a JSON document, JSON lines, a report spool, the archive, the
station view, metrics); it never computes what the pipeline computes.
Every method has a no-op default, so a sink implements only what it takes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from console.analysis.events.block import EventBlock
    from console.analysis.events.detection import DetectionEvent
    from console.analysis.head_table import Heads
    from console.analysis.health.findings import Finding
    from console.analysis.passages.buckets import Columns
    from console.analysis.sections.state import LedgerEntry, ResetRecord, Transition


class Sink:
    """Takes the pipeline's results as they are made (every method optional)."""

    def passages(self, cols: Columns, heads: Heads) -> None:
        """A batch of closed passages, by start time (status-only ones as the pipeline's settings say)."""

    def axles(self, cols: Columns, heads: Heads) -> None:
        """The axles of a batch of closed passages."""

    def detections(self, block: EventBlock) -> None:
        """Detection events released to the section engine, in its order (as columns)."""

    def transitions(self, rows: Sequence[Transition]) -> None:
        """Section state changes, in order."""

    def ledger(self, rows: Sequence[LedgerEntry]) -> None:
        """Axles counted into and out of sections, in order."""

    def resets(self, rows: Sequence[ResetRecord]) -> None:
        """Reset requests, accepted or refused."""

    def findings(self, rows: Sequence[Finding]) -> None:
        """Health findings."""

    def crossing(self, rows: Sequence[Any]) -> None:
        """Crossing controller events (warning on, off, alarms)."""

    def restart(self, passages: bool) -> None:
        """The input is read again from its start: forget the section history, events and findings taken
        so far, and the passages and axles too when ``passages`` (else they will not be handed again)."""


class Sinks(Sink):
    """Several sinks as one, each given every result in the order they were listed."""

    def __init__(self, *sinks: Sink | None) -> None:
        self.sinks = [s for s in sinks if s is not None]

    def passages(self, cols: Columns, heads: Heads) -> None:
        for s in self.sinks:
            s.passages(cols, heads)

    def axles(self, cols: Columns, heads: Heads) -> None:
        for s in self.sinks:
            s.axles(cols, heads)

    def detections(self, block: EventBlock) -> None:
        for s in self.sinks:
            s.detections(block)

    def transitions(self, rows: Sequence[Transition]) -> None:
        for s in self.sinks:
            s.transitions(rows)

    def ledger(self, rows: Sequence[LedgerEntry]) -> None:
        for s in self.sinks:
            s.ledger(rows)

    def resets(self, rows: Sequence[ResetRecord]) -> None:
        for s in self.sinks:
            s.resets(rows)

    def findings(self, rows: Sequence[Finding]) -> None:
        for s in self.sinks:
            s.findings(rows)

    def crossing(self, rows: Sequence[Any]) -> None:
        for s in self.sinks:
            s.crossing(rows)

    def restart(self, passages: bool) -> None:
        for s in self.sinks:
            s.restart(passages)


class EventList(Sink):
    """The detection events released, kept as objects (a replay steps through them; tests compare them)."""

    def __init__(self) -> None:
        self.events: list[DetectionEvent] = []

    def detections(self, block: EventBlock) -> None:
        self.events += block.events()

    def restart(self, passages: bool) -> None:
        self.events = []
