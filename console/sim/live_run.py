"""The simulator as a live feed: growing files in (scaled) real time, and LoRaWAN uplinks on MQTT.

``trackside simulate --live`` steps the simulator against the wall clock
(``speed`` × real time) and appends what happened to the same files the
batch run writes (``diagnostic.log``, ``nmea/<train>-<role>.nmea``), flushed
at every step, so ``trackside follow`` can follow them.  With ``--mqtt
URL`` every GNSS fix is also published as the unit's uplink, in ChirpStack
v4 form, with the payload of ``docs/lora-payload.md``.  ``truth.json`` is
written at the end, as in a batch run.
"""

from __future__ import annotations

import json
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from console.sim.diag_lines import (
    device_ids,
    health_register_rows,
    heartbeat_rows,
    identity_rows,
    in_order_lines,
    wheel_rows,
)
from console.sim.line_values import SentFix, StepResult
from console.sim.station import StationSim
from console.sim.writers import nmea_sentences, truth
from parsers.gnss.lora import UnitReport, chirpstack_topic, chirpstack_uplink, encode_payload

STEP_WALL_S = 0.1  # a line appears within this of its (scaled) time


def unit_eui(train: str, role: str) -> str:
    """A stable DevEUI per unit: 70b3d5e75e + train number (4 hex) + role (2 hex)."""
    return f"70b3d5e75e{train_number(train):04x}{0 if role == 'head' else 1:02x}"


def train_number(train: str) -> int:
    digits = re.sub(r"\D", "", train)
    return int(digits) % 65536 if digits else 0


class UplinkPublisher:
    """Publishes the units' fixes as ChirpStack v4 uplinks (paho-mqtt)."""

    def __init__(self, host: str, port: int, application_id: str = "trackside", tls: bool = False) -> None:
        import paho.mqtt.client as mqtt

        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="")
        if tls:
            self.client.tls_set()
        self.client.reconnect_delay_set(1, 5)
        self.application_id = application_id
        self.f_cnt: dict[str, int] = {}
        self.client.connect(host, port)
        self.client.loop_start()
        self.sent = 0
        self.delivered = 0
        self._pending: list[Any] = []

    def publish(self, f: SentFix) -> None:
        eui = unit_eui(f.train, f.role)
        n = self.f_cnt[eui] = self.f_cnt.get(eui, -1) + 1
        payload = encode_payload(
            UnitReport(
                role=f.role if f.role in ("head", "eot") else "other",
                train=train_number(f.train),
                lat_deg=f.lat,
                lon_deg=f.lon,
                speed_mps=min(max(f.speed_mps, 0.0), 600.0) if not math.isnan(f.speed_mps) else math.nan,
                heading_deg=f.course_deg,
                battery_pct=95.0,
                time_ns=f.t_ns,
                valid=f.valid,
                # Units that report their brake pipe send version 2 (docs/lora-payload.md).
                version=1 if math.isnan(f.brake_pipe_bar) and not f.emergency else 2,
                brake_pipe_bar=f.brake_pipe_bar,
                emergency=f.emergency,
            )
        )
        doc = chirpstack_uplink(
            eui, n, payload, time.time_ns(), application_id=self.application_id, device_name=f"{f.train}-{f.role}"
        )
        info = self.client.publish(chirpstack_topic(eui, self.application_id), json.dumps(doc), qos=1)
        self._pending.append(info)
        if len(self._pending) > 1000:
            self._pending = [i for i in self._pending if not i.is_published()]
        self.sent += 1

    def close(self, timeout_s: float = 10.0) -> None:
        """Stop once every uplink has reached the broker (QoS 1 acknowledged), or after the timeout."""
        end = time.monotonic() + timeout_s
        for info in self._pending:
            left = end - time.monotonic()
            if left <= 0:
                break
            try:
                info.wait_for_publish(left)
            except (RuntimeError, ValueError):
                break  # not connected: what is left is lost, and the summary says how many were sent
        self.delivered = sum(1 for i in self._pending if i.is_published()) + (self.sent - len(self._pending))
        self.client.loop_stop()
        self.client.disconnect()


@dataclass
class LiveWriter:
    """Appends the simulator's records and fixes to the run directory as they happen."""

    sim: StationSim
    directory: Path
    diag: IO[str] | None = None
    nmea: dict[str, IO[str]] = field(default_factory=dict)
    lines: int = 0
    fixes: int = 0

    def open(self) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        (self.directory / "nmea").mkdir(exist_ok=True)
        self.diag = (self.directory / "diagnostic.log").open("a", encoding="utf-8")
        self._write(in_order_lines(identity_rows(self.sim.layout, self.sim.cfg.start_ns), device_ids(self.sim.layout)))

    def _write(self, lines: list[str]) -> None:
        assert self.diag is not None
        if lines:
            self.diag.write("\n".join(lines) + "\n")
            self.diag.flush()
            self.lines += len(lines)

    def step(self, res: StepResult) -> None:
        """A step's records, status records and health registers (slow faults), and the fixes sent."""
        rows = heartbeat_rows(res.heartbeats) + wheel_rows((r.t_ns, r.head, r.channel, r.value) for r in res.records)
        rows += health_register_rows(res.health, self.sim.layout)
        self._write(in_order_lines(rows, device_ids(self.sim.layout)))
        for f in res.fixes:
            device = f"{f.train}-{f.role}"
            out = self.nmea.get(device)
            if out is None:
                out = self.nmea[device] = (self.directory / "nmea" / f"{device}.nmea").open(
                    "a", encoding="ascii", newline=""
                )
            out.write("\r\n".join(nmea_sentences(f.t_ns, f.lat, f.lon, f.speed_mps, f.course_deg)) + "\r\n")
            out.flush()
            self.fixes += 1

    def close(self) -> None:
        if self.diag is not None:
            self.diag.close()
        for f in self.nmea.values():
            f.close()
        doc = truth(self.sim)
        (self.directory / "truth.json").write_text(
            json.dumps(doc, ensure_ascii=False, indent=1) + "\n", encoding="utf-8"
        )


def run_live(
    sim: StationSim,
    duration_s: float,
    speed: float,
    directory: Path | None,
    publisher: UplinkPublisher | None,
    on_step: Callable[[float], None] | None = None,
) -> dict[str, Any]:
    """Step ``sim`` against the wall clock for ``duration_s`` simulated seconds (Ctrl-C stops early)."""
    writer = LiveWriter(sim, directory) if directory is not None else None
    if writer is not None:
        writer.open()
    t_wall0 = time.monotonic()
    interrupted = False
    try:
        while sim.t_s < duration_s:
            target = min(duration_s, (time.monotonic() - t_wall0) * speed)
            if target <= sim.t_s:
                time.sleep(STEP_WALL_S)
                continue
            while sim.t_s < target:  # the simulator's own step; a slow machine catches up
                res = sim.step(min(0.5, target - sim.t_s))
                if writer is not None:
                    writer.step(res)
                if publisher is not None:
                    for f in res.fixes:
                        publisher.publish(f)
            if on_step is not None:
                on_step(sim.t_s)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        sim.finish()
        if writer is not None:
            writer.close()
        if publisher is not None:
            publisher.close()
    return {
        "simulated_s": round(sim.t_s, 3),
        "interrupted": interrupted,
        "diagnostic_lines": writer.lines if writer else 0,
        "fixes": writer.fixes if writer else 0,
        "uplinks": publisher.sent if publisher else 0,
        "uplinks_acknowledged": publisher.delivered if publisher else 0,
        "start_ns": sim.cfg.start_ns,
        "wall_s": round(time.monotonic() - t_wall0, 3),
        "speed": speed,
        "trains": len(sim.trains),
        "step_wall_s": STEP_WALL_S,
    }
