"""A head's records that go back in time within one file: its device's clock stepped back.

A board writes its records in time order; logs interleave boards whose clocks differ, so the analysis sorts a
head's records by time and allows :data:`ORDER_SLACK_S` between boards. A record of a head that is more than
that slack *earlier than the head's record before it in the same file* is a step of the device's clock (an
NTP or GPS correction, a real-time clock reset after power-up, a daylight-saving change in a local-time log),
or a file not in time order (exports joined the wrong way round, an export written newest first).

The analyses sort by time either way, which is right for a file out of order and wrong across a clock step:
an axle counted out after a step back can fall before one counted in before it, and a section would show clear
early. From the records alone the two cannot be told apart, so the first step of each file and head is doubt
(``EventKind.CLOCK_STEP``): the sections the head bounds are disturbed from the first record after the step (no
record after it is earlier) until a reset. For a file written newest first that is near its latest record: the
analysis before it stands.

Checked on every record of a head (status and register records too: the step often shows in a heartbeat long
before the next train), in read order, vectorized per chunk.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from console.analysis.timefmt import display
from parsers.units import NO_TIME, NS

_NONE = np.zeros(0, np.int64)


@dataclass(frozen=True)
class ClockStep:
    head_key: int
    file_id: int
    line: int  # 1-based, the first record after the step
    back_ns: int  # how much earlier it is than the head's record before it
    before_ns: int  # the time of that record

    @property
    def at_ns(self) -> int:
        """The time of the first record after the step: every record after the step is at or after it."""
        return self.before_ns - self.back_ns


@dataclass
class ClockSteps:
    """Per (file, head), the last record time; the steps found: the first per file and head kept, all counted."""

    slack_ns: int
    steps: list[ClockStep] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)  # per kept step, the steps of its file and head
    count: int = 0
    _last: dict[int, np.ndarray] = field(default_factory=dict)  # file id → per head key, its last record (NO_TIME)
    _kept: dict[tuple[int, int], int] = field(default_factory=dict)  # (file, head) → its index in steps

    def feed(
        self, file_id: int, head: np.ndarray, time_ns: np.ndarray, line: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """One chunk's records of one file, in read order (``head``: each record's head key, int64).
        Returns the first steps of their file and head found in it: the heads, and the time of each one's first
        record after the step, which no record after the step precedes (a file written newest first steps back
        at nearly every record: only its first step, near its latest time, is news)."""
        if not len(head):
            return _NONE, _NONE
        # Per head, in read order; a stable sort of 16-bit keys is a radix sort, linear in the records.
        order = np.argsort(head.astype(np.uint16) if int(head.max()) < 1 << 16 else head, kind="stable")
        h, t = head[order], time_ns[order]
        first = np.r_[True, h[1:] != h[:-1]]
        keys = h[first]
        last = self._last.get(file_id, np.zeros(0, np.int64))
        if len(last) <= int(keys[-1]):
            last = np.r_[last, np.full(int(keys[-1]) + 1 - len(last), NO_TIME, np.int64)]
        prev = np.r_[NO_TIME, t[:-1]]
        prev[first] = last[keys]
        back = np.where(prev != NO_TIME, prev - t, 0)
        stepped = np.flatnonzero(back > self.slack_ns)
        new: list[ClockStep] = []
        if len(stepped):
            self.count += len(stepped)
            at = line[order]
            keys_stepped, first_at, n = np.unique(h[stepped], return_index=True, return_counts=True)
            for k, i, c in zip(keys_stepped.tolist(), stepped[first_at].tolist(), n.tolist(), strict=True):
                kept = self._kept.get((file_id, k))
                if kept is None:
                    self._kept[(file_id, k)] = len(self.steps)
                    new.append(ClockStep(k, file_id, int(at[i]), int(back[i]), int(prev[i])))
                    self.steps.append(new[-1])
                    self.counts.append(c)
                else:
                    self.counts[kept] += c
        ends = np.r_[np.flatnonzero(first)[1:], len(h)] - 1
        last[keys] = t[ends]
        self._last[file_id] = last
        new.sort(key=lambda s: s.at_ns)
        return np.array([s.head_key for s in new], np.int64), np.array([s.at_ns for s in new], np.int64)

    def warnings(self, head_names: list[str], file_names: list[str]) -> list[str]:
        """One line per head and file with a step (its first), for people."""
        out = []
        for s, n in zip(self.steps, self.counts, strict=True):
            name = head_names[s.head_key] if s.head_key < len(head_names) else f"head {s.head_key}"
            where = file_names[s.file_id] if s.file_id < len(file_names) else f"input {s.file_id + 1}"
            more = f", and {n - 1:,} more time{'s' if n > 2 else ''} in that file" if n > 1 else ""
            out.append(
                f"{name}: its records go back {s.back_ns / NS:,.1f} s at {where} line {s.line:,}{more} (the device's "
                f"clock stepped back, or the file is not in time order): sections it bounds are disturbed from "
                f"{display(s.at_ns)}, the time of that line"
            )
        return out
