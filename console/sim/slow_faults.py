"""Slow faults: counting heads and GNSS units that wear over days, and the health registers that show it.

Faults take the simulator's ``KIND:TARGET:START[:END[:CH[:RATE]]]`` form:

* ``analog_drift:HEAD`` — the channel's analog receiver value (Analogwert, Adr 134/136) falls by RATE
  counts a day (default 3: from the middle of the ±2 % band the health rule learns around 2400, ±48
  counts, to its edge in 16 days);
* ``disturbance_growth:HEAD`` — the channel's 1-edge counter (disturbances) rate rises by RATE per hour
  each day (default 0.6: from a healthy 1.8/h to the health rule's warning level, 12/h, in 17 days);
* ``gnss_decay:UNIT`` — the unit (``T3-eot``, as its files and fixes name it) loses a share of its reports
  growing by RATE a day (default 0.015: to the forecast's limit, 25 % lost, in 17 days).

At END the fault is repaired: the figure is healthy again.

:class:`HeadHealth` writes every head's health registers every ``period_s`` (a *round*): per channel the
1-edge counter (Adr 088) and the two analog values (Adr 134, 136).  A round's values are drawn from a
generator seeded by the run's seed and the round's number, so a run gives the same registers whether it
is stepped with its trains or run for its health alone (``simulate --health-only``), in steps of any size.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from console.analysis.health.band import BandSettings
from console.analysis.health.forecast import DISTURBANCE_LIMIT_PER_H, GNSS_LOSS_LIMIT
from console.analysis.timefmt import iso
from console.layout import Layout
from console.sim.faults import SLOW_FAULT_KINDS, Fault
from parsers.units import NS

DEFAULT_RATES = {"analog_drift": 3.0, "disturbance_growth": 0.6, "gnss_decay": 0.015}
RATE_UNITS = {"analog_drift": "counts/day", "disturbance_growth": "per hour, each day", "gnss_decay": "share/day"}
DAY_S = 86_400.0
HEALTH_SALT = 27  # the health registers draw from their own streams: a run without them is unchanged
# (address, label as a device writes it); the 1-edge counter first, then the two analog values.
REGISTERS = (("088", "Zähler 1-Fl"), ("134", "Analogwer"), ("136", "Analogwer"))
HEAD_STAGGER_NS = 10_000_000  # heads write their round 10 ms apart, a register 1 ms apart
TRUTH_HORIZON_DAYS = 400.0  # a crossing later than this after the run's end is "never"


@dataclass(frozen=True)
class HealthSettings:
    """The healthy state of a head and how much it wanders."""

    period_s: float = 900.0
    analog_level: float = 2400.0  # about what the paper's excerpts show (2416 / 2402)
    analog_spread: float = 15.0  # heads differ: the level of each channel, normal around analog_level
    address_offset: float = 7.0  # Adr 134 reads this much above the level, Adr 136 below (2416 / 2402)
    reading_noise: int = 4  # each reading: ± this many counts, uniform
    day_sigma: float = 2.0  # each day the level wanders this much (weather, ballast), normal
    disturbance_per_h: float = 1.8  # a healthy channel's 1-edge rate (passing metal, lightning)


@dataclass
class HealthRows:
    """One batch of health records, columns: time, head (index), channel (1, 2), register (index), value."""

    t_ns: np.ndarray
    head: np.ndarray
    channel: np.ndarray
    register: np.ndarray
    value: np.ndarray

    def __len__(self) -> int:
        return len(self.t_ns)

    @staticmethod
    def concat(parts: Sequence[HealthRows]) -> HealthRows:
        if not parts:
            z = np.zeros(0, np.int64)
            return HealthRows(z, z, z, z, z)
        return HealthRows(*(np.concatenate([getattr(p, k) for p in parts]) for k in HealthRows.__annotations__))


@dataclass(frozen=True)
class _Ramps:
    """The faults of one kind on heads, as arrays: head index, channel index (0, 1), start, end (s), rate."""

    head: np.ndarray
    channel: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    rate: np.ndarray

    @staticmethod
    def of(faults: Sequence[Fault], kind: str, index: dict[str, int]) -> _Ramps:
        fs = [f for f in faults if f.kind == kind and f.target in index]
        return _Ramps(
            np.array([index[f.target] for f in fs], np.int64),
            np.array([f.channel - 1 for f in fs], np.int64),
            np.array([f.start_s for f in fs], np.float64),
            np.array([f.end_s for f in fs], np.float64),
            np.array([fault_rate(f) for f in fs], np.float64),
        )

    def at(self, t_s: float, shape: tuple[int, int]) -> np.ndarray:
        """The summed ramps at ``t_s``, per (head, channel)."""
        out = np.zeros(shape)
        if len(self.head):
            active = (self.start_s <= t_s) & (t_s < self.end_s)
            np.add.at(out, (self.head, self.channel), np.where(active, self.rate * (t_s - self.start_s) / DAY_S, 0.0))
        return out


def fault_rate(f: Fault) -> float:
    """The fault's rate, or its kind's default."""
    return f.rate if f.rate is not None else DEFAULT_RATES.get(f.kind, 0.0)


class HeadHealth:
    """Every head's health registers, round after round (see the module's doc)."""

    def __init__(self, layout: Layout, faults: Sequence[Fault], seed: int, settings: HealthSettings) -> None:
        self.layout = layout
        self.s = settings
        self.seed = seed
        self.heads = [h.id for h in layout.heads]
        self.index = {h: i for i, h in enumerate(self.heads)}
        n = len(self.heads)
        rng = np.random.default_rng([seed, HEALTH_SALT])
        learned = np.round(settings.analog_level + rng.normal(0.0, settings.analog_spread, (n, 2)))
        half = BandSettings().min_halfwidth_fraction * np.abs(learned)
        self.base = learned.copy()
        self.band_low, self.band_high = learned - half, learned + half
        for i, h in enumerate(layout.heads):
            if h.analog_band is not None:  # the layout's band: the head was set up in its middle
                lo, hi = h.analog_band
                self.base[i] = (lo + hi) / 2
                self.band_low[i], self.band_high[i] = lo, hi
        self.drift = _Ramps.of(faults, "analog_drift", self.index)
        self.growth = _Ramps.of(faults, "disturbance_growth", self.index)
        self.counters = np.zeros((n, 2), np.int64)
        self.next_round = 0
        self._wander: dict[int, np.ndarray] = {}

    @property
    def next_s(self) -> float:
        """When the next round is written (s into the run)."""
        return self.next_round * self.s.period_s

    def level(self, t_s: float) -> np.ndarray:
        """Each channel's analog level now, without the readings' noise."""
        day = int(t_s // DAY_S)
        wander = self._wander.get(day)
        if wander is None:
            self._wander = {
                day: np.random.default_rng([self.seed, HEALTH_SALT, 2, day]).normal(
                    0.0, self.s.day_sigma, self.base.shape
                )
            }
            wander = self._wander[day]
        return self.base + wander - self.drift.at(t_s, self.base.shape)

    def disturbance_per_h(self, t_s: float) -> np.ndarray:
        return self.s.disturbance_per_h + self.growth.at(t_s, self.base.shape)

    def until(self, t_s: float, start_ns: int) -> HealthRows:
        """The rounds written before ``t_s`` (s into the run) not handed out yet."""
        parts = []
        while self.next_s < t_s:
            parts.append(self._round(self.next_round, start_ns))
            self.next_round += 1
        return HealthRows.concat(parts)

    def _round(self, k: int, start_ns: int) -> HealthRows:
        t = k * self.s.period_s
        n = len(self.heads)
        rng = np.random.default_rng([self.seed, HEALTH_SALT, 1, k])
        self.counters += rng.poisson(self.disturbance_per_h(t) * self.s.period_s / 3600.0)
        noise = rng.integers(-self.s.reading_noise, self.s.reading_noise + 1, (n, 2, 2))
        offsets = np.array([self.s.address_offset, -self.s.address_offset])
        analog = np.rint(self.level(t)[:, :, None] + offsets + noise).astype(np.int64)
        # Per head and channel: counter, analog 134, analog 136 → (n, 2, 3) values.
        values = np.concatenate([self.counters[:, :, None], analog], axis=2)
        head = np.repeat(np.arange(n), 6)
        channel = np.tile(np.repeat([1, 2], 3), n)
        register = np.tile([0, 1, 2], 2 * n)
        t_ns = start_ns + round(t * NS) + head * HEAD_STAGGER_NS + np.tile(np.arange(6), n) * 1_000_000
        return HealthRows(t_ns.astype(np.int64), head, channel, register, values.reshape(-1))


def unit_loss(faults: Sequence[Fault], unit: str, t_s: float) -> float:
    """The share of its reports a GNSS unit loses at ``t_s`` (0 without a ``gnss_decay`` fault)."""
    p = sum(
        fault_rate(f) * (t_s - f.start_s) / DAY_S
        for f in faults
        if f.kind == "gnss_decay" and f.target == unit and f.active(t_s)
    )
    return min(1.0, p)


def _ramp_crossing(ramps: Sequence[Fault], base: float, limit: float, horizon_s: float) -> float | None:
    """First time a figure ``base`` + its ramps (each ``rate`` per day from its start to its end) reaches ``limit``.

    Between two of the ramps' starts and ends the figure is linear: solved there, piece by piece.
    """
    cuts = sorted({f.start_s for f in ramps} | {f.end_s for f in ramps if f.end_s < horizon_s} | {horizon_s})
    for a, b in itertools.pairwise(cuts):
        on = [f for f in ramps if f.start_s <= a < f.end_s]
        value = base + sum(fault_rate(f) * (a - f.start_s) / DAY_S for f in on)
        slope = sum(fault_rate(f) for f in on) / DAY_S
        if value >= limit:
            return a
        if slope > 0 and a + (limit - value) / slope < b:
            return a + (limit - value) / slope
    return None


def threshold_crossings(
    health: HeadHealth | None, faults: Sequence[Fault], start_ns: int, end_s: float
) -> list[dict[str, Any]]:
    """Per head and channel, or unit, with a slow fault: when each figure crosses its threshold.

    The figures and thresholds are the forecast's (``console.analysis.health.forecast``): ``analog_margin`` (the
    analog level's distance inside the band; threshold 0, the band edge), ``disturbance_rate`` (1-edge
    counts per hour; the health rule's warning level), ``gnss_loss`` (share of a unit's reports lost).
    Times follow the faults' trends, without the noise; a crossing after the run's end is given too
    (what a forecast should predict), ``null`` when the fault is repaired first or none comes within
    400 days.
    """
    out: list[dict[str, Any]] = []
    horizon = end_s + TRUTH_HORIZON_DAYS * DAY_S
    targets = sorted({(f.kind, f.target, f.channel) for f in faults if f.kind in SLOW_FAULT_KINDS})
    for kind, target, channel in targets:
        mine = [
            f
            for f in faults
            if f.kind == kind and f.target == target and (kind == "gnss_decay" or f.channel == channel)
        ]
        row: dict[str, Any] = {"target": target, "channel": None if kind == "gnss_decay" else channel}
        if kind == "analog_drift":
            if health is None or target not in health.index:
                continue
            h, c = health.index[target], channel - 1
            base, low = float(health.base[h, c]), float(health.band_low[h, c])
            t_cross = _ramp_crossing(mine, 0.0, base - low, horizon)
            row |= {
                "figure": "analog_margin",
                "threshold": 0.0,
                "band": [low, float(health.band_high[h, c])],
                "level": base,
            }
        elif kind == "disturbance_growth":
            base_rate = health.s.disturbance_per_h if health is not None else HealthSettings().disturbance_per_h
            t_cross = _ramp_crossing(mine, base_rate, DISTURBANCE_LIMIT_PER_H, horizon)
            row |= {"figure": "disturbance_rate", "threshold": DISTURBANCE_LIMIT_PER_H}
        else:
            t_cross = _ramp_crossing(mine, 0.0, GNSS_LOSS_LIMIT, horizon)
            row |= {"figure": "gnss_loss", "threshold": GNSS_LOSS_LIMIT}
        row["kind"] = kind
        row["rate"] = fault_rate(mine[0])
        row["rate_unit"] = RATE_UNITS[kind]
        row["time"] = None if t_cross is None else iso(start_ns + round(round(t_cross, 3) * NS))
        row["within_run"] = t_cross is not None and t_cross <= end_s
        out.append(row)
    return out


# The largest rate each kind takes: far past any wear a forecast could follow (an analog value of some 2400
# counts gone in a quarter of a day; 10,000 more disturbances an hour each day), and small enough that ten
# years of it stay numbers the registers and the generator can hold.
MAX_RATES = {"analog_drift": 10_000.0, "disturbance_growth": 10_000.0, "gnss_decay": 1.0}


def check_rate(kind: str, rate: float) -> None:
    """A rate the kind can use (ValueError otherwise)."""
    top = MAX_RATES.get(kind, 1.0)
    if not math.isfinite(rate) or rate <= 0 or rate > top:
        raise ValueError(f"{kind}: rate must be above 0 and at most {top:g} {RATE_UNITS.get(kind, '')}".rstrip())
