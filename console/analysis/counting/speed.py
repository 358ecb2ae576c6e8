"""Train speeds from one counting head.

Three estimates, each with its own evidence:

* **per-second method** (seed 003, §2.2.1): the head wrote ``records`` records
  in the second in which it detected the train; the paper takes the time to
  cross the coil spacing as ``1/records`` s, so v = spacing × records.  It is
  a proxy tied to the device's logging rate, reproduced because maintainers
  compare against it.
* **whole-train speed** (§2.2.2): (first-to-last-wheel length + spacing) over
  the time from the first Sys1 to the last Sys2 record of the passage.
* **per-axle speed**: spacing over the Sys1 → Sys2 delay of one wheel, only
  when the log has sub-second times fine enough to time that delay to 10 %
  (at least ten steps: millisecond stamps stop at 46.8 km/h on 0.13 m).
"""

from __future__ import annotations

MPS_TO_KMH = 3.6


def per_second_method_kmh(spacing_m: float, records_in_second: int) -> float:
    """v = spacing / (1 / records) (seed 003)."""
    return spacing_m * records_in_second * MPS_TO_KMH


def whole_train_kmh(train_length_m: float, spacing_m: float, duration_s: float) -> float | None:
    """v = (train length + spacing) / passage duration; None for a zero duration."""
    if duration_s <= 0:
        return None
    return (train_length_m + spacing_m) / duration_s * MPS_TO_KMH


def axle_kmh(spacing_m: float, delay_s: float) -> float | None:
    """v = coil spacing / Sys1→Sys2 delay of one wheel; None for a zero delay."""
    if delay_s <= 0:
        return None
    return spacing_m / delay_s * MPS_TO_KMH
