"""The brake pipe's witness of train integrity: the rear pipe vented while the front stayed charged.

An air-braked train has one brake pipe from the cab to the last vehicle,
charged at about 5 bar; service braking lowers it a little (a full service
application leaves about 3.5 bar), an emergency application vents it to
nothing.  When a coupling breaks, the hoses part and the rear part's pipe
vents: the EOT unit sees an emergency the cab did not make (an "undesired
emergency").  The head unit reports the front (cab) pressure, the EOT unit
the rear pressure; real EOT units send such an emergency status at once and
repeat it.

A whole-train emergency vents the front first: the reduction travels back
along the pipe, and no pressure wave in air travels faster than sound
(``FASTEST_WAVE_MPS``).  So a front still charged at a moment the vent would
already have had to leave the cab — the rear's first vented reading, less
the pipe's length at the speed of sound, plus the time the front's own
reading may take to fall to what it read (from the highest it read before,
at ``VENT_MIN_BAR_S`` at least) and the units' clock offsets — is
a front that never vented: the rear vented on its own.  An emergency is held
until the train stands and for ``emergency_hold_s`` after it, so a front
seen charged again soon after a whole-train emergency is not possible
either; the rule only looks at front readings within that time of the rear's
last reading still charged, and at none that is not charged in between.

* **parted**: the rear vented (its first vented reading after a charged one;
  readings between the two levels, a pipe recharging, arm no new vent)
  and a front reading charged, measured after the vent would have had to
  leave the cab, with no front reading below charged in between;
* **doubt**: the rear vented and the front vented too (an emergency of the
  whole train), or its status since not known, or the rear's vent without a
  charged reading before it to date it;
An EOT unit's emergency status (it saw its pipe venting by the rate of fall,
before the level is down) counts as a vented reading at its measurement.

* nothing, while the rear is charged, or no pressure is reported (units that
  do not report it, plain NMEA trackers): then the other witnesses decide.
"""

from __future__ import annotations

from bisect import bisect_left, insort
from dataclasses import dataclass, field

from console.analysis.integrity.counts import NONE, Opinion
from console.analysis.timefmt import iso
from parsers.units import NS

BRAKE_PIPE = "brake_pipe"
REGULATED_BAR = 5.0  # the cab charges the pipe to this
VENTED_BAR = 2.5  # below: vented (an emergency); a full service application leaves about 3.5 bar
CHARGED_BAR = 3.2  # at or above: charged (running, or service braking)
FASTEST_WAVE_MPS = 340.0  # no reduction runs along the pipe faster than sound in air
SLOWEST_WAVE_MPS = 150.0  # an emergency reduction reaches the rear at least this fast (vent valves)
ALARM_ONSET_S = 0.5  # an EOT unit's emergency status comes within this of the fall's start
LONGEST_TRAIN_M = 1500.0  # where the train's length is not known
REAR_FALL_S = 3.0  # the rear's reading falls below VENTED_BAR within this once the reduction arrives
VENT_MIN_BAR_S = 1.8  # a cab's emergency lowers the front's reading at least this fast (below 3.2 bar in 1 s)
SENSOR_MARGIN_BAR = 0.1  # a reading's noise and resolution


@dataclass(frozen=True)
class BrakeSettings:
    clock_offset_s: float = 0.2  # each unit's clock may be this far off
    emergency_hold_s: float = 30.0  # an emergency application is held at least this long
    history_s: float = 240.0


@dataclass
class BrakePipeWitness:
    """The two ends' pressure readings of one train: (measurement time ns, bar), in time order."""

    s: BrakeSettings = field(default_factory=BrakeSettings)
    front: list[tuple[int, float]] = field(default_factory=list)
    rear: list[tuple[int, float]] = field(default_factory=list)
    alarms: list[int] = field(default_factory=list)  # the EOT unit's emergency statuses (measured at)

    def report(self, rear: bool, t_ns: int, bar: float, emergency: bool = False) -> None:
        """A reading; ``emergency``: the unit's own emergency status (it saw its pipe venting, by the
        rate of fall, before the level is down): counted as vented (kept as a reading of 0 bar)."""
        readings = self.rear if rear else self.front
        reading = (t_ns, 0.0 if emergency else bar)
        if reading in readings[-8:]:
            return  # a repeat of the same status (an alarm's retransmission)
        insort(readings, reading)
        if emergency and rear:
            insort(self.alarms, t_ns)
        horizon = readings[-1][0] - int(self.s.history_s * NS)
        k = bisect_left(readings, (horizon, -1.0))
        if k > 0:
            del readings[:k]
        k = bisect_left(self.alarms, horizon)
        if k > 0:
            del self.alarms[:k]

    def _rear(self) -> list[tuple[int, float]]:
        """The rear's readings, less those of a fall in progress: still above the vented level
        within ``REAR_FALL_S`` after the unit's emergency status (the pipe is venting)."""
        if not self.alarms:
            return self.rear
        fall = int(REAR_FALL_S * NS)
        return [
            (t, b)
            for t, b in self.rear
            if b < VENTED_BAR or not any(a <= t <= a + fall for a in self.alarms[bisect_left(self.alarms, t - fall) :])
        ]

    def opinion(self, length_m: float | None) -> Opinion:
        """``length_m``: the pipe's length (the train's); None where only guessed (then no credit
        for the wave's travel, and the longest train's travel time allowed)."""
        rear = self._rear()
        if not rear or rear[-1][1] >= VENTED_BAR:
            return NONE
        # The rear's vent: its first vented reading after the last one charged.  Only a charged pipe
        # arms it again: readings about the vented level (a pipe recharging slowly after an emergency)
        # are no new vent.
        j = len(rear) - 1
        while j >= 0 and rear[j][1] < CHARGED_BAR:
            j -= 1
        t_vent, bar_vent = next(r for r in rear[j + 1 :] if r[1] < VENTED_BAR)
        t_before = rear[j][0] if j >= 0 else None
        if t_vent in self.alarms:
            # The unit's emergency status: it saw the fall begin, within ALARM_ONSET_S of it.
            t_before = max(t_before or 0, t_vent - int(ALARM_ONSET_S * NS))
        what = f"{bar_vent:.1f} bar" if bar_vent > 0.0 else "emergency status"
        rear_txt = f"rear brake pipe vented ({what} at {_hms(t_vent)})"
        if t_before is None:
            return Opinion("doubt", (BRAKE_PIPE,), (rear_txt + ", not seen charged before",), t_vent)
        clock_ns = int(2 * self.s.clock_offset_s * NS)
        # A whole-train emergency started at the front after t_before - travel (the rear still read charged).
        travel_ns = int(((length_m or LONGEST_TRAIN_M) / SLOWEST_WAVE_MPS + REAR_FALL_S) * NS)
        since = t_before - travel_ns - clock_ns
        # The vent would have left the cab by t_vent - length / c (a wave no faster than sound).
        t_left = t_vent - int((length_m or 0.0) / FASTEST_WAVE_MPS * NS) + clock_ns
        # ... and a cab's emergency is still held this long after t_before.
        t_until = t_before + int(self.s.emergency_hold_s * NS) - travel_ns - 2 * clock_ns
        for t, bar in self.front:
            if t < since:
                continue
            if bar < CHARGED_BAR:
                why = f"{rear_txt} and the front too ({bar:.1f} bar at {_hms(t)}): an emergency of the whole train"
                return Opinion("doubt", (BRAKE_PIPE,), (why,), t_vent)
            if t_left + self._fall_ns(t, bar) <= t <= t_until:
                why = (
                    f"{rear_txt} while the front stayed charged ({bar:.1f} bar at {_hms(t)}, "
                    f"{(t - t_vent) / NS:+.1f} s): an emergency at the rear the cab did not make"
                )
                return Opinion("parted", (BRAKE_PIPE,), (why,), t_vent)
        last = [b for t, b in self.front if t >= since]
        known = f"the front charged at its last reading ({last[-1]:.1f} bar)" if last else "the front's status unknown"
        return Opinion("doubt", (BRAKE_PIPE,), (f"{rear_txt}, {known}: not yet told from an emergency",), t_vent)

    def _fall_ns(self, t_ns: int, bar: float) -> int:
        """How long before ``t_ns`` the cab may have vented and the front still read ``bar``: a
        reading falls from the highest the front read in the minute before (the regulated charge at
        least) at ``VENT_MIN_BAR_S``
        at least (a reading at full charge: a vent of a moment ago at most)."""
        lo = bisect_left(self.front, (t_ns - 60 * NS, -1.0))
        # A pipe recharging may have risen past its last reading: the regulated charge at least.
        top = max([REGULATED_BAR, *(b for tt, b in self.front[lo:] if tt <= t_ns)])
        return int(max(0.0, top + SENSOR_MARGIN_BAR - bar) / VENT_MIN_BAR_S * NS)


def _hms(t_ns: int) -> str:
    return (iso(t_ns) or "")[11:21]
