"""Sensor and channel health: findings a maintainer can act on.

Four rules, each a pure function over data the parsers already produced:

* :func:`analog_band_findings`: each channel's analog receiver value
  (``Analogwert``, Adr 134/136) against a band, given by the layout or
  learned from the log;
* :func:`voltage_margin_findings`: seed 000's rule, in-phase minus
  anti-phase receiver voltage must exceed 150 mV for reliable counting;
* :func:`disturbance_rate_findings`: how fast each channel's 1-edge counter
  (``Zähler 1-Flanken``, disturbances) grows, per hour;
* :func:`channel_fault_findings`: what the detection-event stream says about
  faulty channels and single-channel damping.

:func:`health_report` runs them all and sorts the findings critical first.
Everything here is vectorized per counting head and channel: the only Python
loops run once per head/channel (or per finding), never once per record.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any

import numpy as np

from console.analysis.events.detection import DetectionEvent, EventKind, events_to_frame
from console.analysis.timefmt import iso
from parsers.units import NS as _NS_PER_S

if TYPE_CHECKING:
    import pandas as pd

_NS_PER_H = 3600 * _NS_PER_S
_SEVERITY_ORDER = ("info", "warning", "critical")
DISTURBANCE_WARN_PER_H = 12.0  # the disturbance rule's warning level (see disturbance_rate_findings)


class Severity(StrEnum):
    """How urgent a finding is; ordered ``INFO < WARNING < CRITICAL``.

    Comparisons use the rank, not the text, so ``--fail-on warning`` can be
    written as ``finding.severity >= Severity.WARNING``.
    """

    INFO = "info"
    WARNING = "warning"
    CRITICAL = "critical"

    @property
    def rank(self) -> int:
        """0 for INFO, 1 for WARNING, 2 for CRITICAL."""
        return _SEVERITY_ORDER.index(self.value)

    @classmethod
    def parse(cls, text: str) -> Severity:
        """``"Warning"`` → ``Severity.WARNING`` (case-insensitive); ValueError otherwise."""
        try:
            return cls(text.strip().lower())
        except ValueError:
            raise ValueError(f"severity: expected one of {', '.join(_SEVERITY_ORDER)}, found '{text}'") from None

    def __lt__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank < other.rank

    def __le__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank <= other.rank

    def __gt__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank > other.rank

    def __ge__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank >= other.rank


@dataclass(frozen=True)
class Finding:
    """One health verdict about a counting head (or sensor) and channel."""

    severity: Severity
    rule: str  # analog_band | voltage_margin | disturbance_rate | faulty_channel | single_channel
    counting_head: str | None  # the head (or, for voltage_margin, the sensor position)
    channel: int | None  # 1 = Sys1, 2 = Sys2; None = the whole head / sensor
    message: str  # one sentence with the numbers and what to do
    value: float | None = None  # the measured quantity the rule judged
    threshold: float | None = None  # the limit it was judged against
    time_ns: int | None = None  # when the problem was first seen (ns since the epoch, naive local time)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (no NaN: missing numbers are None)."""
        return {
            "severity": str(self.severity),
            "rule": self.rule,
            "counting_head": self.counting_head,
            "channel": self.channel,
            "message": self.message,
            "value": _finite(self.value),
            "threshold": _finite(self.threshold),
            "time_ns": self.time_ns,
            "time": iso(self.time_ns),
        }


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def channel_name(channel: int | None) -> str:
    """1 → ``Sys1``, 2 → ``Sys2``, None → ``all channels``."""
    if channel is None:
        return "all channels"
    return f"Sys{channel}" if channel in (1, 2) else f"ch {channel}"


def _where(head: str | None, channel: int | None) -> str:
    return f"{head} {channel_name(channel)}" if channel is not None else f"{head}"


def _time_ns(times: pd.Series) -> np.ndarray:
    return times.to_numpy(dtype="datetime64[ns]").view(np.int64)


def _picked(records: pd.DataFrame, canonical: str, extra: tuple[str, ...] = ()) -> pd.DataFrame:
    """Records of one register, with a plain-string head, in the table's (read) order."""
    import pandas as pd  # deferred: the report path reads its inputs before pandas is needed (memory)

    picked = records.loc[records["label_canonical"] == canonical, ["time", "counting_head", "channel", "value", *extra]]
    return pd.DataFrame(
        {
            "time_ns": _time_ns(picked["time"]),
            "head": picked["counting_head"].astype(str).to_numpy(),
            "channel": picked["channel"].to_numpy(dtype=np.int64),
            "value": picked["value"].to_numpy(dtype=np.float64),
            **{c: picked[c].to_numpy() for c in extra},
        }
    )


def _rows(records: pd.DataFrame, canonical: str, extra: tuple[str, ...] = ()) -> pd.DataFrame:
    """Records of one register, with a plain-string head, sorted by head, channel, time."""
    out = _picked(records, canonical, extra)
    return out.sort_values(["head", "channel", *extra, "time_ns"], kind="stable").reset_index(drop=True)


# --------------------------------------------------------------------------- analog band


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
    analog = _rows(records, "analog_value")
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
    where = _where(head, channel)
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


# --------------------------------------------------------------------------- voltage margin


def voltage_margin_findings(
    table: pd.DataFrame, threshold_mv: float = 150.0, watch_fraction: float = 0.25
) -> list[Finding]:
    """Seed 000's rule per sensor: margin = in-phase − anti-phase voltage (mV).

    The anti-phase voltage is negative when the receiver reverses phase under
    a wheel, so 346 / −152 mV gives a margin of 498 mV.  Counting is reliable
    when the margin *exceeds* ``threshold_mv`` (150 mV, seed 000 §3).

    * margin > threshold × (1 + ``watch_fraction``) → INFO, reliable;
    * threshold < margin ≤ threshold × 1.25 → WARNING: reliable today, but
      within 25 % of the limit (≤ 187.5 mV).  25 % (37.5 mV of headroom) is
      our choice, not the paper's: the voltages depend on the installation
      (rail type, sleepers, coil angle and position; seed 000 §3), and a
      margin this close needs only a small change in one of them to fall
      below the limit.  On Table 2 it singles out sensor 8 (186 mV) alone;
      the next lowest margin is 259 mV;
    * margin ≤ threshold → CRITICAL: counting is not reliable; so is an
      anti-phase voltage ≥ 0 whatever the margin, since without a phase
      reversal the "occupied" signal B never rises (seed 000 §2.3).

    ``table`` has columns ``sensor``, ``in_phase_mv``, ``anti_phase_mv``
    (:func:`parsers.voltages.read_voltages`).  ``counting_head`` of a finding
    is the sensor as written in the table; ``channel`` is None.
    """
    missing = [c for c in ("sensor", "in_phase_mv", "anti_phase_mv") if c not in table.columns]
    if missing:
        raise ValueError(f"voltage table: missing column(s) {', '.join(missing)}")
    in_mv = table["in_phase_mv"].to_numpy(dtype=np.float64)
    anti_mv = table["anti_phase_mv"].to_numpy(dtype=np.float64)
    margin = in_mv - anti_mv
    watch = threshold_mv * (1.0 + watch_fraction)
    # No phase reversal (anti-phase ≥ 0) means signal B never rises: no axle
    # can be confirmed, whatever the margin says.
    severity = np.where((margin <= threshold_mv) | (anti_mv >= 0), 2, np.where(margin <= watch, 1, 0))
    findings = []
    for sensor, i_mv, a_mv, m_mv, sev in zip(
        table["sensor"].astype(str), in_mv, anti_mv, margin, severity, strict=True
    ):
        volts = f"in-phase {i_mv:g} mV, anti-phase {a_mv:g} mV"
        no_reversal = (
            " The anti-phase voltage is not negative: the receiver does not reverse phase under a wheel."
            if a_mv >= 0
            else ""
        )
        if sev == 0:
            text = f"sensor {sensor}: reliable, margin {m_mv:g} mV > {threshold_mv:g} mV ({volts})."
        elif sev == 1:
            text = (
                f"sensor {sensor}: reliable but close to the limit, margin {m_mv:g} mV is within "
                f"{watch_fraction:.0%} above {threshold_mv:g} mV ({volts}); re-measure at the next visit and "
                "check the transmitter angle and the coil's position on the rail."
            )
        else:
            why = f"margin {m_mv:g} mV ≤ {threshold_mv:g} mV" if m_mv <= threshold_mv else f"margin {m_mv:g} mV"
            text = (
                f"sensor {sensor}: NOT reliable, {why} ({volts}); "
                f"readjust or replace the sensor before relying on its counts.{no_reversal}"
            )
        findings.append(
            Finding(
                Severity(_SEVERITY_ORDER[int(sev)]),
                "voltage_margin",
                sensor,
                None,
                text,
                float(m_mv),
                float(threshold_mv),
            )
        )
    return findings


# --------------------------------------------------------------------------- disturbance rate


def disturbance_rate_findings(
    records: pd.DataFrame,
    warn_per_hour: float = DISTURBANCE_WARN_PER_H,
    critical_per_hour: float = 60.0,
    *,
    window_s: float = 3600.0,
    min_span_s: float = 600.0,
) -> list[Finding]:
    """How fast each channel's 1-edge counter (disturbances) grows, per hour.

    Growth is taken per register series (head, channel, address): the rise
    from one reading to the next.  A *decrease* is a counter reset (device
    restart, wrap at the register's width), not negative growth: the growth
    across it is the new reading (the counter restarted from 0).  The growth
    of all addresses of a channel is summed.  (Where a device writes the
    counter as a high and a low word, e.g. Adr 086/088, a carry into the high
    word is seen as a low-word reset and undercounted: the rate is a lower
    bound then.)

    The rate is judged over trailing windows of ``window_s`` (1 h): at each
    reading at least an hour after the first, growth since the last reading
    an hour or more earlier, divided by that time.  A log shorter than the
    window gives one rate over its whole span, if it spans ``min_span_s``
    (10 min) at least; shorter logs give no finding.

    Thresholds (per channel): above ``warn_per_hour`` (12/h, one disturbance
    every 5 minutes on average) → WARNING; above ``critical_per_hour``
    (60/h, one a minute) → CRITICAL; otherwise INFO.  A healthy channel sees
    a few an hour (passing metal, lightning, track work).  Caution: the
    paper's excerpt (seed 003) shows ``Zähler 1-Fl`` at 72 beside a sum
    counter of 18, i.e. 4 × 18: if a device counts every edge of every wheel
    there, the rate follows the traffic and the thresholds must be raised
    with it (or the 4-edge growth subtracted).  ``time_ns`` is
    the first reading at which the windowed rate crossed the warning level.
    """
    if not 0 < warn_per_hour <= critical_per_hour:
        raise ValueError("disturbance thresholds: need 0 < warn_per_hour <= critical_per_hour")
    counters = _counter_readings(records)
    if counters.empty:
        return []
    # One vectorized pass over all series: growth since the previous reading.
    series = counters.groupby(["head", "channel", "address"], sort=False)
    step = series["value"].diff()
    reset = step < 0
    counters["growth"] = np.where(reset, counters["value"], step.fillna(0.0))
    counters["reset"] = reset
    findings = []
    for _, group in counters.groupby(["head", "channel"], sort=True):
        group = group.sort_values("time_ns", kind="stable")
        f = _judge_rate(
            str(group["head"].iloc[0]),
            int(group["channel"].iloc[0]),
            group["time_ns"].to_numpy(),
            group["growth"].to_numpy(),
            int(group["reset"].sum()),
            warn_per_hour,
            critical_per_hour,
            window_s,
            min_span_s,
        )
        if f is not None:
            findings.append(f)
    return findings


def _counter_readings(records: pd.DataFrame) -> pd.DataFrame:
    """The 1-edge counter readings per series (head, channel, address) in the order the device wrote them.

    Not by time: a board's clock that goes back (a reboot, a DST change of the log's local time) would
    interleave two stretches of readings, each rise and fall a reset and a burst of growth.  Files are
    taken in the order of their first readings (given in any order, they read as one log), lines in
    file order; a reading repeated by an overlapping export (same series, time and value) is read once.
    """
    import pandas as pd

    has_file = "file" in records.columns
    out = _picked(records, "counter_1_edge", ("address", "file") if has_file else ("address",))
    out["file"] = pd.factorize(out["file"])[0] if has_file else 0
    out["seq"] = np.arange(len(out))  # the table's rows are in read order
    out = out.drop_duplicates(["head", "channel", "address", "time_ns", "value"])
    out["file_start"] = out.groupby("file")["time_ns"].transform("min")
    keys = ["head", "channel", "address", "file_start", "file", "seq"]
    return out.sort_values(keys, kind="stable").reset_index(drop=True)


def _judge_rate(
    head: str,
    channel: int,
    times: np.ndarray,
    growth: np.ndarray,
    resets: int,
    warn: float,
    critical: float,
    window_s: float,
    min_span_s: float,
) -> Finding | None:
    span_ns = int(times[-1] - times[0])
    if span_ns <= 0 or span_ns < min_span_s * _NS_PER_S:
        return None
    total = np.cumsum(growth)
    window_ns = int(window_s * _NS_PER_S)
    if span_ns < window_ns:
        at = np.array([len(times) - 1])
        since = np.array([0])
    else:
        at = np.flatnonzero(times - times[0] >= window_ns)
        since = np.searchsorted(times, times[at] - window_ns, side="right") - 1
    rates = (total[at] - total[since]) / ((times[at] - times[since]) / _NS_PER_H)
    peak_i = int(np.argmax(rates))
    peak = float(rates[peak_i])
    overall = float(total[-1]) / (span_ns / _NS_PER_H)
    where = _where(head, channel)
    window = f"{window_s / 3600:g} h windows" if span_ns >= window_ns else f"{span_ns / _NS_PER_H:.2f} h"
    reset_note = f", {resets} counter reset{'s' if resets != 1 else ''} seen" if resets else ""
    plural = "s" if total[-1] != 1 else ""
    summary = (
        f"{total[-1]:.0f} disturbance{plural} in {span_ns / _NS_PER_H:.1f} h ({overall:.1f}/h overall{reset_note})"
    )
    if peak <= warn:
        return Finding(
            Severity.INFO,
            "disturbance_rate",
            head,
            channel,
            f"{where}: 1-edge counter grows at most {peak:.1f}/h over {window}, within {warn:g}/h; {summary}.",
            peak,
            warn,
        )
    severity, limit = (Severity.CRITICAL, critical) if peak > critical else (Severity.WARNING, warn)
    first = int(times[at[int(np.argmax(rates > warn))]])
    if severity is Severity.CRITICAL:
        summary += f"; above {critical:g}/h from {iso(int(times[at[int(np.argmax(rates > critical))]]))}"
    action = (
        "inspect the head now: a loose or damaged sensor, a cable fault or metal near the rail"
        if severity is Severity.CRITICAL
        else "check the head at the next visit for metal near the rail or a loose sensor"
    )
    return Finding(
        severity,
        "disturbance_rate",
        head,
        channel,
        f"{where}: 1-edge counter (disturbances) grows up to {peak:.0f}/h over {window}, above "
        f"{limit:g}/h, first above {warn:g}/h at {iso(first)}; {summary}; {action}.",
        peak,
        float(limit),
        first,
    )


# --------------------------------------------------------------------------- channel events

SINGLE_CHANNEL_REPEATS = 3


def channel_fault_findings(
    events: Iterable[DetectionEvent], single_channel_repeats: int = SINGLE_CHANNEL_REPEATS
) -> list[Finding]:
    """Faulty channels and repeated single-channel damping, per head/channel.

    * Every (head, channel) with CHANNEL_FAULT events → CRITICAL, with the
      first time and the count; a later CHANNEL_OK is mentioned but does not
      lower the verdict (an intermittent fault is still a fault).
    * SINGLE_CHANNEL events (one system damped, the other not): one is what a
      maintenance trolley or a dropped tool does; ``single_channel_repeats``
      (3) or more on the same head and channel in one log is a pattern, the
      sign of a channel that misses wheels or sees ghosts → WARNING.  Fewer
      → INFO.
    """
    kinds = (str(EventKind.CHANNEL_FAULT), str(EventKind.CHANNEL_OK), str(EventKind.SINGLE_CHANNEL))
    # Only these kinds, picked before the table is made (few: a few per fault; none: no table, no pandas).
    picked = [e for e in events if str(e.kind) in kinds]
    if not picked:
        return []
    frame = events_to_frame(picked)
    # A whole-head event has no channel: key it as -1 so it groups like any other.
    frame = frame.assign(channel_key=frame["channel"].fillna(-1).astype("int64"))
    stats = (
        frame.groupby(["head", "channel_key", "kind"], sort=True)["time_ns"]
        .agg(first="min", last="max", n="count")
        .reset_index()
    )
    table: dict[tuple[str, int, str], tuple[int, int, int]] = {
        (str(h), int(c), str(k)): (int(a), int(b), int(n))
        for h, c, k, a, b, n in zip(
            stats["head"].tolist(),
            stats["channel_key"].tolist(),
            stats["kind"].tolist(),
            stats["first"].tolist(),
            stats["last"].tolist(),
            stats["n"].tolist(),
            strict=True,
        )
    }
    findings = []
    for (head, key, kind), (first, last, count) in table.items():
        channel = None if key < 0 else key
        times = f"{count} time{'s' if count != 1 else ''}"
        if kind == EventKind.CHANNEL_FAULT:
            ok = table.get((head, key, str(EventKind.CHANNEL_OK)))
            cleared = (
                f"; it reported OK again at {iso(ok[1])}, so the fault may be intermittent"
                if ok is not None and ok[1] > last
                else ""
            )
            where = _where(head, channel) if channel is not None else f"{head} (whole head)"
            findings.append(
                Finding(
                    Severity.CRITICAL,
                    "faulty_channel",
                    head,
                    channel,
                    f"{where}: channel fault reported {times}, first at {iso(first)}, last at {iso(last)}"
                    f"{cleared}; the head cannot count safely: repair the channel and reset the section only "
                    "after it is confirmed clear.",
                    float(count),
                    1.0,
                    first,
                )
            )
        elif kind == EventKind.SINGLE_CHANNEL:
            where = _where(head, channel)
            if count >= single_channel_repeats:
                severity = Severity.WARNING
                text = (
                    f"{where}: damped alone {times} (first at {iso(first)}, last at {iso(last)}); "
                    f"{single_channel_repeats} or more is a pattern, not a trolley: check this channel's sensor "
                    "and its partner for missed or ghost detections."
                )
            else:
                severity = Severity.INFO
                text = f"{where}: damped alone {times}, first at {iso(first)}: likely a trolley or a metal object."
            findings.append(
                Finding(
                    severity,
                    "single_channel",
                    head,
                    channel,
                    text,
                    float(count),
                    float(single_channel_repeats),
                    first,
                )
            )
    return findings


# --------------------------------------------------------------------------- report

_NUMBER_RE = re.compile(r"(\d+)")


def natural_order_key(text: str | None) -> tuple[int, list[str | int]]:
    """``WS10`` after ``WS9``, sensor ``10`` after ``2``; None last."""
    if text is None:
        return (1, [])
    parts: list[str | int] = [int(p) if i % 2 else p.casefold() for i, p in enumerate(_NUMBER_RE.split(text))]
    return (0, parts)


def sort_findings(findings: Iterable[Finding]) -> list[Finding]:
    """Critical first, then by head (natural order), channel, rule and time."""
    return sorted(
        findings,
        key=lambda f: (
            -f.severity.rank,
            natural_order_key(f.counting_head),
            (1, 0) if f.channel is None else (0, f.channel),
            f.rule,
            -1 if f.time_ns is None else f.time_ns,
        ),
    )


def health_report(
    records: pd.DataFrame | None,
    *,
    bands: Mapping[str, tuple[float, float]] | None = None,
    events: Iterable[DetectionEvent] = (),
    voltages: pd.DataFrame | None = None,
) -> list[Finding]:
    """All health rules over one log (and optional events and voltage table), critical first.

    ``records`` None: no record of the health registers (what an empty table gives, without making one)."""
    findings = [
        *(analog_band_findings(records, bands) if records is not None else []),
        *(disturbance_rate_findings(records) if records is not None else []),
        *channel_fault_findings(events),
    ]
    if voltages is not None:
        findings += voltage_margin_findings(voltages)
    return sort_findings(findings)
