"""Health findings: :class:`Finding`, its :class:`Severity`, and their order (critical first).

What every health rule returns and every face (tables, report, archive, live) shows.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from console.analysis.timefmt import iso

SEVERITY_ORDER = ("info", "warning", "critical")


class Severity(StrEnum):
    """How urgent a finding is; ordered ``INFO < WARNING < CRITICAL``.

    Comparisons use the rank, not the text, so ``--fail-on warning`` can be
    written as ``finding.severity >= Severity.WARNING``.
    """

    INFO = "info"
    WARNING = "warning"
    CRITICAL = "critical"

    @property
    def rank(self) -> int:
        """0 for INFO, 1 for WARNING, 2 for CRITICAL."""
        return SEVERITY_ORDER.index(self.value)

    @classmethod
    def parse(cls, text: str) -> Severity:
        """``"Warning"`` → ``Severity.WARNING`` (case-insensitive); ValueError otherwise."""
        try:
            return cls(text.strip().lower())
        except ValueError:
            raise ValueError(f"severity: expected one of {', '.join(SEVERITY_ORDER)}, found '{text}'") from None

    def __lt__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank < other.rank

    def __le__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank <= other.rank

    def __gt__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank > other.rank

    def __ge__(self, other: str) -> bool:
        if not isinstance(other, Severity):
            return NotImplemented
        return self.rank >= other.rank


@dataclass(frozen=True)
class Finding:
    """One health verdict about a counting head (or sensor) and channel."""

    severity: Severity
    rule: str  # analog_band | voltage_margin | disturbance_rate | faulty_channel | single_channel
    counting_head: str | None  # the head (or, for voltage_margin, the sensor position)
    channel: int | None  # 1 = Sys1, 2 = Sys2; None = the whole head / sensor
    message: str  # one sentence with the numbers and what to do
    value: float | None = None  # the measured quantity the rule judged
    threshold: float | None = None  # the limit it was judged against
    time_ns: int | None = None  # when the problem was first seen (ns since the epoch, naive local time)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (no NaN: missing numbers are None)."""
        return {
            "severity": str(self.severity),
            "rule": self.rule,
            "counting_head": self.counting_head,
            "channel": self.channel,
            "message": self.message,
            "value": finite_or_none(self.value),
            "threshold": finite_or_none(self.threshold),
            "time_ns": self.time_ns,
            "time": iso(self.time_ns),
        }


def finite_or_none(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def channel_name(channel: int | None) -> str:
    """1 → ``Sys1``, 2 → ``Sys2``, None → ``all channels``."""
    if channel is None:
        return "all channels"
    return f"Sys{channel}" if channel in (1, 2) else f"ch {channel}"


def where_text(head: str | None, channel: int | None) -> str:
    return f"{head} {channel_name(channel)}" if channel is not None else f"{head}"


_NUMBER_RE = re.compile(r"(\d+)")


def natural_order_key(text: str | None) -> tuple[int, list[str | int]]:
    """``WS10`` after ``WS9``, sensor ``10`` after ``2``; None last."""
    if text is None:
        return (1, [])
    parts: list[str | int] = [int(p) if i % 2 else p.casefold() for i, p in enumerate(_NUMBER_RE.split(text))]
    return (0, parts)


def sort_findings(findings: Iterable[Finding]) -> list[Finding]:
    """Critical first, then by head (natural order), channel, rule and time."""
    return sorted(
        findings,
        key=lambda f: (
            -f.severity.rank,
            natural_order_key(f.counting_head),
            (1, 0) if f.channel is None else (0, f.channel),
            f.rule,
            -1 if f.time_ns is None else f.time_ns,
        ),
    )
