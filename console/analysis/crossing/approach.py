"""Work-site approach warnings from a counting head's speed (seed 003's purpose).

A train approach indicator warns track workers at a site a known distance
beyond a counting head.  The conventional indicator sounds from the moment
the head detects the train, so a slow train means a long, needless alarm
(and workers who learn to ignore it).  Seed 003 measures the train's speed
at the head to shorten it.

Here the speed-based alarm starts when the train's *earliest* arrival at the
site is within the warning time: from the speed measured at the head, the
train may still accelerate (``accel_mps2``, up to the line speed), so the
workers always get at least the warning time.  Both methods are shown side
by side: when each alarm starts, the lead it gives, and the alarm time the
speed-based method saves.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import pandas as pd

from console.analysis.crossing.values import earliest_arrival_s
from console.analysis.timefmt import iso
from console.layout import Layout, WorkSite
from parsers.units import NS


@dataclass(frozen=True)
class ApproachSettings:
    accel_mps2: float = 0.5  # the train may still accelerate this hard after the head


@dataclass(frozen=True)
class ApproachRow:
    site: str
    counting_head: str
    t_detect_ns: int  # the head first detected the train: the conventional alarm starts here
    speed_kmh: float | None  # measured at the head
    speed_basis: str
    t_arrival_ns: int | None  # expected at the site at the measured speed
    t_alarm_speed_ns: int  # speed-based alarm start
    lead_fixed_s: float | None  # conventional: detection → arrival
    lead_speed_s: float | None  # speed-based: alarm → arrival
    saved_s: float | None  # alarm time the speed-based method spares the workers
    note: str

    def to_dict(self) -> dict[str, Any]:
        def r(x: float | None) -> float | None:
            return None if x is None else round(x, 2)

        return {
            "site": self.site,
            "counting_head": self.counting_head,
            "t_detect": iso(self.t_detect_ns),
            "speed_kmh": r(self.speed_kmh),
            "speed_basis": self.speed_basis,
            "t_arrival": iso(self.t_arrival_ns),
            "t_alarm_fixed": iso(self.t_detect_ns),
            "t_alarm_speed": iso(self.t_alarm_speed_ns),
            "lead_fixed_s": r(self.lead_fixed_s),
            "lead_speed_s": r(self.lead_speed_s),
            "saved_s": r(self.saved_s),
            "note": self.note,
        }


def _speed(p: Any) -> tuple[float | None, str]:
    for col, basis in (
        ("speed_kmh_per_axle_mean", "per axle"),
        ("speed_kmh_whole_train", "whole train"),
        ("speed_kmh_per_second_method", "per-second method"),
    ):
        v = getattr(p, col)
        if v is not None and not pd.isna(v) and v > 0:
            return float(v), basis
    return None, "none"


def approach_timeline(
    passages: pd.DataFrame, layout: Layout, site: WorkSite, settings: ApproachSettings | None = None
) -> list[ApproachRow]:
    """One row per train passage at the site's approach head moving towards the site."""
    s = settings or ApproachSettings()
    head = layout.head(site.head)
    toward = 1 if site.distance_m > 0 else -1  # +: the site lies up the line from the head
    distance = abs(site.distance_m)
    rows: list[ApproachRow] = []
    if passages.empty:
        return rows
    mine = passages[(passages["counting_head"] == site.head) & (passages["kind"] == "train")]
    p: Any
    for p in mine.itertuples(index=False):
        direction = 0
        if isinstance(p.direction, str) and p.direction in ("sys1_to_sys2", "sys2_to_sys1"):
            first_is_up = head.up_is_first_channel_first
            direction = 1 if (p.direction == "sys1_to_sys2") == first_is_up else -1
        if direction == -toward:
            continue  # running away from the site
        t_detect = int(p.start_ns)
        v_kmh, basis = _speed(p)
        note = ""
        if v_kmh is None:
            # No speed: warn at once, as the conventional indicator does.
            rows.append(
                ApproachRow(
                    site.id,
                    site.head,
                    t_detect,
                    None,
                    basis,
                    None,
                    t_detect,
                    None,
                    None,
                    0.0,
                    "no speed measured: alarm from detection",
                )
            )
            continue
        v = v_kmh / 3.6
        nominal = distance / v
        vmax = layout.max_speed_mps(head.chainage_m, head.chainage_m + site.distance_m)
        earliest = earliest_arrival_s(distance, v, s.accel_mps2, max(v, vmax))
        start = t_detect + int(max(0.0, earliest - site.warning_time_s) * NS)
        if direction == 0:
            start, note = t_detect, "direction unknown: alarm from detection"
        elif earliest < site.warning_time_s:
            note = f"the site gets only {earliest:.0f} s even from detection: move the warning point further out"
        lead_speed = nominal - (start - t_detect) / NS
        rows.append(
            ApproachRow(
                site=site.id,
                counting_head=site.head,
                t_detect_ns=t_detect,
                speed_kmh=v_kmh,
                speed_basis=basis,
                t_arrival_ns=t_detect + int(nominal * NS),
                t_alarm_speed_ns=start,
                lead_fixed_s=nominal,
                lead_speed_s=lead_speed,
                saved_s=(start - t_detect) / NS,
                note=note,
            )
        )
    return rows
