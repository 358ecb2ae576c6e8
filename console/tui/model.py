"""What the station view shows, as plain data: the view model.

The app never reads the simulator or a parser directly.  A *source* (a live
:class:`SimSource` or a :class:`ReplaySource` over parsed logs) is advanced
by :meth:`StationModel.tick` and described by :meth:`StationModel.snapshot`;
widgets render snapshots.  Everything here is pure and synchronous, so tests
step it by hand and the app can run it on a worker thread.

The view shows what the *console derives* (section engine, crossing units)
from what the devices report; with the truth toggle it shows the simulator's
truth beside it and marks every difference.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Protocol

from console.analysis.crossing.controller import CrossingController
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState, Transition
from console.analysis.timefmt import display
from console.layout import Layout
from parsers.units import NS

SPEEDS = (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)
SEVERITIES = ("info", "warning", "critical")
# A reported head this far from the true one is a difference: GNSS noise and a
# fix's age at line speed stay well inside it, a lost head unit soon leaves it.
TRAIN_DIFF_M = 60.0


@dataclass(frozen=True)
class LogEntry:
    time_ns: int
    severity: str  # info | warning | critical
    text: str


@dataclass(frozen=True)
class SectionView:
    id: str
    name: str
    state: str
    count: int
    count_in: int
    count_out: int
    reason: str
    true_count: int | None  # the simulator's truth; None in replay


@dataclass(frozen=True)
class TrainView:
    id: str
    head_m: float
    tail_m: float
    direction: int
    speed_kmh: float
    next_stop: str
    controller: str
    head_age_s: float | None = None  # since the head unit's last fix reached the console
    eot_age_s: float | None = None  # likewise for the end-of-train unit; None: never heard
    true_head_m: float | None = None  # the simulator's truth (truth view only)
    integrity: str | None = None  # whole | doubtful | parted (the integrity monitor); None: not yet known


@dataclass(frozen=True)
class CrossingView:
    code: str
    chainage_m: float
    warning_on: bool
    countdown_s: float | None  # the crossing unit's earliest arrival of the nearest approaching head
    alarm: bool
    barrier_down: bool = False


@dataclass(frozen=True)
class Snapshot:
    time_ns: int
    mode: str  # sim | replay
    speed: int
    paused: bool
    sections: tuple[SectionView, ...]
    trains: tuple[TrainView, ...]
    crossings: tuple[CrossingView, ...]
    head_counts: dict[str, int]
    line_m: tuple[float, float]
    end_ns: int | None = None  # replay: the end of the logs


class Source(Protocol):
    """Something the view can follow: the simulator, or a replay of logs."""

    layout: Layout
    engine: SectionEngine
    crossings: dict[str, CrossingController]
    mode: str

    @property
    def now_ns(self) -> int: ...

    def advance(self, seconds: float) -> tuple[list[Transition], list[LogEntry]]: ...

    def trains(self, truth: bool = False) -> list[TrainView]: ...

    def true_count(self, section_id: str) -> int | None: ...

    def head_counts(self) -> dict[str, int]: ...


@dataclass
class StationModel:
    """The view's state: a source, the playback speed, selections and the event log."""

    source: Source
    speed_index: int = 2  # 5× real time
    paused: bool = False
    show_truth: bool = False
    selected_section: int = 0
    selected_train: int = 0
    log_filter: str = "info"  # the least severity shown
    log: deque[LogEntry] = field(default_factory=lambda: deque(maxlen=2000))
    speed_history: dict[str, deque[tuple[float, float]]] = field(default_factory=dict)  # (s, km/h)

    @property
    def speed(self) -> int:
        return SPEEDS[self.speed_index]

    def faster(self) -> None:
        self.speed_index = min(self.speed_index + 1, len(SPEEDS) - 1)

    def slower(self) -> None:
        self.speed_index = max(self.speed_index - 1, 0)

    def toggle_pause(self) -> None:
        self.paused = not self.paused

    def tick(self, wall_s: float) -> None:
        """Wall-clock time passed: advance the source by it times the speed (unless paused)."""
        if not self.paused:
            self.step(wall_s * self.speed)

    def step(self, sim_s: float) -> None:
        """Advance the source by ``sim_s`` simulated seconds, whatever the pause state."""
        self.record(*self.source.advance(sim_s))

    def record(self, transitions: list[Transition], entries: list[LogEntry]) -> None:
        """What the source says happened: section changes and entries into the log, trains' speeds noted."""
        for tr in transitions:
            sev = (
                "critical"
                if tr.state is SectionState.DISTURBED
                else "warning"
                if tr.state is SectionState.PREPARATORY
                else "info"
            )
            self.log.append(LogEntry(tr.time_ns, sev, f"section {tr.section}: {tr.state.value} — {tr.reason}"))
        self.log.extend(entries)
        now_s = self.source.now_ns / NS
        for t in self.source.trains():
            hist = self.speed_history.setdefault(t.id, deque(maxlen=1200))
            hist.append((now_s, t.speed_kmh))

    def visible_log(self, limit: int = 200) -> list[LogEntry]:
        least = SEVERITIES.index(self.log_filter)
        shown = [e for e in self.log if SEVERITIES.index(e.severity) >= least]
        return shown[-limit:]

    def cycle_log_filter(self) -> None:
        self.log_filter = SEVERITIES[(SEVERITIES.index(self.log_filter) + 1) % len(SEVERITIES)]

    # -- selections -------------------------------------------------------
    def section_id(self) -> str | None:
        sections = self.source.layout.sections
        return sections[self.selected_section % len(sections)].id if sections else None

    def train_id(self, snap: Snapshot | None = None) -> str | None:
        """The selected train (from ``snap`` when given: no second pass over the units)."""
        trains = snap.trains if snap is not None else self.source.trains()
        return trains[self.selected_train % len(trains)].id if trains else None

    def select_section(self, delta: int = 1) -> None:
        n = len(self.source.layout.sections)
        if n:
            self.selected_section = (self.selected_section + delta) % n

    def select_train(self, delta: int = 1) -> None:
        n = len(self.source.trains())
        if n:
            self.selected_train = (self.selected_train + delta) % n

    def note(self, severity: str, text: str) -> None:
        self.log.append(LogEntry(self.source.now_ns, severity, text))

    # -- what the widgets draw ---------------------------------------------
    def snapshot(self) -> Snapshot:
        src = self.source
        eng = src.engine
        sections = []
        for s in src.layout.sections:
            st = eng.sections[s.id]
            sections.append(
                SectionView(
                    s.id,
                    s.name,
                    st.state.value,
                    st.count,
                    st.count_in,
                    st.count_out,
                    st.reason,
                    src.true_count(s.id) if self.show_truth else None,
                )
            )
        trains = src.trains(truth=self.show_truth)
        crossings = [
            CrossingView(
                code,
                ctl.crossing.chainage_m,
                ctl.warning_on,
                ctl.arrival_s(src.now_ns),
                ctl.alarm,
                ctl.barriers_down(src.now_ns),
            )
            for code, ctl in src.crossings.items()
        ]
        ch = [p.chainage_m for p in src.layout.track] or [h.chainage_m for h in src.layout.heads]
        return Snapshot(
            time_ns=src.now_ns,
            mode=src.mode,
            speed=self.speed,
            paused=self.paused,
            sections=tuple(sections),
            trains=tuple(trains),
            crossings=tuple(crossings),
            head_counts=src.head_counts(),
            line_m=(min(ch), max(ch)),
            end_ns=getattr(src, "end_ns", None),
        )

    def differences(self, snap: Snapshot) -> set[str]:
        """Sections and trains where the console disagrees with the truth (truth view on)."""
        out = {t.id for t in snap.trains if t.true_head_m is not None and abs(t.head_m - t.true_head_m) > TRAIN_DIFF_M}
        for s in snap.sections:
            if s.true_count is None:
                continue
            # Every disagreement counts: clear over a train is the dangerous kind,
            # occupied, disturbed or preparatory over an empty section the safe kind.
            if (s.state == "clear") != (s.true_count == 0):
                out.add(s.id)
        return out


def clock(snap: Snapshot) -> str:
    return display(snap.time_ns)[:19]


def speed_kmh(mps: float) -> float:
    return 0.0 if math.isnan(mps) else mps * 3.6
