"""Write a simulated run in the real formats, with its ground truth.

Into one directory:

* ``diagnostic.log`` — Frauscher-style records, the real grammar, microsecond
  times (at 90 km/h a wheel crosses the 0.13 m coil spacing in 5.2 ms, so
  milliseconds alone would err by up to 10 % in the per-axle speed; the
  writer can also stamp milliseconds or whole seconds, per head, and
  interleave the boards at random as real exports do): every
  wheel-sensor onset and release (Radsensor, Adr 026), a status record
  (Adr 000) from each head's device every heartbeat, and an identity dump
  per device at the start;
* ``nmea/<train>-<role>.nmea`` — RMC and GGA sentences per GNSS unit (real
  checksums), as the units send them (their own logs: every fix);
* ``gnss_devices.csv`` — the fixes the radio delivered (less those it lost),
  as a network server's device stream: what the station's console received;
* ``centre.tsv`` — the monitoring-centre table of seed 004 (Vietnamese
  header, decimal commas, newest first, one row per train every 10 s of the
  head fixes it received, with each crossing's warning state as the console
  saw it; written when a console watched the run);
* ``sensor_frames.txt`` — each head as an intelligent sensor (seed 002
  frame: status byte and count, 0xA5 check byte while idle);
* ``layout.toml`` — the layout the run used, its ``[devices]`` table saying
  how the devices report (console.sim.devices);
* ``truth.json`` — every axle's time and speed at every head, every
  section's true occupancy, every crossing's true head and tail times, the
  trains, the partings (when, the rear part's axles, where it stopped), the
  faults injected, and the console's final section states (when a console
  watched the run).
"""

from __future__ import annotations

import datetime as dt
import heapq
import json
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from console.analysis.timefmt import iso
from console.layout import BUILTIN, Layout
from console.sim.devices import devices_text
from console.sim.diag_lines import (
    TIME_RESOLUTIONS,
    Row,
    device_ids,
    diag_line,
    health_lines,
    health_register_rows,
    heartbeat_rows,
    identity_rows,
    naive_time,
    wheel_rows,
)
from console.sim.faults import SLOW_FAULT_KINDS
from console.sim.gnss_rows import DEVICE_STREAM_HEADER, device_stream_row, unit_name
from console.sim.slow_faults import threshold_crossings
from console.sim.station import StationSim
from parsers.frames.table import CHECK_BYTE, encode_status
from parsers.units import NS

CENTRE_PERIOD_S = 10.0


def interleave_order(
    t_ns: np.ndarray, printed_ns: np.ndarray, board: np.ndarray, rng: np.random.Generator | None
) -> np.ndarray:
    """The order an export writes records in: by printed time, each board in its own order.

    Records of several boards that print the same time interleave at random
    (``rng``; None: by true time), but a board's own records never change
    order: within a whole second their order is the only timing evidence.
    """
    if rng is None:
        return np.lexsort((t_ns, printed_ns))
    own = np.lexsort((t_ns, board, printed_ns))  # groups (printed, board), each in the board's order
    p, b = printed_ns[own], board[own]
    gid = np.cumsum(np.r_[True, (p[1:] != p[:-1]) | (b[1:] != b[:-1])]) - 1
    u = rng.random(len(t_ns))
    # Groups are contiguous in `own`: the k-th member of a group takes the
    # group's k-th smallest key, so sorting by key keeps each board's order.
    key = np.empty(len(t_ns))
    key[own] = u[np.lexsort((u, gid))]
    return np.lexsort((key, printed_ns))


def write_diagnostic(
    sim: StationSim,
    path: Path,
    resolution: str | dict[str, str] = "us",
    interleave_seed: int | None = None,
    *,
    identity: bool = True,
    append: bool = False,
) -> int:
    """The diagnostic log; ``resolution`` ("us", "ms", "s", or per head id) stamps the times.

    ``interleave_seed``: boards whose records print the same time interleave
    at random (each board keeping its own order); None: in true time order.
    ``identity``: each device's identity dump at the run's start; ``append``: add to the log (a multi-day
    run writes a day at a time).
    """
    ids = device_ids(sim.layout)
    res = {h.id: resolution if isinstance(resolution, str) else resolution.get(h.id, "us") for h in sim.layout.heads}
    rows: list[Row] = identity_rows(sim.layout, sim.cfg.start_ns) if identity else []
    rows += heartbeat_rows(sim.heartbeats)
    rows += wheel_rows((r.t_ns, r.head, r.channel, r.value) for r in sim.all_records)
    fast = interleave_seed is None and all(r == "us" for r in res.values())
    if not fast:
        rows += health_register_rows(sim.health_rows, sim.layout)
    rows.sort(key=lambda x: x[0])  # stable: a board's records stay in the order it saw them
    t_ns = np.array([r[0] for r in rows], np.int64)
    step = np.array([TIME_RESOLUTIONS[res[r[1]]] for r in rows], np.int64)
    board = np.array([ids[r[1]] for r in rows], np.int64)
    rng = None if interleave_seed is None else np.random.default_rng(interleave_seed)
    order = interleave_order(t_ns, t_ns - t_ns % step, board, rng) if rows else np.zeros(0, np.int64)
    lines = []
    for i in order.tolist():
        t, head, ch, adr, label, data = rows[i]
        lines.append(diag_line(ids[head], head, ch, adr, label, data, t, res[head]))
    if fast and sim.health_rows:
        # Weeks of hundreds of heads: the health registers formatted as columns, merged in by time
        # (a stable merge: at equal times the other records first, as the sort above puts them).
        times, health = health_lines(sim.health_rows, sim.layout, ids)
        ours = zip(t_ns[order].tolist(), lines, strict=True)
        merged = heapq.merge(ours, zip(times, health, strict=True), key=lambda x: x[0])
        lines = [line for _, line in merged]
    with path.open("a" if append else "w", encoding="utf-8") as out:
        if lines or not append:
            out.write("\n".join(lines) + "\n")
    return len(lines)


def _nmea(body: str) -> str:
    checksum = 0
    for ch in body.encode("ascii"):
        checksum ^= ch
    return f"${body}*{checksum:02X}"


def _ddmm(value: float, lat: bool) -> tuple[str, str]:
    hemi = ("N" if value >= 0 else "S") if lat else ("E" if value >= 0 else "W")
    v = abs(value)
    deg = int(v)
    minutes = (v - deg) * 60
    return (f"{deg:02d}{minutes:08.5f}" if lat else f"{deg:03d}{minutes:08.5f}"), hemi


def nmea_sentences(t_ns: int, lat: float, lon: float, speed_mps: float, course_deg: float) -> list[str]:
    """RMC and GGA for one fix (GN talker, 5 decimal minutes ≈ 2 cm)."""
    t = dt.datetime(1970, 1, 1, tzinfo=dt.UTC) + dt.timedelta(microseconds=t_ns // 1000)
    hms = f"{t:%H%M%S}.{t.microsecond // 10000:02d}"
    la, ns = _ddmm(lat, True)
    lo, ew = _ddmm(lon, False)
    knots = speed_mps * 3600 / 1852
    rmc = _nmea(f"GNRMC,{hms},A,{la},{ns},{lo},{ew},{knots:.3f},{course_deg:.1f},{t:%d%m%y},,,A")
    gga = _nmea(f"GNGGA,{hms},{la},{ns},{lo},{ew},1,10,0.9,20.0,M,-20.0,M,,")
    return [rmc, gga]


def write_gnss(sim: StationSim, directory: Path, append: bool = False) -> dict[str, int]:
    nmea_dir = directory / "nmea"
    nmea_dir.mkdir(exist_ok=True)
    per_device: dict[str, list[str]] = {}
    csv_path = directory / "gnss_devices.csv"
    csv = [] if append and csv_path.exists() else [DEVICE_STREAM_HEADER]
    for f in sorted(sim.all_fixes, key=lambda f: (f.t_ns, f.train, f.role)):
        per_device.setdefault(unit_name(f), []).extend(nmea_sentences(f.t_ns, f.lat, f.lon, f.speed_mps, f.course_deg))
    csv += [device_stream_row(f) for f in sim.all_received]  # in delivery order: the network's stream
    for device, lines in per_device.items():
        with (nmea_dir / f"{device}.nmea").open("a" if append else "w", encoding="ascii", newline="") as out:
            out.write("\r\n".join(lines) + "\r\n")
    if csv:
        with csv_path.open("a" if append else "w", encoding="utf-8") as out:
            out.write("\n".join(csv) + "\n")
    return {d: len(v) // 2 for d, v in per_device.items()}


def _comma(x: float, digits: int) -> str:
    return f"{x:.{digits}f}".replace(".", ",")


def write_centre_table(sim: StationSim, path: Path, append: bool = False) -> int:
    """Seed 004's monitoring-centre table: one row per train every 10 s of the head fixes the centre
    received, with the warning states of the console watching the run.

    ``append``: a multi-day run's next day, its rows (newest first) after the days before."""
    if sim.console is None:
        raise ValueError("the monitoring-centre table shows the console's warnings: attach a console to the run")
    codes = [c.code for c in sim.layout.crossings]
    header = ["TIMESTAMP", "Mã tàu", "Vĩ độ", "Kinh độ", "Vận tốc (km/h)"]
    for k in range(1, len(codes) + 1):
        header += [f"Mã đường ngang {k}", f"Trạng thái kết nối đường ngang {k}"]
    # Warning intervals per crossing and train, from the console's own events.
    intervals: dict[str, list[tuple[int, int | None]]] = {}
    for code, events in sim.console.crossing_events().items():
        on: dict[str, int] = {}
        for e in events:
            if e.kind == "on":
                on.setdefault(e.train, e.t_ns)
            elif e.kind == "off" and e.train in on:
                intervals.setdefault(code, []).append((on.pop(e.train), e.t_ns))
        intervals.setdefault(code, []).extend((t_on, None) for t_on in on.values())

    def warned(code: str, t: int) -> bool:
        return any(a <= t and (b is None or t < b) for a, b in intervals.get(code, []))

    heads = sorted((f for f in sim.all_received if f.role == "head"), key=lambda f: f.t_ns)
    rows: list[str] = []
    last: dict[str, int] = {}
    for f in heads:
        if f.t_ns - last.get(f.train, -(10**30)) < CENTRE_PERIOD_S * NS:
            continue
        last[f.train] = f.t_ns
        t = naive_time(f.t_ns)
        cells = [f"{t:%Y-%m-%d %H:%M:%S}", f.train, _comma(f.lat, 5), _comma(f.lon, 5), _comma(f.speed_mps * 3.6, 1)]
        for code in codes:
            cells += [code, "Cảnh báo" if warned(code, f.t_ns) else "Bình thường"]
        rows.append("\t".join(cells))
    rows.reverse()  # newest first, as the centre shows it
    head = "" if append and path.exists() else "\t".join(header) + "\n"
    with path.open("a" if append else "w", encoding="utf-8") as out:
        out.write(head + "\n".join(rows) + ("\n" if rows else ""))
    return len(rows)


def write_frames(
    sim: StationSim, path: Path, idle_every_s: float = 5.0, *, since_ns: int | None = None, append: bool = False
) -> int:
    """Each head as an intelligent sensor: a frame per axle while counting, the check byte while idle.

    ``since_ns``: from then on (a multi-day run writes a day at a time, ``append``)."""
    lines: list[tuple[int, str]] = []
    by_head: dict[str, list[tuple[int, int]]] = {}
    for e in sim.axle_events:
        by_head.setdefault(e.head, []).append((e.time_ns, e.direction))
    end = sim.now_ns
    for h in sim.layout.heads:
        axles = sorted(by_head.get(h.id, []))
        count, last_axle = 0, None
        t = sim.cfg.start_ns if since_ns is None else since_ns
        k = 0
        while t < end:
            nxt = axles[k][0] if k < len(axles) else None
            if nxt is not None and nxt <= t + int(idle_every_s * NS):
                t_ax, direction = axles[k]
                k += 1
                count = count + 1 if last_axle is not None and t_ax - last_axle < 10 * NS else 1
                last_axle = t_ax
                up = h.up_is_first_channel_first
                s1_to_s3 = (direction > 0) == up
                status = encode_status(der=not s1_to_s3, t_since_s=0)
                stamp = naive_time(t_ax).isoformat(timespec="milliseconds")
                lines.append((t_ax, f"{stamp} {h.id} {status:02X} {count % 256:02X}"))
                t = t_ax
            else:
                t = t + int(idle_every_s * NS)
                idle = last_axle is None or t - last_axle >= 10 * NS
                if idle:
                    status = encode_status(t_since_s=3)
                    lines.append(
                        (t, f"{naive_time(t).isoformat(timespec='milliseconds')} {h.id} {status:02X} {CHECK_BYTE:02X}")
                    )
    lines.sort(key=lambda x: x[0])
    title = "# trackside simulated intelligent-sensor frames: time sensor status count\n"
    head = "" if append and path.exists() else title
    with path.open("a" if append else "w", encoding="utf-8") as out:
        out.write(head + "\n".join(line for _, line in lines) + ("\n" if lines else ""))
    return len(lines)


def layout_text(layout: Layout) -> str:
    """The layout's own TOML text (shipped or from its file)."""
    name = layout.source.split(" ")[0]
    if name in BUILTIN:
        return resources.files("console.layouts").joinpath(BUILTIN[name]).read_text(encoding="utf-8")
    return Path(layout.source).read_text(encoding="utf-8")


def run_layout_text(sim: StationSim) -> str:
    """The layout the run writes: the one it used, with how its devices report (``[devices]``)."""
    return devices_text(layout_text(sim.layout), sim.layout, sim.devices)


def truth(sim: StationSim) -> dict[str, Any]:
    def t(ns: Any) -> str | None:
        return None if ns is None else iso(int(ns))

    return {
        "schema": "trackside.truth/1",
        "layout": sim.layout.name,
        "seed": sim.cfg.seed,
        "start": t(sim.cfg.start_ns),
        "end": t(sim.now_ns),
        "radio": {
            "spreading_factor": sim.cfg.radio.spreading_factor,
            "airtime_s": round(sim.cfg.radio.airtime_s(), 4),
            "report_period_s": round(sim.period_s, 3),
            "latency_s": round(sim.latency_s, 4),
            "loss": sim.cfg.gnss_loss,
        },
        "trains": [
            {
                "train": tr.id,
                "consist": tr.consist.id,
                "length_m": tr.consist.length_m,
                "axles": len(tr.consist.axles_m),
                "direction": tr.direction,
                "entered": t(sim.cfg.start_ns + int(tr.entered_s * NS)),
            }
            for tr in sim.trains
        ],
        "axles": [
            {
                "time": t(a.time_ns),
                "head": a.head,
                "train": a.train,
                "axle": a.axle,
                "speed_mps": round(a.speed_mps, 4),
                "direction": a.direction,
            }
            for a in sim.truth_axles
        ],
        "sections": {sid: [[t(ns), n] for ns, n in changes] for sid, changes in sim.truth_sections.items()},
        "crossings": [
            {
                "crossing": c["crossing"],
                "train": c["train"],
                "t_head_arrival": t(c["t_head_arrival_ns"]),
                "t_tail_clear": t(c["t_tail_clear_ns"]),
            }
            for c in sim.truth_crossings
            if c["t_head_arrival_ns"] is not None
        ],
        "partings": [p.to_dict() for p in sim.truth_partings],
        "faults": [
            {
                "kind": f.kind,
                "target": f.target,
                "start": t(sim.cfg.start_ns + int(f.start_s * NS)),
                "end": None if not np.isfinite(f.end_s) else t(sim.cfg.start_ns + int(f.end_s * NS)),
                "channel": f.channel,
            }
            for _, f in sim.injected
        ],
        **({} if sim.console is None else {"console_final": sim.console.section_states()}),
        **_slow_truth(sim),
    }


def _slow_truth(sim: StationSim) -> dict[str, Any]:
    """With slow faults or health registers: each threshold's crossing, and the bands the heads were set in."""
    if sim.health is None and not any(f.kind in SLOW_FAULT_KINDS for f in sim.faults):
        return {}
    out: dict[str, Any] = {
        "threshold_crossings": threshold_crossings(sim.health, sim.faults, sim.cfg.start_ns, sim.t_s),
    }
    if sim.health is not None:
        out["health_registers"] = {
            "period_s": sim.health.s.period_s,
            "heads": {
                head: {
                    f"Sys{c + 1}": {
                        "level": float(sim.health.base[i, c]),
                        "band": [float(sim.health.band_low[i, c]), float(sim.health.band_high[i, c])],
                    }
                    for c in (0, 1)
                }
                for i, head in enumerate(sim.health.heads)
            },
        }
    return out


def write_run(sim: StationSim, directory: Path) -> dict[str, Any]:
    """Everything, into ``directory`` (created); returns counts of what was written."""
    counts = write_logs(sim, directory)
    (directory / "layout.toml").write_text(run_layout_text(sim), encoding="utf-8")
    counts["truth.json"] = write_truth(sim, directory / "truth.json")
    return counts


def write_logs(
    sim: StationSim, directory: Path, *, since_ns: int | None = None, append: bool = False, health_only: bool = False
) -> dict[str, Any]:
    """The logs of what the simulator holds, into ``directory`` (created).  A multi-day run writes a day at a
    time: ``since_ns`` the day's start, ``append`` to the days before; ``health_only``: the diagnostic log alone."""
    directory.mkdir(parents=True, exist_ok=True)
    first = since_ns is None or since_ns <= sim.cfg.start_ns
    counts: dict[str, Any] = {
        "diagnostic.log": write_diagnostic(sim, directory / "diagnostic.log", identity=first, append=append)
    }
    if not health_only:
        counts["nmea"] = write_gnss(sim, directory, append=append)
        if sim.console is not None:
            counts["centre.tsv"] = write_centre_table(sim, directory / "centre.tsv", append=append)
        counts["sensor_frames.txt"] = write_frames(
            sim, directory / "sensor_frames.txt", since_ns=since_ns, append=append
        )
    return counts


def write_truth(sim: StationSim, path: Path) -> dict[str, int]:
    doc = truth(sim)
    path.write_text(json.dumps(doc, ensure_ascii=False, indent=1) + "\n", encoding="utf-8")
    return {"axles": len(doc["axles"]), "crossings": len(doc["crossings"])}
