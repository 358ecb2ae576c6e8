"""Detection events: what every source feeds the section engine.

Diagnostic logs, intelligent-sensor frames, CAN count frames and the
simulator are all turned into one time-ordered stream of
:class:`DetectionEvent`; :mod:`console.analysis.sections.engine` runs on that stream
and nothing else, so every source gets the same safety logic.

Direction convention: ``+1`` is *up* (increasing chainage), ``-1`` down,
``0`` unknown.  The layout says, per counting head, which channel order is up.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import pandas as pd

UP, DOWN, UNKNOWN = 1, -1, 0


class EventKind(StrEnum):
    AXLE = "axle"  # a counted axle passing a head, with a direction
    SINGLE_CHANNEL = "single_channel"  # one system damped, the other not: not an axle, but doubt
    CHANNEL_FAULT = "channel_fault"  # a channel (system / element) is faulty; channel None = whole head
    CHANNEL_OK = "channel_ok"  # the channel passed its self-test again
    HEAD_DAMPED = "head_damped"  # something is over the head right now
    HEAD_FREE = "head_free"  # nothing over the head any more
    POWER_LOSS = "power_loss"  # the head's device lost power or contact (explicit, or a record gap)
    POWER_RESTORED = "power_restored"
    INTERFERENCE = "interference"  # an isolated pulse (soft timing): hold the section occupied
    ACCIDENTAL = "accidental"  # that pulse was confirmed accidental: lift the hold
    COUNT_ERROR = "count_error"  # the channels disagreed (majority not unanimous, ERR = 1)
    RESET = "reset"  # an operator asks to reset a section (``head`` holds the section id)
    # The head's records went back in time within a file (console.analysis.passages.clock_steps): a clock step
    # back, or a file out of order; sorted by time, counts on either side of it may be out of order. Last of the
    # kinds: the codes of the others, stored in archives, stay as they were.
    CLOCK_STEP = "clock_step"


@dataclass(frozen=True, slots=True)
class DetectionEvent:
    """One thing that happened at a counting head (or, for RESET, to a section)."""

    time_ns: int
    kind: EventKind
    head: str
    direction: int = UNKNOWN
    channel: int | None = None
    source: str = ""  # diag | frame | can | sim | operator
    detail: str = ""


EVENT_COLUMNS = ("time_ns", "kind", "head", "direction", "channel", "source", "detail")


def events_to_frame(events: Iterable[DetectionEvent]) -> pd.DataFrame:
    """A table of events (one row each), sorted by time, stable for equal times."""
    import pandas as pd

    rows = [(e.time_ns, str(e.kind), e.head, e.direction, e.channel, e.source, e.detail) for e in events]
    frame = pd.DataFrame(rows, columns=list(EVENT_COLUMNS))
    frame["channel"] = frame["channel"].astype("Int64")
    return frame.sort_values("time_ns", kind="stable").reset_index(drop=True)


def frame_to_events(frame: pd.DataFrame) -> list[DetectionEvent]:
    """The inverse of :func:`events_to_frame`."""
    import pandas as pd

    out = []
    r: Any
    for r in frame.itertuples(index=False):
        channel = None if pd.isna(r.channel) else int(r.channel)
        out.append(
            DetectionEvent(
                int(r.time_ns), EventKind(r.kind), str(r.head), int(r.direction), channel, str(r.source), str(r.detail)
            )
        )
    return out


def sort_events(events: Iterable[DetectionEvent]) -> list[DetectionEvent]:
    """Time order; stable, so the order of simultaneous events is kept."""
    return sorted(events, key=lambda e: e.time_ns)
