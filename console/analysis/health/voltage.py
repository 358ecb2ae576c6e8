"""The voltage margin rule: in-phase minus anti-phase receiver voltage, per sensor."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from console.analysis.health.findings import SEVERITY_ORDER, Finding, Severity

if TYPE_CHECKING:
    import pandas as pd


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
                Severity(SEVERITY_ORDER[int(sev)]),
                "voltage_margin",
                sensor,
                None,
                text,
                float(m_mv),
                float(threshold_mv),
            )
        )
    return findings
