"""Count frames arriving live → detection events → sections, frame passages, health.

Frames come from a CAN bus one by one (:meth:`FrameFollow.add`, ``can:``) or
from a followed CAN log or sensor frame log a block at a time
(:meth:`FrameFollow.add_rows`, ``file:``).  The batch path reads a log into a
frame table (:func:`parsers.frames.can.parse_can`, :func:`parsers.frames.sensor.parse_frames`)
and turns it into detection events with
:func:`~console.analysis.frame_events.frames_to_events`.  Live frames go
through that same function, a block at a time: each block of a sensor's
frames is preceded by the sensor's previous frame (the *context* row), so
counts, status edges, sequence numbers and contact gaps are judged against
what came before, exactly as in one table.  The context row itself is not
new: the events the function gives *for it* (its status bits and ERR seen
against "all normal before the first frame") are taken off.

Two things the batch path decides with hindsight are decided as data arrives:

* contact lost: batch, a sensor silent at the end of the data while others
  still report is lost at its last frame + the timeout.  Live, that is
  decided as soon as the bus clock (the latest count frame of any sensor)
  passes that moment; when the sensor speaks again the gap's loss is not
  repeated, only its restoration is added.  So the events are the batch
  ones, whenever the data stops;
* byte 2 = 0xA5 after a count: the check byte (a clear) or the count 165.
  Batch looks at the next count too (``parsers.frames.table.check_byte_mask``);
  live uses what a block holds, and at its end the rule the batch reader
  uses at the end of a file (0xA5 right after 164 is 165, else a clear).
  A clear is announced when it arrives, not one train later; only a count
  that then jumps past 165 (``160, A5, 170``) reads differently from batch.

Events go in time order into one :class:`~console.analysis.sections.engine.SectionEngine`
(section changes), a sensor's axles between two clears make a frame
passage, and channel faults become health findings, as in batch.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import pandas as pd

from console.analysis.events.detection import DOWN, UP, DetectionEvent, EventKind, sort_events
from console.analysis.frame_events import frames_to_events
from console.analysis.health.channel_faults import channel_fault_findings
from console.analysis.sections.engine import SectionEngine
from console.analysis.sections.state import SectionState, Transition
from console.analysis.timefmt import iso
from console.inputs.base import CanFrame, FrameRows
from console.layout import Layout
from console.sinks.tables.event_lines import section_event
from parsers.frames.can_report import COUNT_DLC, COUNT_ID_BASE, NODE_MAX, NODE_MIN, default_sensor_name
from parsers.frames.table import CHECK_BYTE, DER_BIT, check_byte_mask, decode_status
from parsers.report import escape_text
from parsers.units import NS

Emit = Callable[[dict[str, Any]], None]
MAX_BUFFERED = 4096  # frames held between flushes (a burst is analysed in blocks of this size)
_STATUS_CHANNELS = (("sys", None), ("ses1", 1), ("ses2", 2), ("ses3", 3))
_MAJORITY = "majority not unanimous"  # frames_to_events' COUNT_ERROR for ERR turning 1


class CountsListener(Protocol):
    """What else follows the counting heads (the integrity monitor): events in the section engine's order."""

    def detection(self, e: DetectionEvent) -> None: ...

    def transition(self, tr: Transition) -> None: ...


@dataclass
class _Sensor:
    context: dict[str, Any]  # the last accepted count frame, as a row of the frame table
    context_frame: pd.DataFrame | None = None  # the same row as a one-row table, its column types kept
    last_count: tuple[int, int] | None = None  # (time, byte 2) of its last non-0xA5 frame: P of the 0xA5 rule
    lost_announced: bool = False
    source: str = "can"  # what its frames come from: can | frame (text frames), as the batch events say
    axles: int = 0
    first_axle_ns: int = 0
    up: int = 0
    down: int = 0


@dataclass
class FrameFollowStats:
    frames: int = 0
    count_frames: int = 0
    rejected: int = 0
    events: int = 0
    passages: int = 0
    section_changes: int = 0
    health_findings: int = 0
    by_source: dict[str, int] = field(default_factory=dict)  # frames received per source: their "line" numbers


class FrameFollow:
    """The CAN half of the live engine: :meth:`add` frames, :meth:`flush` them into events."""

    def __init__(
        self,
        layout: Layout | None,
        emit: Emit,
        *,
        comm_timeout_s: float = 10.0,
        sensor_names: Mapping[int, str] | None = None,
    ) -> None:
        self.layout = layout
        self.emit = emit
        self.timeout_ns = round(comm_timeout_s * NS)
        self.names = dict(sensor_names or {})
        self.up: dict[str, bool] | bool = (
            {h.id: h.up_is_first_channel_first for h in layout.heads} if layout is not None else True
        )
        self.stats = FrameFollowStats()
        self.sensors: dict[str, _Sensor] = {}
        self.clock_ns: int | None = None
        self.sections: SectionEngine | None = None
        self._buffer: list[CanFrame] = []
        self._numbers: list[int] = []
        self._seen_findings: set[tuple[str, str | None, int | None]] = set()
        self.listener: CountsListener | None = None  # also gets every event and section change

    # -- input -----------------------------------------------------------
    def add(self, frame: CanFrame) -> None:
        n = self.stats.by_source.get(frame.source, 0) + 1
        self.stats.by_source[frame.source] = n
        self.stats.frames += 1
        self._buffer.append(frame)
        self._numbers.append(n)
        if len(self._buffer) >= MAX_BUFFERED:
            self.flush()

    def flush(self) -> None:
        """Analyse the frames received since the last flush (the engine calls it when its queue is empty)."""
        if not self._buffer:
            return
        block, numbers = self._buffer, self._numbers
        self._buffer, self._numbers = [], []
        self._analyse(self._count_table(block, numbers), "can")

    def add_rows(self, rows: FrameRows) -> None:
        """Count frames read from a followed CAN or frame log: analysed at once (a block of the file)."""
        self.flush()  # frames of a bus that came before, first
        self.stats.frames += len(rows)

        def reject(i: int, category: str, reason: str) -> None:
            line = int(rows.line[i])
            self._emit_rejection(rows.file, line, category, reason, escape_text(rows.text.get(line, b"")))

        extra = {k: v for k, v in (("total", rows.total), ("seq", rows.seq)) if v is not None}
        self._analyse(self._table(rows.time_ns, rows.sensor, rows.status, rows.byte2, extra, reject), rows.kind)

    def _analyse(self, table: pd.DataFrame, source: str) -> None:
        events: list[DetectionEvent] = []
        if len(table):
            self.stats.count_frames += len(table)
            self.clock_ns = max(self.clock_ns or 0, int(table["time_ns"].max()))
            for sensor, part in table.groupby("sensor", sort=True):  # per sensor (a few), not per frame
                events += self._sensor_block(str(sensor), part.drop(columns="time_ns"), source)
        events += self._silences()
        self._publish(sort_events(events))

    def finish(self) -> None:
        self.flush()

    # -- frames → a frame table ------------------------------------------
    def _count_table(self, block: list[CanFrame], numbers: list[int]) -> pd.DataFrame:
        """The block's count frames as frame-table rows (vectorized); bad count frames rejected."""
        n = len(block)
        can_id = np.fromiter((f.arbitration_id for f in block), np.int64, n)
        flags = np.fromiter((f.extended or f.remote for f in block), bool, n)
        length = np.fromiter((len(f.data) for f in block), np.int64, n)
        t_ns = np.fromiter((f.t_ns for f in block), np.int64, n)
        data = np.frombuffer(b"".join(f.data[:8].ljust(8, b"\0") for f in block), np.uint8).reshape(n, 8)
        node = can_id - COUNT_ID_BASE
        count_id = ~flags & (node >= NODE_MIN) & (node <= NODE_MAX)
        bad_dlc = count_id & (length != COUNT_DLC)
        for i in np.flatnonzero(bad_dlc).tolist():  # rare: one line per bad frame
            reason = f"count frame 0x{can_id[i]:03X}: expected DLC {COUNT_DLC}, found {length[i]} data bytes"
            self._reject(block[i], numbers[i], "dlc", reason)
        keep = np.flatnonzero(count_id & ~bad_dlc)
        sensor = np.array([self.names.get(k, default_sensor_name(k)) for k in node[keep].tolist()], dtype=object)
        d = data[keep]
        extra = {"total": d[:, 2].astype(np.uint16) | (d[:, 3].astype(np.uint16) << 8), "seq": d[:, 4]}

        def reject(j: int, category: str, reason: str) -> None:
            i = int(keep[j])
            self._reject(block[i], numbers[i], category, reason)

        return self._table(t_ns[keep], sensor, d[:, 0], d[:, 1], extra, reject)

    def _table(
        self,
        t_ns: np.ndarray,
        sensor: np.ndarray,
        status: np.ndarray,
        byte2: np.ndarray,
        extra: Mapping[str, np.ndarray],
        reject: Callable[[int, str, str], None],
    ) -> pd.DataFrame:
        """Count frames → frame-table rows in time order (stably); check-byte frames with DER = 1 rejected."""
        order = np.argsort(t_ns, kind="stable")
        check = self._check(sensor[order], t_ns[order], byte2[order])
        broken = check & ((status[order] & DER_BIT) != 0)
        for j in np.flatnonzero(broken).tolist():
            reason = "byte 2 is the check byte 0xA5 here (no count reaching 165 around it) but DER = 1"
            reject(int(order[j]), "protocol", reason + "; a check-byte frame has DER = 0")
        rows, ok = order[~broken], ~broken
        return pd.DataFrame(
            {
                "time_ns": t_ns[rows],
                "time": pd.to_datetime(t_ns[rows], unit="ns"),
                "sensor": sensor[order][ok],
                "status": status[rows],
                "byte2": byte2[rows],
                "check": check[ok],
                **decode_status(status[rows]),
                **{k: np.asarray(v)[rows] for k, v in extra.items()},
            }
        )

    def _check(self, sensor: np.ndarray, t_ns: np.ndarray, byte2: np.ndarray) -> np.ndarray:
        """0xA5 as check byte or count, per sensor: the batch rule over each sensor's last count + this block."""
        out = np.zeros(len(byte2), bool)
        for name in sorted(set(sensor.tolist())):  # per sensor
            idx = np.flatnonzero(sensor == name)
            st = self.sensors.get(name)
            prior = st.last_count if st is not None else None
            t = t_ns[idx] if prior is None else np.r_[prior[0], t_ns[idx]]
            b = byte2[idx] if prior is None else np.r_[prior[1], byte2[idx]].astype(np.uint8)
            out[idx] = check_byte_mask(np.zeros(len(b), np.int64), t, b)[0 if prior is None else 1 :]
        return out

    def _reject(self, frame: CanFrame, number: int, category: str, reason: str) -> None:
        text = f"{frame.arbitration_id:03X}#{frame.data.hex().upper()}"
        self._emit_rejection(frame.source, number, category, reason, text)

    def _emit_rejection(self, file: str, line: int, category: str, reason: str, text: str) -> None:
        self.stats.rejected += 1
        self.emit(
            {"type": "source", "kind": "rejected", "file": file, "line": line, "category": category}
            | {"reason": reason, "text": text}
        )

    # -- a sensor's block → events ---------------------------------------
    def _sensor_block(self, name: str, part: pd.DataFrame, source: str) -> list[DetectionEvent]:
        st = self.sensors.get(name)
        ctx = st.context if st is not None else None
        before = st.context_frame if st is not None else None
        # The context row kept as a table: concatenated with its column types, nothing to convert (a
        # row rebuilt from a dict would be object columns, and converting them took most of a flush).
        table = part if before is None else pd.concat([before, part], ignore_index=True)
        events = frames_to_events(table, up_is_s1_to_s3=self.up, comm_timeout_s=self.timeout_ns / NS, source=source)
        if ctx is not None and st is not None:
            events = self._without_context(events, ctx, st)
        last = part.iloc[-1]
        if st is None:
            st = self.sensors[name] = _Sensor(context={}, source=source)
        st.context = {str(k): v for k, v in last.items()}
        st.context_frame = part.iloc[[-1]]
        counts = part[part["byte2"] != CHECK_BYTE]
        if len(counts):
            st.last_count = (int(counts["time"].iloc[-1].value), int(counts["byte2"].iloc[-1]))
        return events

    def _without_context(self, events: list[DetectionEvent], ctx: dict[str, Any], st: _Sensor) -> list[DetectionEvent]:
        """Take off what was said of the context row again, and a contact loss already announced."""
        t_ctx = int(pd.Timestamp(ctx["time"]).value)
        # The context row's status bits and ERR, seen against "all normal before": said when it was new.
        again = {(EventKind.CHANNEL_FAULT, ch) for bit, ch in _STATUS_CHANNELS if ctx[bit]}
        out = []
        for e in events:
            if e.time_ns == t_ctx and (
                (e.kind is EventKind.CHANNEL_FAULT and (e.kind, e.channel) in again)
                or (e.kind is EventKind.COUNT_ERROR and ctx["err"] and e.detail.startswith(_MAJORITY))
            ):
                continue
            if st.lost_announced and e.kind is EventKind.POWER_LOSS and e.time_ns == t_ctx + self.timeout_ns:
                continue
            out.append(e)
        st.lost_announced = False
        return out

    def _silences(self) -> list[DetectionEvent]:
        """Sensors silent for longer than the timeout by the bus clock: contact lost (once)."""
        out: list[DetectionEvent] = []
        if self.clock_ns is None:
            return out
        for name, st in self.sensors.items():
            t_last = int(pd.Timestamp(st.context["time"]).value)
            if not st.lost_announced and self.clock_ns - t_last > self.timeout_ns:
                st.lost_announced = True
                detail = f"no frames for {self.timeout_ns / NS:g} s"
                out.append(
                    DetectionEvent(
                        t_last + self.timeout_ns, EventKind.POWER_LOSS, name, source=st.source, detail=detail
                    )
                )
        return out

    # -- events → sections, passages, health -------------------------------
    def _publish(self, events: list[DetectionEvent]) -> None:
        self.stats.events += len(events)
        for e in events:  # per event: the section rules are sequential
            self._passage(e)
            if self.listener is not None:
                self.listener.detection(e)
            if self.layout is not None and self.layout.sections:
                if self.sections is None:
                    self.sections = SectionEngine(self.layout, initial=SectionState.PREPARATORY, start_ns=e.time_ns)
                    for tr in self.sections.transitions:  # the starting state, as the batch timeline begins
                        self._section(tr)
                for tr in self.sections.step(e):
                    self._section(tr)
        if self.sections is not None:
            drain_history(self.sections)
        # Findings come from channel faults only (frames give no single-channel events): most blocks have none.
        faults = [e for e in events if e.kind in (EventKind.CHANNEL_FAULT, EventKind.CHANNEL_OK)]
        for f in channel_fault_findings(faults) if any(e.kind is EventKind.CHANNEL_FAULT for e in faults) else []:
            key = (f.rule, f.counting_head, f.channel)
            if key in self._seen_findings or str(f.severity) == "info":
                continue
            self._seen_findings.add(key)
            self.stats.health_findings += 1
            self.emit({"type": "health", **f.to_dict()})

    def _passage(self, e: DetectionEvent) -> None:
        """A sensor's axles from its first after a clear up to the next clear: one passage."""
        st = self.sensors.get(e.head)
        if st is None:
            return
        if e.kind is EventKind.AXLE:
            if not st.axles:
                st.first_axle_ns = e.time_ns
            st.axles += 1
            st.up += e.direction == UP
            st.down += e.direction == DOWN
        elif e.kind is EventKind.HEAD_FREE and st.axles:
            direction = "up" if st.up > st.down else "down" if st.down > st.up else None
            self.stats.passages += 1
            self.emit(
                {
                    "type": "passage",
                    "source": st.source,
                    "counting_head": e.head,
                    "start": iso(st.first_axle_ns),
                    "end": iso(e.time_ns),
                    "duration_s": round((e.time_ns - st.first_axle_ns) / NS, 3),
                    "axles": st.axles,
                    "direction": direction,
                }
            )
            st.axles = st.up = st.down = 0

    def _section(self, tr: Transition) -> None:
        self.stats.section_changes += 1
        if self.listener is not None:
            self.listener.transition(tr)
        self.emit(section_event(tr))

    def section_states(self) -> dict[str, tuple[str, int]]:
        if self.sections is None:
            return {}
        return {sid: (str(s.state), s.count) for sid, s in self.sections.sections.items()}


def drain_history(engine: SectionEngine) -> None:
    """Drop the section engine's history: live, each change is emitted as it happens, and a
    history kept for days (every axle in the ledger) would grow without bound."""
    engine.transitions.clear()
    engine.ledger.clear()
    engine.resets.clear()
