"""A table of GNSS fixes (batch) → the crossing units' trains and placed fixes.

Fixes (from :mod:`parsers.gnss.centre`) are grouped into trains — a train is a head
unit and an EOT unit, paired by the caller or, with one of each, by their
roles — and projected onto the layout's track.  Fixes far from the track are
set aside and counted: they cannot be placed on the line.  The batch driver
(:mod:`console.drivers.crossings`) feeds the placed fixes to the one crossing
and integrity stage every mode runs.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Collection, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from console.analysis.crossing.timeline import TimelineRow
from console.analysis.crossing.values import EOT, HEAD, ControllerSettings, CrossingEvent
from console.analysis.integrity.values import IntegrityEvent, IntegritySettings
from console.layout import Layout
from console.plural import count

OFF_TRACK_M = 100.0


@dataclass(frozen=True)
class TrainDevices:
    train: str
    head: tuple[str, ...]
    eot: tuple[str, ...]
    length_m: float
    length_given: bool = False  # False: the layout's default, not this train's own


@dataclass
class CrossingRun:
    timelines: list[TimelineRow]
    events: list[CrossingEvent]
    trains: list[TrainDevices]
    off_track: int = 0
    unassigned_devices: list[str] = field(default_factory=list)
    position_jumps: int = 0  # fixes set aside as implausible for a train (counted once, not per crossing)
    integrity: list[IntegrityEvent] = field(default_factory=list)  # every train's integrity changes, in time order
    undated: int = 0  # the units' fixes set aside for want of a date and time (GGA with no RMC or ZDA to date it)

    @property
    def late_warnings(self) -> int:
        return sum(1 for r in self.timelines if r.late_by_s is not None)

    @property
    def violations(self) -> int:
        return sum(1 for r in self.timelines if r.violations)


_UNIT_NAME = re.compile(r"(.+)-(head|eot)", re.IGNORECASE)


def _unit_name(device: str) -> tuple[str, str] | None:
    """``T1-head`` (or ``T1-HEAD``) → ("T1", HEAD); None for a name that says no train and role."""
    m = _UNIT_NAME.fullmatch(device)
    return (m.group(1), HEAD if m.group(2).lower() == "head" else EOT) if m else None


def pair_trains(
    fixes: pd.DataFrame, given: Sequence[TrainDevices], default_length_m: float
) -> tuple[list[TrainDevices], list[str]]:
    """The trains to follow: as given, else one train of all head and all EOT devices.

    Returns (trains, devices in the data that belong to no train).
    """
    devices = sorted(str(d) for d in fixes["device"].unique()) if len(fixes) else []
    if given:
        known = {d for t in given for d in (*t.head, *t.eot)}
        return list(given), [d for d in devices if d not in known]
    roles = fixes.groupby("device", observed=True)["role"].first() if len(fixes) else pd.Series(dtype=object)
    # NMEA carries no role: a device named <train>-head / <train>-eot says it (any case: A-HEAD too).
    names = {str(d): _unit_name(str(d)) for d in roles.index}

    def role_of(device: object, given: object) -> object:
        named = names[str(device)]
        return given if given in (HEAD, EOT) or named is None else named[1]

    roles = pd.Series({d: role_of(d, r) for d, r in roles.items()}, dtype=object)
    heads = tuple(str(d) for d, r in roles.items() if r == HEAD)
    eots = tuple(str(d) for d, r in roles.items() if r == EOT)
    # Devices named <train>-head / <train>-eot pair by name.
    named = {n[0] for d in (*heads, *eots) if (n := names[d])}
    if len(named) > 1 or (named and len(heads) + len(eots) == 2 * len(named)):
        out = [
            TrainDevices(
                n,
                tuple(d for d in heads if names[d] == (n, HEAD)),
                tuple(d for d in eots if names[d] == (n, EOT)),
                default_length_m,
            )
            for n in sorted(named)
        ]
        known = {d for t in out for d in (*t.head, *t.eot)}
        return out, [d for d in devices if d not in known]
    if not heads and not eots:
        return [], devices
    other = [d for d in devices if d not in heads and d not in eots]
    return [TrainDevices("train", heads, eots, default_length_m)], other


def merged_units(trains: Sequence[TrainDevices], pairing_hint: str) -> str | None:
    """What to say when :func:`pair_trains` read several head or EOT devices as one train (no ``--train``, no
    ``<train>-head`` / ``<train>-eot`` names to pair them by): two trains merged give false partings and stale
    units, so it is said, never silent."""
    if len(trains) != 1 or trains[0].train != "train":
        return None
    t = trains[0]
    if len(t.head) <= 1 and len(t.eot) <= 1:
        return None
    return (
        f"{len(t.head)} head and {len(t.eot)} EOT devices, not named <train>-head / <train>-eot, read as one train: "
        + pairing_hint
    )


def input_warnings(run: CrossingRun, fixes: pd.DataFrame, *, trains_named: bool, pairing_hint: str) -> list[str]:
    """What a crossing run set aside or could not tell from ``fixes``, said the same by every face that runs it
    (``trackside crossing``, the report of files or of the archive); ``pairing_hint``: how that face's user
    pairs devices into trains."""
    out = []
    if run.off_track:
        out.append(f"{count(run.off_track, 'fix')} more than {OFF_TRACK_M:.0f} m from the track set aside")
    if run.undated:  # a GGA-only capture: positions but no date, none of them usable
        out.append(f"{count(run.undated, 'fix')} without a date and time set aside (GGA with no RMC or ZDA to date it)")
    for device, n, spread_m in conflicting_instants(fixes, run.trains):
        out.append(
            f"{device}: {count(n, 'instant')} with two positions up to {spread_m:,.0f} m apart (the device"
            " written twice, differently?): the last row of each read, the other set aside"
        )
    if never := units_never_valid(fixes, run.trains):
        out.append(f"no valid fix from {', '.join(never)}: every one marked invalid (no position fix)")
    if run.position_jumps:
        out.append(f"{count(run.position_jumps, 'fix')} set aside as position jumps (implausible for a train)")
    if run.unassigned_devices:
        out.append("devices in no train: " + ", ".join(run.unassigned_devices))
    if not run.trains:
        out.append(f"no head or EOT device found: {pairing_hint}")
    if not trains_named and (merged := merged_units(run.trains, pairing_hint)):
        out.append(merged)
    return out


def _valid_unit_rows(fixes: pd.DataFrame, units: Collection[str]) -> pd.Series:
    """The rows of ``units``' fixes marked valid (a mask)."""
    return fixes["device"].astype(str).isin(units) & fixes["valid"].astype(bool)


def _placeable(fixes: pd.DataFrame, units: Collection[str]) -> pd.DataFrame:
    """``units``' valid fixes with a time and a position: the ones a crossing unit can take."""
    return fixes[_valid_unit_rows(fixes, units)].dropna(subset=["lat", "lon", "time"])


def _units(trains: Sequence[TrainDevices]) -> set[str]:
    return {d for t in trains for d in (*t.head, *t.eot)}


def unit_fixes(fixes: pd.DataFrame, trains: Sequence[TrainDevices]) -> pd.DataFrame:
    """The trains' units' valid fixes with a time and a position, one per device and instant, in time order,
    with each one's ``train`` and ``role`` and its time in ns (``t_ns``)."""
    owner = {d: (t.train, HEAD) for t in trains for d in t.head}
    owner.update({d: (t.train, EOT) for t in trains for d in t.eot})
    sel = _placeable(fixes, owner.keys())
    # One fix per device and instant: NMEA gives an RMC and a GGA for each (keep the one with a speed).
    sel = sel.assign(_has_speed=sel["speed_mps"].notna()).sort_values(["device", "time", "_has_speed"], kind="stable")
    sel = sel.drop_duplicates(["device", "time"], keep="last").sort_values("time", kind="stable")
    devices = sel["device"].astype(str)
    return sel.assign(
        device=devices,
        train=devices.map(lambda d: owner[d][0]),
        role=devices.map(lambda d: owner[d][1]),
        # In ns whatever resolution the table came in (pandas 3 keeps µs or s from its source).
        t_ns=pd.to_datetime(sel["time"], utc=True).dt.as_unit("ns").astype("int64"),
    )


# Two fixes of one device at one instant further apart than this are two positions, not one fix written twice
# (an RMC and a GGA of one epoch agree to the metre).
CONFLICT_M = 30.0
M_PER_DEG = 111_320.0  # a degree of latitude (and of longitude × cos latitude): enough to tell 30 m from 1 km


def conflicting_instants(fixes: pd.DataFrame, trains: Sequence[TrainDevices]) -> list[tuple[str, int, float]]:
    """(device, instants, the widest spread m) of the trains' units whose valid fixes give two positions for
    one instant more than CONFLICT_M apart: :func:`unit_fixes` keeps one row of each (an export that wrote a
    device twice, differently), which no reader can choose right, so it is said."""
    sel = _placeable(fixes, _units(trains))
    if not len(sel):
        return []
    g = sel.assign(device=sel["device"].astype(str)).groupby(["device", "time"], sort=False, observed=True)
    lat, lon = g["lat"], g["lon"]
    mid_lat = np.radians(lat.mean().to_numpy())
    spread_m = np.hypot(
        (lat.max() - lat.min()).to_numpy() * M_PER_DEG,
        (lon.max() - lon.min()).to_numpy() * M_PER_DEG * np.cos(mid_lat),
    )
    wide = pd.Series(spread_m, index=lat.max().index)
    wide = wide[wide > CONFLICT_M]
    out = []
    for device, per in wide.groupby(level=0, sort=True):
        out.append((str(device), len(per), float(per.max())))
    return out


def undated_fixes(fixes: pd.DataFrame, trains: Sequence[TrainDevices]) -> int:
    """How many of the trains' units' valid, positioned fixes have no time (:func:`unit_fixes` sets them aside)."""
    if not len(fixes):
        return 0
    mine = _valid_unit_rows(fixes, _units(trains))
    return int((mine & fixes["lat"].notna() & fixes["lon"].notna() & fixes["time"].isna()).sum())


def units_never_valid(fixes: pd.DataFrame, trains: Sequence[TrainDevices]) -> list[str]:
    """The trains' units with fixes, every one marked invalid (no position fix): :func:`unit_fixes` sets them all
    aside, and a run of nothing else was an empty table with no word why."""
    if not len(fixes):
        return []
    devices = fixes["device"].astype(str)
    valid = set(devices[fixes["valid"].astype(bool)])
    present = set(devices)
    return [d for t in trains for d in (*t.head, *t.eot) if d in present and d not in valid]


def crossing_settings(
    layout: Layout, report_period_s: float | None = None, base: ControllerSettings | None = None
) -> ControllerSettings:
    """The crossing units' settings on ``layout``, the same in every mode: its line speed; the GNSS units'
    report period (the layout's ``[devices]``, else ``report_period_s``, else the default) and the radio's
    delay allowance (the layout's, else the default).  A unit is stale after several missed reports,
    never after one lost packet."""
    s = base or ControllerSettings(line_speed_mps=layout.line_speed_mps)
    period = layout.gnss_report_period_s if layout.gnss_report_period_s is not None else report_period_s
    if layout.gnss_latency_s is not None:
        s = dataclasses.replace(s, latency_s=layout.gnss_latency_s)
    if period is not None:
        s = dataclasses.replace(s, report_period_s=period, stale_after_s=max(s.stale_after_s, 4 * period))
    return s


def integrity_settings(s: ControllerSettings) -> IntegritySettings:
    """The integrity monitor's timing, the crossing units' (the same fixes, the same radio)."""
    return IntegritySettings(report_period_s=s.report_period_s, latency_s=s.latency_s, stale_after_s=s.stale_after_s)


MAX_TRAIN_LENGTH_M = 5000.0  # past the longest freight trains run (about 3.5 km)


def parse_train_options(texts: Sequence[str], default_length_m: float) -> list[TrainDevices]:
    """Every ``--train``, each train and each device named once (ValueError with the reason): a device is one
    train's head or EOT, and a train one pair (fixes go to a device's one owner; the second was taken unsaid)."""
    trains = [parse_train_option(t, default_length_m) for t in texts]
    names: set[str] = set()
    owner: dict[str, str] = {}
    for t in trains:
        if t.train in names:
            raise ValueError(f"--train {t.train}: given twice (one --train per train)")
        names.add(t.train)
        for role, device in (("head", t.head[0]), ("EOT", t.eot[0])):
            if device in owner:
                raise ValueError(
                    f"--train {t.train}: {device} is already {owner[device]} (a device is one train's head or EOT)"
                )
            owner[device] = f"{t.train}'s {role}"
    return trains


def parse_train_option(text: str, default_length_m: float) -> TrainDevices:
    """``T1=head1,eot1[,length_m]`` → TrainDevices (ValueError with the reason)."""
    name, sep, rest = text.partition("=")
    parts = [x.strip() for x in rest.split(",")] if sep else []
    if not name.strip() or len(parts) not in (2, 3) or not all(parts[:2]):
        raise ValueError(f"--train {text!r}: expected TRAIN=HEAD_DEVICE,EOT_DEVICE[,LENGTH_M]")
    length = default_length_m
    if len(parts) == 3:
        try:
            length = float(parts[2])
        except ValueError:
            raise ValueError(f"--train {text!r}: length {parts[2]!r} is not a number") from None
        if not 0 < length <= MAX_TRAIN_LENGTH_M:  # NaN fails this too
            raise ValueError(f"--train {text!r}: length {parts[2]!r} m: expected above 0 and at most 5000")
    return TrainDevices(name.strip(), (parts[0],), (parts[1],), length, len(parts) == 3)
