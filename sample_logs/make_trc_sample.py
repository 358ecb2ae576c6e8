"""Write can_counts.trc: the CAN frames of make_can_samples.py as a PEAK trace (version 2.1).

The count frames and foreign traffic are written by python-can's own
``TRCWriter``.  That writer drops remote and error frames, so the remote
frame of the other samples, one error frame and one bus status line are
put in as PEAK's PCAN-Explorer writes them (types ``RR``, ``ER``, ``ST``;
PEAK, "PCAN-Trace file format", version 2.1), and the messages are
numbered again.  The header line with the writer's absolute output path is
made relative, so the file is the same on every machine.  Deterministic:

    python sample_logs/make_trc_sample.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import can

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from make_can_samples import DAY, frames, messages  # noqa: E402  (the script beside this one)

ERROR_AT_S = 38.2  # an error frame on the bus (a stuff error, say), between count frames
STATUS_AT_S = 38.3  # the controller reports its error counters (bus status, not a frame)


def _offset_ms(seconds: float) -> float:
    return seconds * 1000.0


def main() -> None:
    os.environ["TZ"] = "UTC"
    time.tzset()
    msgs = messages(frames())
    remote = [m for m in msgs if m.is_remote_frame]
    with tempfile.TemporaryDirectory() as tmp:
        written = Path(tmp) / "can_counts.trc"
        writer = can.TRCWriter(written)
        for m in msgs:
            writer.on_message_received(m)  # the writer skips the remote frame (and says so in its log)
        writer.stop()
        text = written.read_text(encoding="utf-8").replace(str(written), "can_counts.trc")
    lines = text.splitlines()
    header = [line for line in lines if line.startswith(";")]
    # (offset ms, the columns after the offset), for the writer's lines and the ones put in
    rows = [line.split(maxsplit=2) for line in lines if line.strip() and not line.startswith(";")]
    timed = [(float(cols[1]), cols[2]) for cols in rows]
    start = DAY.timestamp()
    timed += [(_offset_ms(r.timestamp - start), f"RR  1     {r.arbitration_id:04X} Rx -  {r.dlc}") for r in remote]
    timed += [
        (_offset_ms(ERROR_AT_S), "ER  1          Rx -  5    01 00 00 08 00"),
        (_offset_ms(STATUS_AT_S), "ST  1          Rx -  4    00 00 00 08"),
    ]
    timed.sort(key=lambda item: item[0])
    out = header + [f"{n:>7} {ms:13.3f} {rest}" for n, (ms, rest) in enumerate(timed, 1)]
    (HERE / "can_counts.trc").write_bytes(("\r\n".join(out) + "\r\n").encode("ascii"))
    print(f"can_counts.trc: {len(out)} lines ({len(header)} header), {len(timed)} frames and bus events")


if __name__ == "__main__":
    main()
