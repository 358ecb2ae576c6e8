"""The CAN count frame's layout, the kinds of CAN frames, and a CAN log's report.

Standard id ``0x180 + n`` (n = 1..127) with DLC 5 is node n's count frame
(``docs/frames.md``); no python-can here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from parsers.frames.table import FRAME_COLUMNS
from parsers.report import FileReport

COUNT_ID_BASE = 0x180  # standard id 0x180 + node = count frame of sensor node 1..127
NODE_MIN, NODE_MAX = 1, 127
COUNT_DLC = 5  # [status, count or 0xA5, total lo, total hi, seq]
CAN_ID_MAX = 0x1FFFFFFF  # 29 bits
FRAME_KINDS = ("count", "foreign", "remote", "error")
CAN_COLUMNS = (*FRAME_COLUMNS, "total", "seq", "can_id", "kind", "extended", "dlc", "data")


@dataclass
class CanFileReport(FileReport):
    """Line accounting for one CAN log, and its frames by kind.

    ``lines_read`` counts text lines (candump, ASC, TRC) or CAN objects
    (BLF).  ``records`` are CAN frames of every kind, each a row of the
    table: ``count_frames + foreign + remote_frames + error_frames``.
    ``blank`` are lines that hold no frame: headers, comments, bus events.
    """

    format: str = ""
    messages: int = 0  # CAN frames the reader returned (rows and rejected frames)
    foreign: int = 0  # frames with ids other than the count ids (extended ids included)
    remote_frames: int = 0
    error_frames: int = 0

    @property
    def count_frames(self) -> int:
        """Count frames kept as rows (a protocol rejection leaves ``records``, so it leaves here too)."""
        return self.records - self.foreign - self.remote_frames - self.error_frames

    def to_dict(self) -> dict[str, Any]:
        return {
            **super().to_dict(),
            "format": self.format,
            "messages": self.messages,
            "count_frames": self.count_frames,
            "foreign": self.foreign,
            "remote_frames": self.remote_frames,
            "error_frames": self.error_frames,
        }


def default_sensor_name(node: int) -> str:
    """The sensor id a CAN node gets when no name is given: node 7 → ``AC07``."""
    return f"AC{node:02d}"
