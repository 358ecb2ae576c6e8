"""The disturbance rule: how fast each channel's 1-edge counter grows, per hour."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from console.analysis.health.findings import Finding, Severity, where_text
from console.analysis.health.register_rows import NS_PER_H, NS_PER_S, register_records
from console.analysis.timefmt import iso

if TYPE_CHECKING:
    import pandas as pd


DISTURBANCE_WARN_PER_H = 12.0  # the disturbance rule's warning level (see disturbance_rate_findings)


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
    out = register_records(records, "counter_1_edge", ("address", "file") if has_file else ("address",))
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
    if span_ns <= 0 or span_ns < min_span_s * NS_PER_S:
        return None
    total = np.cumsum(growth)
    window_ns = int(window_s * NS_PER_S)
    if span_ns < window_ns:
        at = np.array([len(times) - 1])
        since = np.array([0])
    else:
        at = np.flatnonzero(times - times[0] >= window_ns)
        since = np.searchsorted(times, times[at] - window_ns, side="right") - 1
    rates = (total[at] - total[since]) / ((times[at] - times[since]) / NS_PER_H)
    peak_i = int(np.argmax(rates))
    peak = float(rates[peak_i])
    overall = float(total[-1]) / (span_ns / NS_PER_H)
    where = where_text(head, channel)
    window = f"{window_s / 3600:g} h windows" if span_ns >= window_ns else f"{span_ns / NS_PER_H:.2f} h"
    reset_note = f", {resets} counter reset{'s' if resets != 1 else ''} seen" if resets else ""
    plural = "s" if total[-1] != 1 else ""
    summary = f"{total[-1]:.0f} disturbance{plural} in {span_ns / NS_PER_H:.1f} h ({overall:.1f}/h overall{reset_note})"
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
