"""Intelligent-sensor and CAN count frames → detection events.

A frame reports a sensor's state at one moment: its status bits and its
axle count since the section was last cleared (or the check byte 0xA5 while
it is clear).  Per sensor, in time order, changes between consecutive frames
become events (see ``docs/frames.md``):

* the count rising from one frame to the next → that many ``AXLE`` events,
  at the later frame, in the direction its DER bit gives; after a check
  byte the count starts again from 0.  The first frame of a sensor only
  sets the baseline: axles counted before the data began are not invented;
* the count dropping to the check byte → the section is clear at that
  sensor (``HEAD_FREE``);
* the count going down without a clear, a lost or repeated CAN sequence
  number, a cumulative total that disagrees with the count, or ERR turning
  1 (the majority was not unanimous) → ``COUNT_ERROR``;
* SES1..3 turning 1 → ``CHANNEL_FAULT`` for that element, back to 0 →
  ``CHANNEL_OK``; SYS likewise for the whole sensor (channel None);
* no frame for longer than ``comm_timeout_s`` → ``POWER_LOSS`` at the last
  frame + the timeout; ``POWER_RESTORED`` when frames resume.  A sensor
  silent at the end of the data, while others still report, is lost too.

Text frames and CAN count frames go through the same code, so the same
frames give the same events (only ``source`` differs).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from console.analysis.events.detection import DOWN, UNKNOWN, UP, DetectionEvent, EventKind, sort_events
from parsers.frames.table import check_byte_mask
from parsers.units import NS

COUNT_MODULO = 256  # byte 2 is one byte: a long train's count wraps 255 → 0
# A fall from this high to this low is the byte wrapping, not the count going back.
WRAP_FROM, WRAP_TO = 224, 32
SEQ_MODULO = 256
TOTAL_MODULO = 1 << 16

# Order of simultaneous events from one frame: restore contact, faults,
# doubts about the count, the axles, then the clear.
_RESTORED, _STATUS, _ERROR, _AXLE, _FREE = range(5)


def _direction(der: bool, up: bool | None) -> int:
    if up is None:
        return UNKNOWN
    s1_to_s3 = not der
    return UP if s1_to_s3 == up else DOWN


def frames_to_events(
    frames: pd.DataFrame,
    *,
    up_is_s1_to_s3: Mapping[str, bool] | bool = True,
    comm_timeout_s: float = 10.0,
    source: str | None = None,
) -> list[DetectionEvent]:
    """Detection events from a frame table (:func:`parsers.frames.sensor.parse_frames` or ``parse_can``).

    ``up_is_s1_to_s3``: per sensor (or for all), whether travel S1→S3 is
    *up*; a sensor missing from a mapping gets axles of unknown direction.
    ``source`` defaults to ``"can"`` when the table has CAN columns, else
    ``"frame"``.  Events are in time order (stable).
    """
    if comm_timeout_s <= 0:
        raise ValueError("comm_timeout_s must be positive")
    src = source or ("can" if "seq" in frames.columns else "frame")
    if "kind" in frames.columns:  # a CAN table: only count frames are a sensor's
        frames = frames[frames["kind"] == "count"]
    if frames.empty:
        return []
    time_ns = frames["time"].to_numpy("datetime64[ns]").view(np.int64)
    end_ns = int(time_ns.max())
    timeout_ns = round(comm_timeout_s * NS)
    codes, names = pd.factorize(frames["sensor"].astype(str), sort=True)
    order = np.lexsort((time_ns, codes))  # per sensor, in time order; stable for equal times
    bounds = np.flatnonzero(np.diff(codes[order])) + 1
    events: list[DetectionEvent] = []
    for rows in np.split(order, bounds):
        head = str(names[codes[rows[0]]])
        up = up_is_s1_to_s3 if isinstance(up_is_s1_to_s3, bool) else up_is_s1_to_s3.get(head)
        events += _sensor_events(head, frames.iloc[rows], time_ns[rows], up, timeout_ns, end_ns, src)
    return sort_events(events)


def _sensor_events(
    head: str,
    f: pd.DataFrame,
    t: np.ndarray,
    up: bool | None,
    timeout_ns: int,
    end_ns: int,
    src: str,
) -> list[DetectionEvent]:
    """One sensor's frames (time order) → its events; diffs are vectorized, events built per change."""
    n = len(t)
    byte2 = f["byte2"].to_numpy(np.int64)
    # The parser's reading of 0xA5 (check byte or the count 165); the same rule for a hand-made table.
    check = f["check"].to_numpy(bool) if "check" in f.columns else check_byte_mask(np.zeros(n), t, byte2)
    der = f["der"].to_numpy(bool)
    out: list[tuple[int, int, int, DetectionEvent]] = []  # (time, frame, order, event)

    def add(
        i: int,
        order: int,
        kind: EventKind,
        detail: str,
        *,
        time: int | None = None,
        direction: int = UNKNOWN,
        channel: int | None = None,
    ) -> None:
        when = int(t[i]) if time is None else time
        out.append((when, i, order, DetectionEvent(when, kind, head, direction, channel, src, detail)))

    # Contact: gaps between frames, and silence at the end of the data.
    gap = np.diff(t)
    lost = np.flatnonzero(gap > timeout_ns) + 1
    for i in lost.tolist():
        add(i - 1, _RESTORED, EventKind.POWER_LOSS, _silence(timeout_ns), time=int(t[i - 1]) + timeout_ns)
        add(i, _RESTORED, EventKind.POWER_RESTORED, f"frames resumed after {gap[i - 1] / NS:.3f} s")
    if end_ns - t[-1] > timeout_ns:
        add(n - 1, _RESTORED, EventKind.POWER_LOSS, _silence(timeout_ns), time=int(t[-1]) + timeout_ns)
    contiguous = np.ones(n, bool)
    contiguous[lost] = False

    # Status bits: edges against the previous frame (all normal before the first).
    for name, channel, fault, ok in (
        ("sys", None, "sensor self-test failed (SYS = 1)", "sensor self-test passed again (SYS = 0)"),
        ("ses1", 1, "element S1 or its channel faulty (SES1 = 1)", "element S1 normal again (SES1 = 0)"),
        ("ses2", 2, "element S2 or its channel faulty (SES2 = 1)", "element S2 normal again (SES2 = 0)"),
        ("ses3", 3, "element S3 or its channel faulty (SES3 = 1)", "element S3 normal again (SES3 = 0)"),
    ):
        bit = f[name].to_numpy(bool)
        before = np.concatenate(([False], bit[:-1]))
        for i in np.flatnonzero(bit != before).tolist():
            if bit[i]:
                add(i, _STATUS, EventKind.CHANNEL_FAULT, fault, channel=channel)
            else:
                add(i, _STATUS, EventKind.CHANNEL_OK, ok, channel=channel)
    err = f["err"].to_numpy(bool)
    err_before = np.concatenate(([False], err[:-1]))
    for i in np.flatnonzero(err & ~err_before).tolist():
        add(i, _ERROR, EventKind.COUNT_ERROR, "majority not unanimous (ERR = 1): the count may be wrong")

    # CAN: sequence numbers between frames that arrived without a timeout.
    seq_step = np.ones(n, np.int64)
    if "seq" in f.columns and n > 1:
        seq = f["seq"].to_numpy(np.int64)
        seq_step[1:] = (seq[1:] - seq[:-1]) % SEQ_MODULO
        for i in np.flatnonzero((seq_step != 1) & contiguous).tolist():
            if i == 0:
                continue
            a, b = int(seq[i - 1]), int(seq[i])
            lost_frames = int(seq_step[i]) - 1 if seq_step[i] else 0
            detail = (
                f"sequence number {b} repeated"
                if not lost_frames and a == b
                else f"{lost_frames} frame(s) lost (sequence {a} → {b})"
            )
            add(i, _ERROR, EventKind.COUNT_ERROR, detail)

    # Counts: the count before each frame (0 after a clear), and the step.
    count = np.where(check, 0, byte2)
    prev = np.concatenate(([0], count[:-1]))
    prev_check = np.concatenate(([True], check[:-1]))
    step = count - prev
    wrapped = (step < 0) & (prev >= WRAP_FROM) & (count < WRAP_TO)
    step = np.where(wrapped, step + COUNT_MODULO, step)
    counting = ~check
    counting[0] = False  # the first frame is the baseline
    backwards = counting & (step < 0)
    axles = np.where(counting & (step > 0), step, 0)
    for i in np.flatnonzero(backwards).tolist():
        add(i, _ERROR, EventKind.COUNT_ERROR, f"count went back from {prev[i]} to {count[i]} without a clear")
    if "total" in f.columns and n > 1:
        total = f["total"].to_numpy(np.int64)
        advanced = np.concatenate(([0], (total[1:] - total[:-1]) % TOTAL_MODULO))
        expected = np.where(backwards, advanced, axles)  # a count going back is already an error
        differ = (advanced != expected) & (seq_step == 1) & contiguous
        differ[0] = False
        for i in np.flatnonzero(differ).tolist():
            detail = f"cumulative total advanced by {advanced[i]} but the count by {axles[i]}"
            add(i, _ERROR, EventKind.COUNT_ERROR, detail)
    for i in np.flatnonzero(axles).tolist():
        direction = _direction(bool(der[i]), up)
        base = int(prev[i])
        for k in range(1, int(axles[i]) + 1):
            add(i, _AXLE, EventKind.AXLE, f"count {(base + k) % COUNT_MODULO}", direction=direction)
    cleared = check & ~prev_check
    for i in np.flatnonzero(cleared).tolist():
        add(i, _FREE, EventKind.HEAD_FREE, f"section clear: check byte after count {prev[i]}")

    out.sort(key=lambda e: (e[0], e[1], e[2]))
    return [e[3] for e in out]


def _silence(timeout_ns: int) -> str:
    return f"no frames for {timeout_ns / NS:g} s"


# The same frames recorded twice (the sensor's text frames and a CAN capture of its bus, or one capture in two
# formats) give the same events, at most a clock's skew apart.  Two distinct events of one kind at one sensor
# with the same detail are never this close: an axle's detail carries the count byte, which repeats only after
# 256 axles.
REPEAT_TOLERANCE_NS = NS // 2
_EventKey = tuple[str, EventKind, int, int | None, str]  # what makes two files' events the same, time aside


def events_once(
    tables: list[pd.DataFrame],
    up_is_s1_to_s3: Mapping[str, bool] | bool = True,
    comm_timeout_s: float = 10.0,
) -> tuple[list[DetectionEvent], dict[str, int]]:
    """Frame tables → their events in time order, each event once, and per file how many it repeated.

    Per file (its own recording: sequence and count checks run within it);
    an event that an earlier file already gave (same sensor, kind,
    direction, channel and detail, within :data:`REPEAT_TOLERANCE_NS`) is
    set aside and counted against the later file.
    """
    earlier: dict[_EventKey, np.ndarray] = {}  # per event key: the earlier files' times, sorted
    events: list[DetectionEvent] = []
    repeated: dict[str, int] = {}
    for table in tables:
        for name, part in table.groupby("file", observed=True, sort=False):
            mine: dict[_EventKey, list[int]] = {}
            n_repeated = 0
            for e in frames_to_events(part, up_is_s1_to_s3=up_is_s1_to_s3, comm_timeout_s=comm_timeout_s):
                key = (e.head, e.kind, e.direction, e.channel, e.detail)
                times = earlier.get(key)
                if times is not None:
                    k = int(np.searchsorted(times, e.time_ns))
                    near = [times[j] for j in (k - 1, k) if 0 <= j < len(times)]
                    if any(abs(int(t) - e.time_ns) <= REPEAT_TOLERANCE_NS for t in near):
                        n_repeated += 1
                        continue
                events.append(e)
                mine.setdefault(key, []).append(e.time_ns)
            for key, ts in mine.items():
                earlier[key] = np.sort(np.r_[earlier.get(key, np.zeros(0, np.int64)), ts])
            repeated[str(name)] = repeated.get(str(name), 0) + n_repeated
    return sort_events(events), repeated


def frames_once(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """The count frames of frame tables (a CAN capture's other traffic aside), a frame that two files both
    recorded (same sensor, time and bytes) once: ``time``, ``sensor``, ``status``, ``byte2``, ``file``, ``line``."""
    columns = ["time", "sensor", "status", "byte2", "file", "line"]
    parts = [(t[t["kind"] == "count"] if "kind" in t.columns else t)[columns] for t in tables]
    if not parts:
        return pd.DataFrame(columns=columns)
    # File names as objects: pandas would infer Arrow strings, which a name that is not UTF-8 cannot be.
    frames = pd.concat([p.astype({"file": object}) for p in parts], ignore_index=True)
    return frames.drop_duplicates(["sensor", "time", "status", "byte2"], keep="first", ignore_index=True)
