"""``can:INTERFACE[:CHANNEL]`` — a live CAN bus through python-can.

``can:socketcan:vcan0`` on Linux, ``can:virtual:NAME`` for tests (python-can's
in-process bus).  Every frame is handed over as a
:class:`~console.inputs.base.CanFrame`; count frames (``0x180 + node``,
DLC 5, ``docs/frames.md``) carry a sequence byte, and a jump in a node's
sequence counts the frames in between as lost.  Error frames are counted
as malformed.  A bus that cannot be opened is retried with backoff.
"""

from __future__ import annotations

import math
import time
from typing import Any

from console.inputs.base import CanFrame, Source, SourceError, backoff_delays
from parsers.frames.can_report import COUNT_DLC, COUNT_ID_BASE, NODE_MAX, NODE_MIN

RECV_TIMEOUT_S = 0.5
# Receive times as nanoseconds fit an int64 up to 2262; a peer (udp_multicast, a virtual bus) sends any float.
LATEST_TIMESTAMP_S = 9.2e9


class CanSource(Source):
    kind = "can"

    def __init__(self, uri: str, interface: str, channel: str = "") -> None:
        super().__init__(uri)
        self.interface, self.channel = interface, channel
        self._bus: Any = None
        self._seq: dict[int, int] = {}

    def check(self) -> None:
        import can

        if self.interface not in can.VALID_INTERFACES:
            known = ", ".join(sorted(can.VALID_INTERFACES)[:12])
            raise SourceError(f"{self.uri}: unknown python-can interface {self.interface!r} (e.g. {known}…)")

    def run(self) -> None:
        import can

        delay = backoff_delays()
        while not self.stopping:
            try:
                bus = can.Bus(interface=self.interface, channel=self.channel or None, receive_own_messages=False)
            except (can.CanError, OSError, ValueError) as exc:
                self.set_connected(False, f"cannot open the bus: {exc}; retrying")
                if self.wait(delay()):
                    return
                continue
            self._bus = bus
            self.set_connected(True, f"listening on {self.interface}:{self.channel or '(default)'}")
            try:
                while not self.stopping:
                    msg = bus.recv(RECV_TIMEOUT_S)
                    if msg is not None:
                        self._frame(msg)
            except (can.CanError, OSError) as exc:
                self.set_connected(False, f"bus error: {exc}; reopening")
            finally:
                bus.shutdown()
                self._bus = None

    def _frame(self, msg: Any) -> None:
        if msg.is_error_frame:
            self.count_malformed()
            return
        data = bytes(msg.data)
        node = msg.arbitration_id - COUNT_ID_BASE
        if (
            not msg.is_extended_id
            and not msg.is_remote_frame
            and NODE_MIN <= node <= NODE_MAX
            and len(data) == COUNT_DLC
        ):
            seq = data[4]
            prev = self._seq.get(node)
            if prev is not None and seq != (prev + 1) % 256 and seq != prev:
                self.count_lost((seq - prev - 1) % 256)
            self._seq[node] = seq
        stamp = msg.timestamp
        if stamp and not (math.isfinite(stamp) and 0 < stamp < LATEST_TIMESTAMP_S):
            self.count_malformed()  # received, not lost; a NaN stopped the source, 1e12 s overflowed the engine
            return
        # Microseconds, as the log readers take them: the same frames give the same times live and recorded.
        t_ns = round(stamp * 1e6) * 1000 if stamp else time.time_ns()
        channel = str(msg.channel or self.channel)
        self.emit(
            CanFrame(
                self.uri,
                t_ns,
                msg.arbitration_id,
                data,
                channel,
                time.monotonic(),
                extended=bool(msg.is_extended_id),
                remote=bool(msg.is_remote_frame),
            )
        )
