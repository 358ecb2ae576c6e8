"""Write sensor_frames.txt, can_counts.log and can_counts.asc: one frame sequence, three formats.

Two intelligent axle-counting sensors (*Design of intelligent axle counting sensor*), AC07 and AC08 (CAN nodes
7 and 8: count ids 0x187 and 0x188), bound a section.  The same frames are
written as the text frame format and, with foreign bus traffic around them,
through python-can's own candump and ASC writers; docs/frames.md describes
the layouts and sample_logs/README.md the truths.  Deterministic:

    python sample_logs/make_can_samples.py
"""

from __future__ import annotations

import datetime as dt
import io
import os
import time
from pathlib import Path

import can

HERE = Path(__file__).resolve().parent
DAY = dt.datetime(2021, 6, 6, 10, 15, 0, tzinfo=dt.UTC)
NODES = {"AC07": 7, "AC08": 8}
TOTAL_AT_START = {"AC07": 1000, "AC08": 2000}  # cumulative axles since power-up


def status(*, ses2: bool = False, der: bool = False, err: bool = False, t: int = 0) -> int:
    """Byte 1, MSB first: SYS SES1 SES2 SES3 DER ERR T1 T2."""
    return 0x20 * ses2 + 0x08 * der + 0x04 * err + t


CLEAR = (status(t=3), 0xA5)


def frames() -> list[tuple[float, str, int, int]]:
    """(seconds after 10:15:00, sensor, byte 1, byte 2), in time order."""
    out: list[tuple[float, str, int, int]] = []
    # Both sensors in their self-test loop (section clear), every 2 s.
    for s in range(0, 10, 2):
        out += [(s, "AC07", *CLEAR), (s + 0.25, "AC08", *CLEAR)]
    # A train of 8 axles passes AC07 S1→S3 (up); two axles fall in one frame interval twice.
    for s, count in ((10.0, 1), (10.5, 2), (11.0, 4), (11.5, 5), (12.0, 6), (12.5, 8)):
        out.append((s, "AC07", status(t=0), count))
    out += [(13.5, "AC07", status(t=1), 8), (14.5, "AC07", status(t=2), 8), (15.5, "AC07", status(t=3), 8)]
    out.append((16.0, "AC07", *CLEAR))
    out += [(s + 0.25, "AC08", *CLEAR) for s in (10, 12, 14, 16, 18)]
    out += [(18.0, "AC07", *CLEAR)]
    # The train reaches AC08; element S2 fails during the passage (SES2, and ERR while the vote split).
    out += [
        (20.0, "AC08", status(), 1),
        (20.5, "AC08", status(ses2=True, err=True), 2),
        (21.0, "AC08", status(ses2=True, err=True), 4),
        (21.5, "AC08", status(ses2=True), 6),
        (22.0, "AC08", status(ses2=True), 8),
        (23.0, "AC08", status(ses2=True, t=1), 8),
        (24.0, "AC08", *CLEAR),  # S2 passes its self-test again
        (26.0, "AC08", *CLEAR),
    ]
    out += [(s, "AC07", *CLEAR) for s in (20, 22, 24, 26, 28)]
    # A trolley of 4 axles runs back over AC07, S3→S1 (down).
    for s, count in ((30.0, 1), (30.5, 2), (31.0, 3), (31.5, 4)):
        out.append((s, "AC07", status(der=True), count))
    out += [(32.5, "AC07", status(der=True, t=1), 4), (33.0, "AC07", *CLEAR)]
    out += [(s, "AC07", *CLEAR) for s in (35, 37, 39, 41, 43, 45, 47, 49)]
    # AC08 was silent from 10:15:26 to 10:15:45 (19 s): contact lost, then back.
    out += [(s + 0.25, "AC08", *CLEAR) for s in (45, 47, 49)]
    return sorted(out, key=lambda f: f[0])


def stamp(seconds: float) -> dt.datetime:
    return DAY + dt.timedelta(seconds=seconds)


def write_text(path: Path, rows: list[tuple[float, str, int, int]]) -> None:
    lines = [
        "# Intelligent axle-counting sensor frames (Design of intelligent axle counting sensor), see docs/frames.md",
        "# <time> <sensor> <byte 1: SYS SES1 SES2 SES3 DER ERR T1 T2><byte 2: count or check byte A5>",
        "",
    ]
    for s, sensor, b1, b2 in rows:
        t = stamp(s)
        lines.append(f"{t:%Y-%m-%dT%H:%M:%S}.{t.microsecond // 1000:03d} {sensor} {b1:02X}{b2:02X}")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8", newline="\n")


def messages(rows: list[tuple[float, str, int, int]]) -> list[can.Message]:
    """The count frames with sequence numbers and totals, plus foreign traffic."""
    seq = dict.fromkeys(NODES, 0)
    total = dict(TOTAL_AT_START)
    last = {sensor: 0 for sensor in NODES}  # count before each frame (0 after a clear)
    out: list[can.Message] = []
    for s, sensor, b1, b2 in rows:
        if sensor == "AC08" and s >= 45 and seq[sensor] > 20:  # AC08 restarted after the contact loss
            seq[sensor] = 0
        count = 0 if b2 == 0xA5 else b2
        total[sensor] = (total[sensor] + max(count - last[sensor], 0)) % 65536
        last[sensor] = count
        data = bytes([b1, b2, total[sensor] & 0xFF, total[sensor] >> 8, seq[sensor]])
        seq[sensor] = (seq[sensor] + 1) % 256
        out.append(
            can.Message(
                timestamp=stamp(s).timestamp(), arbitration_id=0x180 + NODES[sensor], data=data, is_extended_id=False
            )
        )
    # Foreign traffic on the same bus: a heartbeat of node 1 every 5 s, an
    # extended-id frame and a remote frame asking node 7 for its count.
    for s in range(0, 50, 5):
        out.append(
            can.Message(timestamp=stamp(s + 0.1).timestamp(), arbitration_id=0x701, data=b"\x05", is_extended_id=False)
        )
    out.append(
        can.Message(
            timestamp=stamp(17.3).timestamp(), arbitration_id=0x18FEF100, is_extended_id=True, data=bytes(range(8))
        )
    )
    out.append(
        can.Message(
            timestamp=stamp(27.7).timestamp(), arbitration_id=0x187, is_remote_frame=True, dlc=5, is_extended_id=False
        )
    )
    return sorted(out, key=lambda m: m.timestamp)


def write_candump(path: Path, msgs: list[can.Message]) -> None:
    with can.CanutilsLogWriter(path, channel="can0") as writer:
        for m in msgs:
            writer.on_message_received(m)


def write_asc(path: Path, msgs: list[can.Message]) -> None:
    buf = io.StringIO()
    writer = can.ASCWriter(buf)
    for m in msgs:
        writer.on_message_received(m)
    writer.file.write("End TriggerBlock\n")  # what stop() writes; stop() would close the buffer
    lines = buf.getvalue().splitlines()
    # The writer dates the file header with the wall clock now; use the
    # measurement start instead, so the file is the same on every run.
    trigger = next(line for line in lines if line.startswith("Begin Triggerblock "))
    lines[0] = "date " + trigger.removeprefix("Begin Triggerblock ")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8", newline="\n")


def main() -> None:
    os.environ["TZ"] = "UTC"  # python-can's ASC writer dates the measurement in local time
    time.tzset()
    rows = frames()
    write_text(HERE / "sensor_frames.txt", rows)
    msgs = messages(rows)
    write_candump(HERE / "can_counts.log", msgs)
    write_asc(HERE / "can_counts.asc", msgs)


if __name__ == "__main__":
    main()
