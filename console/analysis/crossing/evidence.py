"""What one GNSS device's fixes prove about its train: speed, direction, jumps.

The crossing unit needs an upper bound on the train's speed (the earliest
arrival must never be late) and it must not be fooled by a wild fix.  Many
device exports carry no speed at all, so the bound comes from the positions
themselves when it must:

* **Reported speed** (Doppler, from the receiver): taken with its error
  allowance (a few tenths of a m/s: at 30 m/s and 70 s that is a second of
  warning), raised to what the positions prove at least (a frozen ``0.0`` on a moving
  train is doubt, not standstill).
* **No reported speed**: the mean speed between two accepted fixes
  ``Δt`` apart is at most ``(|Δs| + 2·noise) / Δt``, and the speed now is
  at most that mean plus ``a·Δt / 2`` (the train may have accelerated at
  ``a`` since).  Every older fix in the window gives such a bound; the
  smallest is kept.  Short baselines are swamped by noise, long ones by the
  acceleration term, so the minimum over all of them is robust to jitter
  at 2.5 Hz and still tight at 0.1 Hz.  A standing train earns a small
  bound only from positions that stay put over several seconds.
* **One fix, or none**: nothing is known, the worst case is assumed
  (the most a train can run, ``max_speed_mps``).
* **Position jumps**: a fix further from the last accepted one than the
  train could have run (its speed bound plus a hard acceleration, capped at
  the most any train can run, plus twice the noise allowance) is set aside
  and counted.  It does not refresh the device: staleness, and with it the
  held warning and the alarm, runs on from the last accepted fix.  Two set
  aside fixes that agree with each other show the *track* was wrong (a wild
  first fix, or a receiver re-acquiring after a tunnel): the device starts
  over from them, its speed unknown again.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass

from console.analysis.window import Window
from parsers.units import NS

REPORTED, ESTIMATED, ASSUMED = "reported", "estimated", "assumed"


@dataclass(frozen=True)
class Report:
    """One accepted fix of a device, with what it says about the speed."""

    t_fix_ns: int
    chainage_m: float
    speed_mps: float  # as the device reported it (NaN: the export had none)
    speed_hi_mps: float  # the fastest the train can be running at t_fix (m/s)
    speed_basis: str  # reported | estimated | assumed
    restarted: bool = False  # the device's track started over at this fix (after jumps)


@dataclass(frozen=True)
class EvidenceLimits:
    noise_m: float  # GNSS noise allowance per fix (a bound, not a sigma)
    accel_mps2: float  # the most a train accelerates in service
    jump_accel_mps2: float  # no train changes speed faster than this (braking included)
    max_speed_mps: float  # no train runs faster
    window_s: float = 45.0  # how far back the speed bound looks
    speed_error_mps: float = 0.5  # allowance on a reported (Doppler) speed
    history_step_s: float = 2.0  # keep one fix per this for the bound (bounded work at 2.5 Hz)


class DeviceEvidence:
    """The accepted fixes of one device and the jumps set aside."""

    def __init__(self, limits: EvidenceLimits) -> None:
        self.lim = limits
        self.last: Report | None = None
        self.history: list[tuple[int, float]] = []  # (t_fix_ns, chainage_m), thinned: a list (a deque is 600 B)
        self.latest: Window[float] = Window(3)  # chainages of the last accepted fixes
        self.jumps = 0  # fixes set aside as position jumps
        self.restarts = 0  # times the track started over from two agreeing set-aside fixes
        self.rejected_since_last = False  # a jump was set aside after the last accepted fix
        self._pending: tuple[int, float, float] | None = None  # the last set-aside fix

    # -- speed -------------------------------------------------------------
    def _upper(self, t_ns: int, chainage_m: float) -> float:
        """Upper bound of |speed| at ``t_ns`` from the positions alone (inf without a baseline)."""
        noise2, half_a = 2 * self.lim.noise_m, self.lim.accel_mps2 / 2
        hi = math.inf
        for t_old, ch_old in self.history:  # ≤ window / history_step entries
            dt = (t_ns - t_old) / NS
            if dt > 0:
                b = (abs(chainage_m - ch_old) + noise2) / dt + half_a * dt
                if b < hi:
                    hi = b
        return hi

    def _lower(self, t_ns: int, chainage_m: float) -> float:
        """Lower bound of |speed| at ``t_ns`` from the positions alone (0 without evidence)."""
        noise2, half_b = 2 * self.lim.noise_m, self.lim.jump_accel_mps2 / 2
        lo = 0.0
        for t_old, ch_old in self.history:
            dt = (t_ns - t_old) / NS
            if dt > 0:
                b = (abs(chainage_m - ch_old) - noise2) / dt - half_b * dt
                if b > lo:
                    lo = b
        return lo

    def _report(self, t_ns: int, chainage_m: float, speed_mps: float, restarted: bool = False) -> Report:
        if not math.isnan(speed_mps):
            hi = max(speed_mps + self.lim.speed_error_mps, self._lower(t_ns, chainage_m))
            return Report(t_ns, chainage_m, speed_mps, hi, REPORTED, restarted)
        hi = self._upper(t_ns, chainage_m)
        if math.isinf(hi):
            return Report(t_ns, chainage_m, speed_mps, self.lim.max_speed_mps, ASSUMED, restarted)
        return Report(t_ns, chainage_m, speed_mps, min(hi, self.lim.max_speed_mps), ESTIMATED, restarted)

    def _accept(self, rep: Report) -> Report:
        self.last = rep
        self.latest.append(rep.chainage_m)
        self.rejected_since_last = False
        self._pending = None
        h = self.history
        if not h or (rep.t_fix_ns - h[-1][0]) >= self.lim.history_step_s * NS:
            h.append((rep.t_fix_ns, rep.chainage_m))
        while h and rep.t_fix_ns - h[0][0] > self.lim.window_s * NS:
            del h[0]  # ≤ window / history_step entries
        return rep

    # -- jumps -------------------------------------------------------------
    def reach_m(self, dt_s: float) -> float:
        """How far from the last accepted fix the train can be after ``dt_s`` (noise included)."""
        lim = self.lim
        last = self.last
        v = lim.max_speed_mps if last is None else last.speed_hi_mps
        run = min(v * dt_s + 0.5 * lim.jump_accel_mps2 * dt_s * dt_s, lim.max_speed_mps * dt_s)
        return run + 2 * lim.noise_m

    def offer(self, t_fix_ns: int, chainage_m: float, speed_mps: float) -> Report | None:
        """Accept a fix (→ its report) or set it aside as a position jump (→ None)."""
        last = self.last
        if last is None:
            return self._accept(self._report(t_fix_ns, chainage_m, speed_mps))
        dt = (t_fix_ns - last.t_fix_ns) / NS
        if abs(chainage_m - last.chainage_m) <= self.reach_m(dt):
            return self._accept(self._report(t_fix_ns, chainage_m, speed_mps))
        pending, self._pending = self._pending, (t_fix_ns, chainage_m, speed_mps)
        if pending is not None:
            dt_p = (t_fix_ns - pending[0]) / NS
            if dt_p > 0 and abs(chainage_m - pending[1]) <= self.lim.max_speed_mps * dt_p + 2 * self.lim.noise_m:
                # Two set-aside fixes agree: start over from them, the speed unknown again.
                self.history.clear()
                self.latest.clear()
                self.jumps -= 1  # the earlier one was not a jump after all
                self.restarts += 1
                self._accept(self._report(pending[0], pending[1], pending[2], restarted=True))
                return self._accept(self._report(t_fix_ns, chainage_m, speed_mps, restarted=True))
        self.jumps += 1
        self.rejected_since_last = True
        return None

    # -- direction ---------------------------------------------------------
    def direction(self, medians_only: bool = False) -> int:
        """+1 / −1 from the accepted fixes; 0 without a clear movement.

        The median of the last three accepted fixes against the median of the three oldest
        in the window: one plausible-looking jump moves neither median, so it cannot
        reverse the train (a reversed direction would read an EOT still before the
        crossing as past it).  With fewer than three fixes: the first against the last,
        unless ``medians_only`` (then 0: too little to reverse a known direction on)."""
        old = [ch for _, ch in list(self.history)[:3]]
        new = list(self.latest)
        if len(old) < 3 or len(new) < 3:
            if medians_only or self.last is None or not self.history:
                return 0
            older, newer = self.history[0][1], self.last.chainage_m
        else:
            older, newer = statistics.median(old), statistics.median(new)
        if abs(newer - older) <= 2 * self.lim.noise_m:
            return 0
        return 1 if newer > older else -1
