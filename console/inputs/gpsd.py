"""``gpsd://HOST:PORT[/DEVICE]`` — position fixes from a running gpsd.

Speaks gpsd's JSON protocol: ``?WATCH={"enable":true,"json":true}`` (with
the device, if one is named) and reads one JSON object per line.  ``TPV``
reports with a 2D or 3D fix (``mode`` ≥ 2), a time and a position become
:class:`~console.inputs.base.GnssFix`; a TPV without a fix is counted, not
a position.  Lines that are not JSON objects are counted as malformed.
When gpsd goes away (restarted, the link dropped) the source reconnects
with doubling delays (0.2 s … 5 s) and watches again.
"""

from __future__ import annotations

import contextlib
import json
import math
import socket
import time
from typing import Any

from console.inputs.base import GnssFix, Source, backoff_delays
from parsers.gnss.lora import PayloadError, parse_time_rfc3339

READ_TIMEOUT_S = 0.5  # to notice stop(); gpsd sends at least once a second while a device reports
MAX_LINE_BYTES = 1 << 16


class GpsdSource(Source):
    kind = "gpsd"

    def __init__(
        self, uri: str, host: str, port: int, device: str | None = None, role: str = "", train: str = ""
    ) -> None:
        super().__init__(uri)
        self.host, self.port, self.device = host, port, device
        self.role, self.train = role, train
        self._sock: socket.socket | None = None
        self.connects = 0
        self.no_fix = 0

    def interrupt(self) -> None:
        sock = self._sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def run(self) -> None:
        delay = backoff_delays()
        while not self.stopping:
            try:
                sock = socket.create_connection((self.host, self.port), timeout=2.0)
            except OSError as exc:
                self.set_connected(False, f"cannot connect: {exc.strerror or exc}; retrying")
                if self.wait(delay()):
                    return
                continue
            self._sock = sock
            try:
                sock.settimeout(READ_TIMEOUT_S)
                watch: dict[str, Any] = {"enable": True, "json": True}
                if self.device:
                    watch["device"] = self.device
                sock.sendall(f"?WATCH={json.dumps(watch)}\n".encode())
                self.connects += 1
                self.set_connected(True, f"watching {self.device or 'all devices'}")
                delay = backoff_delays()
                self._read(sock)
            except OSError as exc:
                if not self.stopping:
                    self.set_connected(False, f"connection lost: {exc.strerror or exc}; reconnecting")
            finally:
                self._sock = None
                sock.close()
            if not self.stopping:
                self.set_connected(False, "gpsd closed the connection; reconnecting")
                if self.wait(delay()):
                    return

    def _read(self, sock: socket.socket) -> None:
        buf = b""
        skipping = False  # in a line too long to keep: dropped up to its end, counted once
        while not self.stopping:
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            if not data:
                if buf.strip() and not skipping:
                    self.count_malformed()  # gpsd went away mid-line
                return
            buf += data
            *lines, buf = buf.split(b"\n")
            if skipping and lines:
                lines, skipping = lines[1:], False  # the long line's tail
            if len(buf) > MAX_LINE_BYTES:
                if not skipping:
                    self.count_malformed()
                skipping, buf = True, b""
            for line in lines:
                if line.strip():
                    self._line(line)

    def _line(self, line: bytes) -> None:
        try:
            doc = json.loads(line)
        except ValueError:
            self.count_malformed()
            return
        if not isinstance(doc, dict):
            self.count_malformed()
            return
        if doc.get("class") != "TPV":
            return
        fix = self._fix(doc)
        if fix is None:
            self.no_fix += 1
            self.count_messages()
            return
        self.emit(fix)

    def _fix(self, doc: dict[str, Any]) -> GnssFix | None:
        mode = doc.get("mode")
        lat, lon = doc.get("lat"), doc.get("lon")
        if not isinstance(mode, int) or mode < 2 or not _finite(lat) or not _finite(lon):
            return None
        lat_deg, lon_deg = float(lat), float(lon)  # type: ignore[arg-type]  # _finite checked them
        if abs(lat_deg) > 90 or abs(lon_deg) > 180:
            self.count_malformed()  # as every other GNSS reader refuses it
            return None
        try:
            t_ns = parse_time_rfc3339(doc.get("time"))
        except PayloadError:
            self.count_malformed()
            return None
        if t_ns is None:
            return None  # a position without a time cannot be aged: not a fix for the crossing units
        return GnssFix(
            source=self.uri,
            device=str(doc.get("device") or self.device or f"gpsd@{self.host}:{self.port}"),
            t_fix_ns=t_ns,
            lat_deg=lat_deg,
            lon_deg=lon_deg,
            speed_mps=float(doc["speed"]) if _finite(doc.get("speed")) else math.nan,
            course_deg=float(doc["track"]) if _finite(doc.get("track")) else math.nan,
            received_mono=time.monotonic(),
            role=self.role,
            train=self.train,
            meta={"mode": mode},
        )


def _finite(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
