"""The two-byte intelligent-sensor frame, and the frame table both readers build.

Seed 002's sensor sends its processor two bytes: byte 1 is the working
status, byte 2 the axle count while the section is occupied or the check
byte 0xA5 while it is clear.  ``parsers.frames.sensor`` reads them from text files,
``parsers.frames.can`` from recorded CAN traffic; both collect columns in a
:class:`FrameColumns` and finish them into one table with
:func:`finish_table`, which also rejects check-byte frames that break the
protocol.  The layout of every bit is in ``docs/frames.md``.

Byte 1, most significant bit first::

    bit   7    6     5     4     3    2    1  0
          SYS  SES1  SES2  SES3  DER  ERR  T1 T2
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from parsers.report import ParseReport

SYS_BIT = 0x80  # microprocessor self-test: 0 normal, 1 fault
SES1_BIT = 0x40  # element S1 and its channel: 0 normal, 1 fault
SES2_BIT = 0x20
SES3_BIT = 0x10
DER_BIT = 0x08  # direction: 0 S1→S3, 1 S3→S1
ERR_BIT = 0x04  # 0 majority count normal, 1 the count may be wrong
T_MASK = 0x03  # T1 T2: whole seconds since the last interrupt, 0-3 (saturating)
CHECK_BYTE = 0xA5
# A count of 165 is the same byte as the check byte; see check_byte_mask.
COUNT_MAX = 255


FRAME_COLUMNS = (
    "time",
    "sensor",
    "status",
    "byte2",
    "check",
    "sys",
    "ses1",
    "ses2",
    "ses3",
    "der",
    "err",
    "t_since_s",
    "file",
    "line",
)


def encode_status(
    *,
    sys: bool = False,
    ses: tuple[bool, bool, bool] = (False, False, False),
    der: bool = False,
    err: bool = False,
    t_since_s: int = 0,
) -> int:
    """Byte 1 from its fields (the inverse of :func:`decode_status`)."""
    if not 0 <= t_since_s <= 3:
        raise ValueError(f"T1 T2 holds 0-3 seconds, not {t_since_s}")
    return (
        SYS_BIT * sys
        + SES1_BIT * ses[0]
        + SES2_BIT * ses[1]
        + SES3_BIT * ses[2]
        + DER_BIT * der
        + ERR_BIT * err
        + t_since_s
    )


def decode_status(status: np.ndarray) -> dict[str, np.ndarray]:
    """Byte 1 (uint8 array) → its fields: sys, ses1..3, der, err (bool), t_since_s (uint8)."""
    s = np.asarray(status, dtype=np.uint8)
    return {
        "sys": (s & SYS_BIT) != 0,
        "ses1": (s & SES1_BIT) != 0,
        "ses2": (s & SES2_BIT) != 0,
        "ses3": (s & SES3_BIT) != 0,
        "der": (s & DER_BIT) != 0,
        "err": (s & ERR_BIT) != 0,
        "t_since_s": (s & T_MASK).astype(np.uint8),
    }


def check_byte_mask(sensor: np.ndarray, time_ns: np.ndarray, byte2: np.ndarray) -> np.ndarray:
    """Which frames' byte 2 is the check byte 0xA5 (True) rather than a count.

    0xA5 is also the count 165.  Per sensor, in time order (input order for
    equal times), take each run of consecutive 0xA5 frames and the frames
    just before (P) and after (N) it; those are counts, by the run's
    definition.  The run is the count 165 when counting goes through it::

        P exists, P < 165, and (N > 165 if N exists, else P == 164)

    otherwise it is the check byte.  So ``164, A5, 170`` and ``160, A5, 170``
    are counts (165 passed between), ``164, A5`` at the end of the data is a
    count (a train standing at 165 axles), while ``160, A5`` and ``164, A5, 2``
    are a clear (the count restarts) and a log that starts with 0xA5 starts
    clear.  Vectorized: no Python loop over frames.
    """
    n = len(byte2)
    out = np.zeros(n, bool)
    if n == 0:
        return out
    order = np.lexsort((np.arange(n), time_ns, sensor))
    key = np.asarray(sensor)[order]
    b = np.asarray(byte2, dtype=np.int64)[order]
    is_a5 = b == CHECK_BYTE
    idx = np.arange(n)
    new_group = np.ones(n, bool)
    new_group[1:] = key[1:] != key[:-1]
    group_start = np.maximum.accumulate(np.where(new_group, idx, 0))
    last = np.empty(n, bool)
    last[:-1] = new_group[1:]
    last[-1] = True
    group_end = np.minimum.accumulate(np.where(last, idx, n - 1)[::-1])[::-1]
    # The nearest count (non-A5 frame) before and after each row.
    prev = np.maximum.accumulate(np.where(~is_a5, idx, -1))
    prev_before = np.concatenate(([-1], prev[:-1]))
    nxt = np.minimum.accumulate(np.where(~is_a5, idx, n)[::-1])[::-1]
    next_after = np.concatenate((nxt[1:], [n]))
    has_p = prev_before >= group_start
    has_n = next_after <= group_end
    p = b[np.clip(prev_before, 0, n - 1)]
    nx = b[np.clip(next_after, 0, n - 1)]
    counting = has_p & (p < CHECK_BYTE) & np.where(has_n, nx > CHECK_BYTE, p == CHECK_BYTE - 1)
    out[order] = is_a5 & ~counting
    return out


@dataclass
class FrameColumns:
    """Parsed frames of all files so far, as lists of per-chunk arrays."""

    time_ns: list[np.ndarray] = field(default_factory=list)
    sensor: list[np.ndarray] = field(default_factory=list)  # str objects
    status: list[np.ndarray] = field(default_factory=list)
    byte2: list[np.ndarray] = field(default_factory=list)
    file_id: list[np.ndarray] = field(default_factory=list)
    line: list[np.ndarray] = field(default_factory=list)
    extra: dict[str, list[np.ndarray]] = field(default_factory=dict)
    # Raw text of the frames the protocol check may reject, by (file id, line).
    suspects: dict[tuple[int, int], bytes] = field(default_factory=dict)

    def add(
        self,
        time_ns: np.ndarray,
        sensor: np.ndarray,
        status: np.ndarray,
        byte2: np.ndarray,
        file_id: int,
        line: np.ndarray,
        **extra: np.ndarray,
    ) -> None:
        self.time_ns.append(time_ns.astype(np.int64))
        self.sensor.append(sensor)
        self.status.append(status.astype(np.uint8))
        self.byte2.append(byte2.astype(np.uint8))
        self.file_id.append(np.full(len(line), file_id, np.int32))
        self.line.append(line.astype(np.int64))
        for k, v in extra.items():
            self.extra.setdefault(k, []).append(v)

    def concat(self, name: str, dtype: Any) -> np.ndarray:
        parts = self.extra[name] if name in self.extra else getattr(self, name, [])
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)


def suspect_mask(status: np.ndarray, byte2: np.ndarray) -> np.ndarray:
    """Frames the protocol check could reject: byte 2 = 0xA5 with DER = 1."""
    return (byte2 == CHECK_BYTE) & ((status & DER_BIT) != 0)


def _categorical(values: np.ndarray) -> pd.Categorical:
    """Sensor names as a categorical; None (a CAN frame that is no sensor's) becomes missing."""
    cats = pd.Index(sorted({v for v in values.tolist() if v is not None}), dtype="str")
    return pd.Categorical(values, categories=cats)


def _file_column(files: list[str], file_id: np.ndarray) -> pd.Categorical:
    """File names as a categorical (a file given twice is one category)."""
    unique = list(dict.fromkeys(files))
    remap = np.array([unique.index(f) for f in files], np.int32)
    codes = remap[file_id] if len(files) else file_id
    try:
        categories = pd.Index(unique, dtype="str")
    except UnicodeEncodeError:  # a file name with undecodable bytes (surrogate escapes): keep it exact
        categories = pd.Index(unique, dtype=object)
    return pd.Categorical.from_codes(codes, categories=categories)


def finish_table(cols: FrameColumns, files: list[str], report: ParseReport, extra: Mapping[str, Any]) -> pd.DataFrame:
    """One table from the parsed columns; reject check-byte frames that break the protocol."""
    sensor = np.concatenate(cols.sensor) if cols.sensor else np.zeros(0, object)
    time_ns = cols.concat("time_ns", np.int64)
    status = cols.concat("status", np.uint8)
    byte2 = cols.concat("byte2", np.uint8)
    file_id = cols.concat("file_id", np.int32)
    line = cols.concat("line", np.int64)
    sensor_cat = _categorical(sensor)
    check = check_byte_mask(sensor_cat.codes, time_ns, byte2)
    broken = check & ((status & DER_BIT) != 0)
    for i in np.flatnonzero(broken).tolist():
        fr = report.files[int(file_id[i])]
        fr.records -= 1
        raw = cols.suspects.get((int(file_id[i]), int(line[i])), b"")
        reason = (
            "byte 2 is the check byte 0xA5 here (no count reaching 165 around it) but DER = 1;"
            " a check-byte frame has DER = 0"
        )
        report.reject(fr, int(line[i]), "protocol", reason, raw)
    keep = ~broken
    bits = decode_status(status[keep])
    frame = pd.DataFrame(
        {
            "time": pd.to_datetime(time_ns[keep], unit="ns").astype("datetime64[ns]"),
            "sensor": sensor_cat[keep].remove_unused_categories(),
            "status": status[keep],
            "byte2": byte2[keep],
            "check": check[keep],
            **bits,
            "file": _file_column(files, file_id[keep]),
            "line": line[keep],
            **{k: v[keep] if isinstance(v, pd.Categorical) else np.asarray(v)[keep] for k, v in extra.items()},
        }
    )
    report.check()
    return frame.reset_index(drop=True)
