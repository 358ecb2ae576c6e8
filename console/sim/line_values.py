"""The simulated line's settings and the values its parts pass around: the trains, the truth's axles,
the heads' wheel records, the units' fixes, one step's reports, and what watches the line.

Kept apart from :class:`console.sim.station.StationSim` so the modules that move the trains, report the
heads and send the units' fixes read them without importing the station (no import circle)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

from console.analysis.crossing.values import CrossingEvent
from console.layout import Consist
from console.sim import brake_pipe as bp
from console.sim.faults import Fault
from console.sim.radio import LoRaLink
from console.sim.slow_faults import HealthRows
from parsers.units import NS


@dataclass(frozen=True)
class SimConfig:
    seed: int = 1
    trains_per_hour: float = 6.0
    first_train_s: float = 60.0
    dwell_s: float = 30.0
    accel_mps2: float = 0.6
    brake_mps2: float = 0.7
    gnss_noise_m: float = 3.0
    gnss_loss: float = 0.05
    radio: LoRaLink = field(default_factory=LoRaLink)
    heartbeat_s: float = 20.0  # each head's device writes a status record this often
    faults: tuple[Fault, ...] = ()
    start_ns: int = 1_772_438_400 * NS  # 2026-03-02 08:00 UTC
    # Each head's health registers (1-edge counters, analog values) every this often; None: not written,
    # unless a slow fault on a head needs them (then every HealthSettings.period_s).
    health_period_s: float | None = None
    fleet: int = 0  # > 0: trains are this many trainsets, T1..Tn, each with its own units, making trip after trip


@dataclass
class SimTrain:
    id: str
    consist: Consist
    direction: int
    x_m: float  # head chainage
    v_mps: float = 0.0
    entered_s: float = 0.0
    dwell_until_s: float | None = None
    stops: list[float] = field(default_factory=list)  # head chainages to stop at, in order
    done: bool = False
    next_head_fix_s: float = 0.0
    next_eot_fix_s: float = 0.0
    controller: str = "pid"
    driver: Any = None  # the ATO driver (console.sim.ato.Driver) when the force model runs the train
    travelled_m: float = 0.0
    units: tuple[str, ...] = ("head", "eot")  # the GNSS units riding on it
    axle_offset: int = 0  # a rear part's first axle, in the whole consist's numbering
    rear: SimTrain | None = None  # the rear part, once the train has parted
    pipe_bar: float = bp.NOMINAL_BAR  # its brake pipe (both ends: the reduction's travel is neglected)
    vent_from_s: float | None = None  # a rear part: its pipe vents from then (the break's wave at the EOT)
    alarms_s: list[float] = field(default_factory=list)  # the EOT unit's emergency statuses still to send

    @property
    def tail_m(self) -> float:
        return self.x_m - self.direction * self.consist.length_m


@dataclass(frozen=True)
class TruthAxle:
    """One wheel passing one head's centre, as it really happened."""

    train: str
    head: str
    axle: int
    time_ns: int
    speed_mps: float
    direction: int


@dataclass(frozen=True)
class WheelRecord:
    t_ns: int
    head: str
    channel: int
    value: int  # 1 damped, 0 free


@dataclass(frozen=True)
class SentFix:
    """A GNSS fix as a unit sends it (written to NMEA; the radio delivers it, or not, after its latency)."""

    t_ns: int
    train: str
    role: str
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    valid: bool
    brake_pipe_bar: float = math.nan  # the unit's end of the brake pipe (the LoRa payload's version 2)
    emergency: bool = False  # the unit's emergency status: its brake pipe venting, sent at once


@dataclass
class StepResult:
    """What the devices reported in one step (each list in time order), up to ``t_ns``."""

    t_ns: int
    records: list[WheelRecord]  # wheel-sensor onsets and releases, as the heads report them
    heartbeats: list[tuple[int, str]]  # (time, head): each powered head's status record
    health: list[HealthRows]  # the heads' health registers written in this step
    fixes: list[SentFix]  # fixes the units sent (their own logs: NMEA)
    received: list[SentFix]  # fixes the radio delivered (sent earlier, less those it lost), in delivery order


class Console(Protocol):
    """What watches the simulated line: the station's console (console.live.simulated)."""

    def take(self, step: StepResult) -> None:
        """A step's reports."""

    def finish(self) -> None:
        """The run ends: what the console still holds is decided."""

    def section_states(self) -> dict[str, str]:
        """Each section's state as the console shows it."""

    def crossing_events(self) -> dict[str, list[CrossingEvent]]:
        """Each crossing unit's events so far (warnings on and off, alarms)."""
