"""The common shape of a live source: a thread that hands items to a sink.

Items are plain frozen dataclasses, cheap to queue.  A source never raises
out of its thread for bad input: malformed messages are counted and noted,
a lost connection is retried with backoff, and only a setup error (a URI
that cannot work at all) is a :class:`SourceError` from :meth:`Source.start`.
"""

from __future__ import annotations

import math
import threading
import time
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np


class SourceError(Exception):
    """A source that cannot be set up (bad URI, missing interface): exit 2."""


@dataclass(frozen=True, slots=True)
class LineBlock:
    """Complete lines appended to a followed file (each ends with a newline)."""

    source: str
    file: str  # the followed path, with ``#N`` from the Nth file after a rotation
    first_line: int  # 1-based line number of the block's first line in that file
    data: bytes
    received_mono: float  # time.monotonic() when read, for latency figures


@dataclass(frozen=True, slots=True)
class GnssFix:
    """One position report of a unit (gpsd TPV or a LoRaWAN uplink)."""

    source: str
    device: str  # gpsd device path or the LoRaWAN DevEUI
    t_fix_ns: int  # when the receiver measured it (its clock)
    lat_deg: float
    lon_deg: float
    speed_mps: float  # NaN when not reported
    course_deg: float  # NaN when not reported
    received_mono: float
    role: str = ""  # head | eot when the unit says so (LoRa payload), else ""
    train: str = ""  # train the unit rides on, when known
    battery_pct: float | None = None
    meta: dict[str, Any] = field(default_factory=dict)  # fCnt, rssi, snr, gateways…
    recorded: bool = False  # read from a file: its own clock, not the console's, says when it happened
    brake_pipe_bar: float = math.nan  # the unit's end of the brake pipe (LoRa payload version 2), NaN: none
    emergency: bool = False  # the unit's emergency status: its brake pipe venting (sent at once)


@dataclass(frozen=True, slots=True)
class CanFrame:
    """One frame from a CAN bus (error frames are counted by the source, not handed over)."""

    source: str
    t_ns: int  # the bus's receive time, to the microsecond as in recorded logs
    arbitration_id: int
    data: bytes
    channel: str
    received_mono: float
    extended: bool = False  # 29-bit id
    remote: bool = False  # RTR: no payload


@dataclass(frozen=True, slots=True, eq=False)
class FrameRows:
    """Count frames read from a followed file (a CAN log or a sensor frame log), a block at a time.

    Columns as the batch frame table has them (``parsers.frames.sensor``): one entry
    per frame, in line order.  ``kind`` is ``can`` (CAN count frames, with
    ``total`` and ``seq``) or ``frame`` (intelligent-sensor text frames).
    """

    source: str
    file: str  # the followed path, with ``#N`` from the Nth file after a rotation
    kind: str  # can | frame
    time_ns: np.ndarray  # int64, as written (no zone: naive)
    sensor: np.ndarray  # object: the sensor's name
    status: np.ndarray  # uint8
    byte2: np.ndarray  # uint8: the count or the check byte 0xA5
    line: np.ndarray  # int64
    received_mono: float
    total: np.ndarray | None = None  # CAN: uint16, cumulative axles
    seq: np.ndarray | None = None  # CAN: uint8, sequence number
    can_id: np.ndarray | None = None  # CAN: the frame's id (0x180 + node)
    text: dict[int, bytes] = field(default_factory=dict)  # line → its text, for frames the follower may reject

    def __len__(self) -> int:
        return len(self.line)


@dataclass(frozen=True, slots=True)
class SourceNote:
    """Something about the transport itself: connected, lost, malformed, rotated…"""

    source: str
    # connected | disconnected | ended | malformed | lost | duplicate | rotated | truncated | unrecognised | info
    kind: str
    detail: str
    received_mono: float


Item = LineBlock | GnssFix | CanFrame | FrameRows | SourceNote
Sink = Callable[[Item], None]


@dataclass(frozen=True)
class SourceStatus:
    """One line of the station view's source panel."""

    uri: str
    connected: bool
    last_message_age_s: float | None
    rate_per_s: float
    messages: int
    lost: int
    malformed: int
    duplicates: int
    detail: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "uri": self.uri,
            "connected": self.connected,
            "last_message_age_s": None if self.last_message_age_s is None else round(self.last_message_age_s, 3),
            "rate_per_s": round(self.rate_per_s, 2),
            "messages": self.messages,
            "lost": self.lost,
            "malformed": self.malformed,
            "duplicates": self.duplicates,
            "detail": self.detail,
        }


RATE_WINDOW_S = 10.0


class Source(ABC):
    """A live feed run in a daemon thread; :meth:`stop` ends it within about a second."""

    kind = "source"
    # May its thread be made to wait for the engine (console.live.backlog)?  Not a network source: its
    # sender sets the rate, and holding it would only lose its messages elsewhere.
    waits_for_room = False

    def __init__(self, uri: str) -> None:
        self.uri = uri
        self._stop = threading.Event()
        self.abandoned = False  # stopping without the last read: what it would deliver is not wanted
        self.input_ended = False  # its input ended for good (a pipe's writer closed it): it delivers no more
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self._connected = False
        self.ever_connected = False  # follow --idle-exit: a source never up is an error, not a wait
        self._told = False  # the first state is always told: a source that cannot open says so at once
        self._detail = "starting"
        self._last_mono: float | None = None
        self._messages = 0
        self._lost = 0
        self._malformed = 0
        self._duplicates = 0
        self._recent: deque[tuple[float, int]] = deque()
        self._sink: Sink | None = None

    # -- lifecycle -----------------------------------------------------------
    def start(self, sink: Sink) -> None:
        self.check()
        self._sink = sink
        self._thread = threading.Thread(target=self._main, name=f"source {self.uri}", daemon=True)
        self._thread.start()

    def check(self) -> None:  # noqa: B027 - optional hook
        """Raise :class:`SourceError` if the source cannot work at all (called before the thread)."""

    def stop(self, timeout_s: float = 3.0) -> None:
        self.request_stop()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def request_stop(self) -> None:
        """Ask the thread to end, without waiting: it may still deliver what it reads on its way out
        (a followed file is read to its end)."""
        self._stop.set()
        self.interrupt()

    def abandon(self) -> None:
        """Stop without the last read (a second Ctrl-C, a closed view): a followed file is not read on to its end."""
        self.abandoned = True
        self.request_stop()

    @property
    def running(self) -> bool:
        """The source's thread has not ended yet."""
        return self._thread is not None and self._thread.is_alive()

    def interrupt(self) -> None:  # noqa: B027 - optional hook
        """Wake a thread blocked on I/O (close a socket…)."""

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    def _main(self) -> None:
        try:
            self.run()
        except Exception as exc:  # a bug in a source must not kill the console silently
            self.note("disconnected", f"source stopped: {type(exc).__name__}: {exc}")
            self.set_connected(False, f"stopped: {exc}")

    @abstractmethod
    def run(self) -> None:
        """The thread body: loop until :attr:`stopping`, calling :meth:`emit`."""

    # -- reporting -----------------------------------------------------------
    def emit(self, item: Item, messages: int = 1) -> None:
        if messages:
            self.count_messages(messages)
        if self._sink is not None:
            self._sink(item)

    def note(self, kind: str, detail: str) -> None:
        if self._sink is not None:
            self._sink(SourceNote(self.uri, kind, detail, time.monotonic()))

    def count_messages(self, n: int = 1) -> None:
        now = time.monotonic()
        with self._lock:
            self._messages += n
            self._last_mono = now
            self._recent.append((now, n))
            while self._recent and self._recent[0][0] < now - RATE_WINDOW_S:
                self._recent.popleft()

    @property
    def message_count(self) -> int:
        """Messages (lines of a file) received so far: cheap, for a caller that asks after every item."""
        return self._messages

    def count_lost(self, n: int) -> None:
        with self._lock:
            self._lost += n

    def count_malformed(self, n: int = 1) -> None:
        with self._lock:
            self._malformed += n

    def count_duplicate(self, n: int = 1) -> None:
        with self._lock:
            self._duplicates += n

    def set_connected(self, connected: bool, detail: str) -> None:
        with self._lock:
            changed = connected != self._connected or not self._told
            self._connected, self._told = connected, True
            self.ever_connected = self.ever_connected or connected
            self._detail = detail
        if changed:
            self.note("connected" if connected else "disconnected", detail)

    def set_ended(self, detail: str) -> None:
        """Its input ended for good (a stream's writer closed it): told once, as an ``ended`` note."""
        with self._lock:
            self._connected, self._told, self._detail = False, True, f"ended: {detail}"
        self.note("ended", detail)
        self.input_ended = True  # after every item of it was handed over

    def status(self) -> SourceStatus:
        now = time.monotonic()
        with self._lock:
            recent = sum(n for t, n in self._recent if t >= now - RATE_WINDOW_S)
            return SourceStatus(
                uri=self.uri,
                connected=self._connected,
                last_message_age_s=None if self._last_mono is None else now - self._last_mono,
                rate_per_s=recent / RATE_WINDOW_S,
                messages=self._messages,
                lost=self._lost,
                malformed=self._malformed,
                duplicates=self._duplicates,
                detail=self._detail,
            )

    def file_reports(self) -> list[dict[str, Any]]:
        """Line accounting of the files this source read itself (a followed GNSS or CAN log), for the summary."""
        return []

    def wait(self, seconds: float) -> bool:
        """Sleep unless stopped; True if stopping."""
        return self._stop.wait(seconds)


def backoff_delays(first_s: float = 0.2, max_s: float = 5.0) -> Callable[[], float]:
    """Reconnect delays doubling from ``first_s`` up to ``max_s`` (call ``reset`` by making a new one)."""
    state = {"next": first_s}

    def nxt() -> float:
        d = state["next"]
        state["next"] = min(max_s, d * 2)
        return d

    return nxt
