"""The CAN frames python-can's readers return, collected for the batch decoder (:mod:`parsers.frames.can_decode`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import cast

import can

from parsers.frames.can_clock import TIME_MAX_NS, TIME_MIN_NS
from parsers.frames.can_report import CAN_ID_MAX, COUNT_DLC, COUNT_ID_BASE, NODE_MAX, NODE_MIN
from parsers.frames.table import CHECK_BYTE, DER_BIT

FLAG_EXT, FLAG_REMOTE, FLAG_ERROR = 1, 2, 4
READER_ERRORS = (ValueError, IndexError, KeyError, TypeError, OverflowError)


@dataclass
class CanMessages:
    """What the readers returned, one entry per CAN frame (decoded later, vectorized)."""

    time_ns: list[int] = field(default_factory=list)
    line: list[int] = field(default_factory=list)
    can_id: list[int] = field(default_factory=list)
    flags: list[int] = field(default_factory=list)
    dlc: list[int] = field(default_factory=list)
    length: list[int] = field(default_factory=list)
    data: bytearray = field(default_factory=bytearray)  # 8 bytes per frame, zero padded
    text: dict[int, bytes] = field(default_factory=dict)  # by frame index: lines of count-id frames to reject


def _frame_problem(msg: can.Message, time_ns: int | None) -> tuple[str, str] | None:
    """Why a frame the reader returned cannot be a row: (category, reason) naming the field, or None."""
    if time_ns is None or not TIME_MIN_NS <= time_ns < TIME_MAX_NS:
        return "time", f"time: timestamp {msg.timestamp!r} s is not a time in 1900-2199"
    if not 0 <= msg.arbitration_id <= CAN_ID_MAX:
        return "id", f"id: 0x{msg.arbitration_id:X} is wider than 29 bits"
    if not 0 <= msg.dlc <= 64:
        return "dlc", f"dlc: {msg.dlc} is not a CAN DLC"
    return None


def collect_frame(
    msgs: CanMessages, msg: can.Message, line: int, base_ns: int, text: bytes | None, *, error: bool = False
) -> tuple[str, str] | None:
    """Add one frame; or say why it cannot be added (the caller rejects it)."""
    stamp = msg.timestamp
    time_ns = base_ns + round(stamp * 1e6) * 1000 if math.isfinite(stamp) and abs(stamp) < 1e13 else None
    problem = _frame_problem(msg, time_ns)
    if problem is not None:
        return problem
    is_error = msg.is_error_frame or error
    flags = FLAG_EXT * msg.is_extended_id + FLAG_REMOTE * msg.is_remote_frame + FLAG_ERROR * is_error
    data = bytes(msg.data or b"")
    msgs.time_ns.append(cast(int, time_ns))
    msgs.line.append(line)
    msgs.can_id.append(msg.arbitration_id)
    msgs.flags.append(flags)
    msgs.dlc.append(msg.dlc)
    msgs.length.append(len(data))
    msgs.data += data[:8].ljust(8, b"\0")
    # Keep the line only for a count-id frame the decoding may reject (bounded by those).
    suspect = len(data) != COUNT_DLC or msg.dlc != COUNT_DLC or (data[1] == CHECK_BYTE and data[0] & DER_BIT)
    if suspect and not flags and NODE_MIN <= msg.arbitration_id - COUNT_ID_BASE <= NODE_MAX:
        msgs.text[len(msgs.line) - 1] = text if text is not None else candump_text(msg)
    return None


def candump_text(msg: can.Message) -> bytes:
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f"{ident}#{bytes(msg.data or b'').hex().upper()}".encode()
