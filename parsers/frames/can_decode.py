"""Collected CAN frames → frame-table columns by kind, bad count frames rejected (vectorized)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from parsers.frames.can_messages import FLAG_ERROR, FLAG_EXT, FLAG_REMOTE, CanMessages
from parsers.frames.can_report import (
    COUNT_DLC,
    COUNT_ID_BASE,
    NODE_MAX,
    NODE_MIN,
    CanFileReport,
    default_sensor_name,
)
from parsers.frames.table import FrameColumns, suspect_mask
from parsers.report import ParseReport

_KIND_COUNT, _KIND_FOREIGN, _KIND_REMOTE, _KIND_ERROR = range(4)


def decode_messages(
    msgs: CanMessages, fr: CanFileReport, report: ParseReport, sensor_names: Mapping[int, str] | None = None
) -> FrameColumns:
    """Frames a :class:`TextCanReader` took (a block of a growing log) → frame-table columns, as
    :func:`parse_can` makes them (file id 0); bad count frames rejected, the file's counts added to."""
    cols = FrameColumns()
    decode_can(msgs, 0, fr, report, cols, dict(sensor_names or {}))
    return cols


_HEX_PAIRS = np.array([f"{b:02X}" for b in range(256)], dtype="S2").view(np.uint8).reshape(256, 2)


def _hex_payloads(data: np.ndarray, length: np.ndarray) -> np.ndarray:
    """(n, 8) payload bytes and their lengths → hex strings, without a Python loop per frame."""
    if len(data) == 0:
        return np.zeros(0, object)
    chars = _HEX_PAIRS[data].reshape(len(data), 16)
    chars[np.arange(16)[None, :] >= 2 * np.minimum(length, 8)[:, None]] = ord(" ")
    text = np.char.rstrip(chars.copy().view("S16").ravel()).astype("U16")
    return text.astype(object)


def decode_can(
    msgs: CanMessages,
    file_id: int,
    fr: CanFileReport,
    report: ParseReport,
    cols: FrameColumns,
    names: Mapping[int, str],
) -> None:
    """Sort one file's frames by kind, reject bad count frames, add the rest as rows (vectorized).

    Called once per file, or once per block of a growing file: the counts add up.
    """
    can_id = np.array(msgs.can_id, np.int64)
    flags = np.array(msgs.flags, np.int64)
    dlc = np.array(msgs.dlc, np.int64)
    length = np.array(msgs.length, np.int64)
    line = np.array(msgs.line, np.int64)
    data = np.frombuffer(bytes(msgs.data), np.uint8).reshape(-1, 8)
    fr.messages += len(can_id)
    error = (flags & FLAG_ERROR) != 0
    remote = ((flags & FLAG_REMOTE) != 0) & ~error
    node = can_id - COUNT_ID_BASE
    count_id = ~error & ~remote & ((flags & FLAG_EXT) == 0) & (node >= NODE_MIN) & (node <= NODE_MAX)
    foreign = ~error & ~remote & ~count_id
    bad_dlc = count_id & ((length != COUNT_DLC) | (dlc != COUNT_DLC))
    for i in np.flatnonzero(bad_dlc).tolist():
        reason = (
            f"count frame 0x{can_id[i]:03X}: expected DLC {COUNT_DLC}, found DLC {dlc[i]} with {length[i]} data bytes"
        )
        report.reject(fr, int(line[i]), "dlc", reason, msgs.text.get(i, b""))
    fr.error_frames += int(error.sum())
    fr.remote_frames += int(remote.sum())
    fr.foreign += int(foreign.sum())
    rows = np.flatnonzero(~bad_dlc)
    is_count = count_id[rows]
    kind = np.select(
        [is_count, foreign[rows], remote[rows]], [_KIND_COUNT, _KIND_FOREIGN, _KIND_REMOTE], _KIND_ERROR
    ).astype(np.int8)
    d = data[rows]
    lut = np.array([names.get(k, default_sensor_name(k)) for k in range(NODE_MAX + 1)], dtype=object)
    sensor = lut[np.clip(node[rows], 0, NODE_MAX)]
    sensor[~is_count] = None
    # Status, count, total and seq mean something only in a count frame.
    status = np.where(is_count, d[:, 0], 0).astype(np.uint8)
    byte2 = np.where(is_count, d[:, 1], 0).astype(np.uint8)
    total = np.where(is_count, d[:, 2].astype(np.uint16) | (d[:, 3].astype(np.uint16) << 8), 0)
    cols.add(
        np.array(msgs.time_ns, np.int64)[rows],
        sensor,
        status,
        byte2,
        file_id,
        line[rows],
        total=total.astype(np.uint16),
        seq=np.where(is_count, d[:, 4], 0).astype(np.uint8),
        can_id=can_id[rows].astype(np.uint32),
        kind=kind,
        extended=(flags[rows] & FLAG_EXT) != 0,
        dlc=dlc[rows].astype(np.uint8),
        data=_hex_payloads(d, np.where(remote[rows] | error[rows], 0, length[rows])),
    )
    for j in np.flatnonzero(suspect_mask(status, byte2)).tolist():
        cols.suspects[(file_id, int(line[rows[j]]))] = msgs.text.get(int(rows[j]), b"")
    fr.records += len(rows)
    # Every line is a frame (a row), a rejection, or holds no frame (headers, comments, bus events).
    fr.blank = fr.lines_read - fr.records - fr.rejected
