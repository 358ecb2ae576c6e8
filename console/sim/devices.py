"""How the simulated line's devices report, said once: in the layout's ``[devices]`` table.

The station's console and every command reading the written run take their
timing from the layout (``power_gap_s``, ``gnss_report_period_s``,
``gnss_latency_s``), so the simulator states its devices there: the layout's
own values where it gives them, else the simulator's (a power loss once a
heartbeat is missed: silent for one and a half heartbeats; the LoRa link's
report period; its delay plus a margin for handling).  The power gap is the
time a train can enter over a dead head unseen (a section shown clear over
it): the shorter, the safer, and the simulated heads keep their beat exactly.
The run's ``layout.toml`` is written with them.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

from console.layout import Layout
from console.sim.radio import LoRaLink

MISSED_HEARTBEATS = 1.5  # a head silent this many of its heartbeats (one missed) has lost power or contact
LATENCY_MARGIN_S = 0.5  # the console's allowance over the radio's delay (handling, clocks)


@dataclass(frozen=True)
class Devices:
    power_gap_s: float
    gnss_report_period_s: float
    gnss_latency_s: float


def line_devices(layout: Layout, heartbeat_s: float, radio: LoRaLink) -> Devices:
    """The devices' timing: the layout's where it says, else the simulator's.  ValueError: a layout whose
    figures the simulated devices cannot keep (a power gap no longer than a heartbeat; units reporting more
    often than the radio's duty cycle allows)."""
    gap = layout.power_gap_s if layout.power_gap_s is not None else MISSED_HEARTBEATS * heartbeat_s
    if gap <= heartbeat_s:
        raise ValueError(
            f"{layout.source}: devices.power_gap_s {gap:g} s is not longer than the heads' heartbeat "
            f"({heartbeat_s:g} s)"
        )
    shortest = radio.report_period_s()
    period = layout.gnss_report_period_s if layout.gnss_report_period_s is not None else shortest
    if period < shortest:
        raise ValueError(
            f"{layout.source}: devices.gnss_report_period_s {period:g} s is shorter than the LoRa duty cycle allows "
            f"at SF{radio.spreading_factor} ({shortest:.2f} s)"
        )
    latency = layout.gnss_latency_s if layout.gnss_latency_s is not None else radio.latency_s() + LATENCY_MARGIN_S
    return Devices(gap, period, latency)


def with_devices(layout: Layout, devices: Devices) -> Layout:
    """The layout as the run writes it: its ``[devices]`` figures filled in."""
    return dataclasses.replace(
        layout,
        power_gap_s=devices.power_gap_s,
        gnss_report_period_s=devices.gnss_report_period_s,
        gnss_latency_s=devices.gnss_latency_s,
    )


_TABLE = re.compile(r"^\s*\[\s*devices\s*\]\s*(#.*)?$")


def devices_text(text: str, layout: Layout, devices: Devices) -> str:
    """A layout's TOML text with its ``[devices]`` figures filled in: the keys it lacks added at the head of
    its table, or a table added at the end."""
    given = {
        "power_gap_s": layout.power_gap_s,
        "gnss_report_period_s": layout.gnss_report_period_s,
        "gnss_latency_s": layout.gnss_latency_s,
    }
    missing = [f"{key} = {getattr(devices, key)!r}" for key, value in given.items() if value is None]
    if not missing:
        return text
    lines = text.splitlines()
    at = next((i for i, line in enumerate(lines) if _TABLE.match(line)), None)
    if at is None:
        note = "# How the simulated devices report (written by trackside simulate)."
        return text.rstrip("\n") + "\n\n" + "\n".join([note, "[devices]", *missing]) + "\n"
    return "\n".join([*lines[: at + 1], *missing, *lines[at + 1 :]]) + "\n"
