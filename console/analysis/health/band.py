"""The analog band rule: each channel's analog receiver value against a band, given or learned."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from console.analysis.health.findings import Finding, Severity, where_text
from console.analysis.health.register_rows import register_rows
from console.analysis.timefmt import iso

if TYPE_CHECKING:
    import pandas as pd


@dataclass(frozen=True)
class BandSettings:
    """How a band is learned and judged (see :func:`analog_band_findings`)."""

    baseline_fraction: float = 0.25
    min_baseline_samples: int = 8
    mad_factor: float = 6.0
    min_halfwidth_fraction: float = 0.02
    sustained_samples: int = 6
    critical_fraction: float = 0.2


def learn_band(values: np.ndarray, settings: BandSettings = BandSettings()) -> tuple[float, float, int]:
    """A robust band from the first part of a channel's values: (low, high, samples used).

    The baseline is the first ``baseline_fraction`` of the values in time
    order (at least ``min_baseline_samples``; all of them when there are
    fewer); the band is its median ± max(``mad_factor`` × MAD,
    ``min_halfwidth_fraction`` × median).
    """
    n = len(values)
    used = (
        n
        if n <= settings.min_baseline_samples
        else max(settings.min_baseline_samples, math.ceil(settings.baseline_fraction * n))
    )
    base = values[:used]
    median = float(np.median(base))
    mad = float(np.median(np.abs(base - median)))
    half = max(settings.mad_factor * mad, settings.min_halfwidth_fraction * abs(median))
    return median - half, median + half, used


def analog_band_findings(
    records: pd.DataFrame,
    bands: Mapping[str, tuple[float, float]] | None = None,
    settings: BandSettings = BandSettings(),
) -> list[Finding]:
    """Each (counting head, channel)'s analog values against its band.

    Analog values are the ``analog_value`` records; both addresses (Adr 134
    and 136) count for the channel the record names.  The band is
    ``bands[head]`` when the layout sets one; otherwise it is learned from the
    log by :func:`learn_band`:

    * from the *first part* of the log (first quarter of the samples), not the
      whole log: a drift that lasts half the log would move a whole-log median
      with it and widen the MAD, and so hide itself.  The first part is the
      "as found" state the rest is compared with.  The price: a channel that
      is already out at the start is not caught without a layout band;
    * median ± 6 × MAD: the MAD ignores the excursions we are looking for,
      and 6 MAD (about 4 σ for Gaussian noise) keeps normal noise inside;
    * never narrower than ± 2 % of the median (± 48 counts at 2400): a quiet,
      quantised channel has a MAD of a count or two, and a band that narrow
      would flag harmless wobble.  The paper's excerpts (2416/2402 on one
      channel) and the healthy heads of ``ws4_health.log`` stay inside.

    Verdicts: no value out of band → INFO (the band is reported); a few
    excursions → WARNING; a sustained departure → CRITICAL, meaning the last
    ``sustained_samples`` (6) values are all out of band, or at least 20 % of
    all values are (and at least 6 of them).  ``time_ns`` is the first time a
    value left the band; ``value`` is the value furthest out, ``threshold``
    the band edge it crossed.
    """
    analog = register_rows(records, "analog_value")
    findings: list[Finding] = []
    for _, group in analog.groupby(["head", "channel"], sort=True):
        head, channel = str(group["head"].iloc[0]), int(group["channel"].iloc[0])
        values = group["value"].to_numpy()
        times = group["time_ns"].to_numpy()
        if bands is not None and head in bands:
            low, high = (float(x) for x in bands[head])
            if not low < high:
                raise ValueError(f"band for {head}: low {low:g} must be below high {high:g}")
            origin = "set in the layout"
        else:
            low, high, used = learn_band(values, settings)
            origin = f"learned from the first {used} values"
        findings.append(_judge_band(head, channel, values, times, low, high, origin, settings))
    return findings


def _judge_band(
    head: str,
    channel: int,
    values: np.ndarray,
    times: np.ndarray,
    low: float,
    high: float,
    origin: str,
    settings: BandSettings,
) -> Finding:
    where = where_text(head, channel)
    band = f"{low:.0f}–{high:.0f} counts ({origin})"  # the receiver's raw reading (Analogwert), no unit beyond
    below, above = values < low, values > high
    out = below | above
    n, n_out = len(values), int(out.sum())
    if n_out == 0:
        return Finding(
            Severity.INFO,
            "analog_band",
            head,
            channel,
            f"{where}: all {n} analog values within {band}, median {np.median(values):.0f} counts.",
        )
    distance = np.where(below, low - values, values - high)
    worst = int(np.argmax(distance))
    edge = low if below[worst] else high
    side = "below" if below[worst] else "above"
    first = int(np.argmax(out))
    k = settings.sustained_samples
    sustained = n_out >= k and bool(out[-k:].all())
    widespread = n_out >= k and n_out / n >= settings.critical_fraction
    if sustained or widespread:
        how = f"the last {k} values are all out of band" if sustained else f"{n_out} of {n} values are out of band"
        return Finding(
            Severity.CRITICAL,
            "analog_band",
            head,
            channel,
            f"{where}: analog value has drifted {side} its band {band}: {how} "
            f"({n_out} of {n}), latest {values[-1]:.0f}, furthest {values[worst]:.0f} counts, first out at "
            f"{iso(int(times[first]))}; inspect the sensor's mounting, cable and rail clearance and "
            "readjust or replace it before it stops detecting.",
            float(values[worst]),
            float(edge),
            int(times[first]),
        )
    return Finding(
        Severity.WARNING,
        "analog_band",
        head,
        channel,
        f"{where}: {n_out} of {n} analog values left the band {band}, furthest {values[worst]:.0f} "
        f"({side}), first at {iso(int(times[first]))}; watch this channel and check the sensor at the "
        "next visit.",
        float(values[worst]),
        float(edge),
        int(times[first]),
    )
