"""Condition forecasts: when will a daily health figure cross its threshold?

Each series is one daily figure of one counting head and channel (or one GNSS unit):

* ``analog_margin`` — the day's median analog value's distance inside the channel's band, in counts;
  worse downwards, threshold 0 (the band edge: half the day's values out, the health rule's
  sustained departure);
* ``disturbance_rate`` — the channel's 1-edge counter growth per hour that day; worse upwards,
  threshold the health rule's warning level (12/h);
* ``gnss_loss`` — the share of a unit's reports missing that day; worse upwards, threshold 25 %
  (at 25 % lost, four reports in a row — the crossing units' stale time at the usual report
  periods — go missing about once every 256 report windows: a warning held on and an alarm).

The trend is Sen's slope with its confidence interval (``scipy.stats.theilslopes``) over the last
``fit_days`` days of figures, each placed at its day's middle: robust to a day of odd readings, and
short enough that a wear which started a few weeks ago is not flattened by the healthy months
before it.  The crossing date is where that line meets the threshold; its interval, where the
lines of the slope's confidence bounds through the same pivot (the medians of the days and of the
figures) meet it.

Status, worst first:

* ``past`` — the latest figure is already beyond the threshold (whatever the trend says: a head
  past its threshold is never called healthy);
* ``due`` — the interval's early end falls within the horizon (doubt brings maintenance forward);
* ``watch`` — worsening, but not within the horizon;
* ``unknown`` — too few days to fit a trend (fewer than ``min_days``);
* ``ok`` — the figure is not worsening.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from console.analysis.health.disturbance import DISTURBANCE_WARN_PER_H
from console.analysis.timefmt import iso
from parsers.units import NS_PER_DAY

DISTURBANCE_LIMIT_PER_H = DISTURBANCE_WARN_PER_H
GNSS_LOSS_LIMIT = 0.25
ANALOG_MARGIN_LIMIT = 0.0
FIT_DAYS = 14
MIN_DAYS = 7
CONFIDENCE = 0.90
FAR_DAYS = 36_500.0
STATUSES = ("past", "due", "watch", "unknown", "ok")
FIGURES = {
    # figure: (threshold, worse upwards, unit)
    "analog_margin": (ANALOG_MARGIN_LIMIT, False, "counts"),
    "disturbance_rate": (DISTURBANCE_LIMIT_PER_H, True, "per hour"),
    "gnss_loss": (GNSS_LOSS_LIMIT, True, "share lost"),
}


@dataclass(frozen=True)
class Series:
    """One daily figure of one head and channel, or of one GNSS unit.  ``day`` is days since 1970-01-01."""

    figure: str
    target: str
    channel: int | None
    day: np.ndarray  # int64, one per figure, ascending
    value: np.ndarray  # float64
    threshold: float

    @property
    def rising(self) -> bool:
        """The figure gets worse upwards."""
        return FIGURES[self.figure][1]

    def beyond(self, value: float) -> bool:
        return value >= self.threshold if self.rising else value <= self.threshold


@dataclass(frozen=True)
class ForecastSettings:
    horizon_days: float = 30.0
    fit_days: int = FIT_DAYS
    min_days: int = MIN_DAYS
    confidence: float = CONFIDENCE


@dataclass(frozen=True)
class Forecast:
    """The forecast of one series.  Times in ns since the epoch (the logs' own clock, read as UTC)."""

    figure: str
    target: str
    channel: int | None
    status: str
    threshold: float
    days: int  # daily figures fitted
    last_ns: int  # the end of the series' last day with a figure
    last_value: float
    slope_per_day: float | None
    slope_low: float | None
    slope_high: float | None
    intercept: float | None  # the fitted line's value at day 0 (1970-01-01)
    crossing_ns: int | None
    earliest_ns: int | None
    latest_ns: int | None  # None with a crossing: the interval has no late end (the trend may stop)
    pivot_day: float | None = None  # the fitted lines pass through (median day, median figure)
    pivot_value: float | None = None
    # "Now": where the horizon starts and the days left count from, the end of the archive's last day (None: the
    # series' own, ``last_ns``).
    now_ns: int | None = None

    @property
    def from_ns(self) -> int:
        """Where the horizon starts and the days left count from."""
        return self.last_ns if self.now_ns is None else max(self.now_ns, self.last_ns)

    @property
    def due(self) -> bool:
        return self.status in ("past", "due")

    def to_dict(self) -> dict[str, Any]:
        def r(x: float | None, digits: int = 4) -> float | None:
            return None if x is None or not math.isfinite(x) else round(float(x), digits)

        return {
            "figure": self.figure,
            "target": self.target,
            "channel": self.channel,
            "status": self.status,
            "threshold": self.threshold,
            "unit": FIGURES[self.figure][2],
            "days": self.days,
            "last_day_end": iso(self.last_ns),
            "last_value": r(self.last_value),
            "slope_per_day": r(self.slope_per_day, 6),
            "slope_low": r(self.slope_low, 6),
            "slope_high": r(self.slope_high, 6),
            "crossing": iso(self.crossing_ns),
            "earliest": iso(self.earliest_ns),
            "latest": iso(self.latest_ns),
            "days_left": None if self.crossing_ns is None else r((self.crossing_ns - self.from_ns) / NS_PER_DAY, 2),
            "pivot_day": r(self.pivot_day),
            "pivot_value": r(self.pivot_value),
        }


def _days_ns(day: float) -> int:
    return round(day * NS_PER_DAY)


def _crossing(pivot_x: float, pivot_y: float, slope: float, threshold: float, rising: bool) -> float | None:
    """Day at which the line through the pivot with this slope meets the threshold, if it heads there."""
    worsening = slope > 0 if rising else slope < 0
    if not worsening:
        return None
    day = pivot_x + (threshold - pivot_y) / slope
    # A trend so slight it reaches the threshold only in centuries: no crossing to speak of.
    return day if math.isfinite(day) and abs(day - pivot_x) <= FAR_DAYS else None


def forecast(series: Series, settings: ForecastSettings = ForecastSettings(), now_ns: int | None = None) -> Forecast:
    """The series' trend and the date it crosses its threshold (see the module's doc).

    ``now_ns``: where the horizon starts (the end of the last day of the archive: a unit silent for a week
    counts from the same day as the others); default the end of the series' own last day."""
    day, value = series.day, series.value
    last_day = int(day[-1])
    last_ns = (last_day + 1) * NS_PER_DAY
    recent = day > last_day - settings.fit_days
    x = day[recent].astype(np.float64) + 0.5  # a day's figure stands for its middle
    y = value[recent]

    def made(status: str, fit: _Fit | None, crossing: int | None, early: int | None, late: int | None) -> Forecast:
        slope, low, high, px, py = fit if fit is not None else (None, None, None, None, None)
        return Forecast(
            series.figure,
            series.target,
            series.channel,
            status,
            series.threshold,
            int(recent.sum()),
            last_ns,
            float(value[-1]),
            slope,
            low,
            high,
            None if fit is None else py - slope * px,  # type: ignore[operator]
            crossing,
            early,
            late,
            px,
            py,
            now_ns,
        )

    if series.beyond(float(value[-1])):
        # Already past: the date is when this run of days beyond the threshold began.
        inside = np.flatnonzero(~np.array([series.beyond(float(v)) for v in value]))
        at = int(day[inside[-1] + 1] if len(inside) else day[0]) * NS_PER_DAY
        return made("past", _fit(x, y, settings) if len(x) >= 2 else None, at, at, at)
    if len(x) < min(settings.min_days, settings.fit_days):
        return made("unknown", None, None, None, None)
    fit = _fit(x, y, settings)
    slope, low, high, px, py = fit
    rising = series.rising
    point = _crossing(px, py, slope, series.threshold, rising)
    # The steepest worsening bound gives the earliest date; the mildest, the latest (none if it may not worsen).
    steep, mild = (high, low) if rising else (low, high)
    early = _crossing(px, py, steep, series.threshold, rising)
    late = _crossing(px, py, mild, series.threshold, rising)
    horizon_ns = (last_ns if now_ns is None else max(now_ns, last_ns)) + _days_ns(settings.horizon_days)
    early_ns = None if early is None else _days_ns(early)
    if early_ns is not None and early_ns <= horizon_ns:
        status = "due"
    elif point is not None:
        status = "watch"
    else:
        status = "ok"
    return made(
        status,
        fit,
        None if point is None else _days_ns(point),
        early_ns,
        None if late is None or point is None else _days_ns(late),
    )


_Fit = tuple[float, float, float, float, float]


def _fit(x: np.ndarray, y: np.ndarray, settings: ForecastSettings) -> _Fit:
    """Sen's slope, its confidence bounds, and the pivot (median day, median figure) the line passes."""
    from scipy.stats import theilslopes

    res = theilslopes(y, x, alpha=settings.confidence)
    return float(res[0]), float(res[2]), float(res[3]), float(np.median(x)), float(np.median(y))


def forecasts(
    series: Iterable[Series], settings: ForecastSettings = ForecastSettings(), now_ns: int | None = None
) -> list[Forecast]:
    """Every series' forecast: the due ones first by date, then the others by target.

    ``now_ns``: where every horizon starts, the end of the archive's last day (default: of the series' last day,
    when they are all the archive's; a head alone is given the archive's, :func:`last_day_end`)."""
    from console.analysis.health.findings import natural_order_key

    given = [s for s in series if len(s.day)]
    if now_ns is None:
        now_ns = last_day_end(given)
    out = [forecast(s, settings, now_ns) for s in given]
    far = 2**62

    def key(f: Forecast) -> tuple[Any, ...]:
        return (
            0 if f.due else 1,
            _by_date(f)[0] if f.due else far,
            STATUSES.index(f.status),
            natural_order_key(f.target),
            -1 if f.channel is None else f.channel,
            f.figure,
        )

    return sorted(out, key=key)


def last_day_end(series: Iterable[Series]) -> int | None:
    """The end of the last day any of the series has a figure for (None: none has)."""
    days = [int(s.day[-1]) for s in series if len(s.day)]
    return (max(days) + 1) * NS_PER_DAY if days else None


def due_list(items: Iterable[Forecast]) -> list[Forecast]:
    """The heads and units due for maintenance within the horizon (or past), by date: earliest first."""
    due = [f for f in items if f.due]
    return sorted(due, key=_by_date)


def _by_date(f: Forecast) -> tuple[int, int, str, str]:
    """The predicted date (else the interval's early end), then the early end."""
    when = f.crossing_ns if f.crossing_ns is not None else f.earliest_ns
    return (when if when is not None else 0, f.earliest_ns or 0, f.target, f.figure)
