"""GNSS files read as they grow: the batch parsers' fix rows, a block of lines at a time.

A receiver stream (NMEA, gpsd JSON, binary packets) goes line by line
through the batch :class:`~parsers.gnss.stream.StreamParser` itself, so a
sentence is decoded, an epoch merged and a packet framed exactly as when
the whole file is read.  Two things the batch reader knows from having the
whole file are waited for instead:

* a binary packet may run past the end of its line (0x0A is just a byte in
  it): a line where a packet starts whose length reaches past the lines at
  hand waits for more (at most :data:`~parsers.gnss.packets.MAX_PACKET_BYTES`);
  at the end of the file it is read as the batch reader reads a file's end;
* a row stays *open* while a later line may still change it: it is its
  device's current epoch (the GGA of the same second merges into the RMC's
  row), it waits for a date (a GGA before the device's first RMC), or it
  is a binary epoch still open for late messages (``parsers.gnss.epochs``).
  :meth:`GrowingStream.settle` hands out the rows that are no longer open,
  and forgets them: memory holds the open rows (one or two per device), not
  the file.  So the fixes come out one epoch late (the next epoch's first
  sentence, or the end, closes an epoch), and they are the batch rows.

Device exports (CSV, JSON lines) are row by row: :class:`DeviceLines` in
:mod:`parsers.gnss.csv`; their rows are never open.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from parsers.gnss import packets
from parsers.gnss.lines import split_lf, text_of
from parsers.gnss.stream import UNPRINTABLE_RE, LookaheadLines, StreamParser
from parsers.report import FileReport, ParseReport
from parsers.sources import DEFAULT_MAX_LINE_BYTES

if TYPE_CHECKING:
    import pandas as pd


def _waits_for_more(ahead: deque[tuple[int, bytes, int]]) -> bool:
    """Whether a packet starting in the first line at hand may run past the lines at hand.

    Each sync in the line is read as the batch reader reads it, over the
    lines at hand: a read that wanted more bytes than there are waits (a
    packet is at most MAX_PACKET_BYTES, so the wait is bounded).
    """
    _, line, start = ahead[0]

    def more(k: int) -> bytes | None:
        return ahead[k + 1][1] if k + 1 < len(ahead) else None

    at = start
    while (m := packets.SYNC_RE.search(line, at)) is not None:  # '$'/'!' start sentences, no look-ahead
        at = m.start()
        kind = packets.packet_kind(line[at : at + 2])
        if kind is not None:
            window = packets.ByteWindow(line, at, more)
            if packets.read_packet(kind, window) is None and window.ran_out:
                return True
        at += 1
    return False


class GrowingStream:
    """Receiver streams read as they grow; one per followed source (a device's date and epoch carry
    across its files, as across the files of one batch run)."""

    def __init__(self, report: ParseReport) -> None:
        self.report = report
        self.parser = StreamParser(report)
        self._feed = LookaheadLines(iter(()))
        self._fr: FileReport | None = None
        self._stem = ""
        # Row ids in the order the batch reader creates the rows: the open rows' ids, the next id.
        self._open_ids = np.zeros(0, np.int64)
        self._next_id = 0

    def open_file(self, fr: FileReport, stem: str) -> None:
        """Start a file (a rotation's next one): the previous one ends here."""
        self.end_file()
        self._fr, self._stem = fr, stem
        self._feed = LookaheadLines(iter(()))
        self.parser._gpsd_devices = {}

    def add(self, first_line: int, data: bytes) -> None:
        """Complete lines of the current file (each ends with a newline), from line ``first_line`` on."""
        fr = self._fr
        assert fr is not None, "open_file first"
        for k, raw in enumerate(split_lf(data)):
            fr.lines_read += 1
            if len(raw) > DEFAULT_MAX_LINE_BYTES:  # as the batch reader's line splitter refuses it
                reason = f"line of {len(raw)} bytes is too long to be a GNSS record"
                self.report.reject(fr, first_line + k, "too long", reason, raw[:1024])
                continue
            self._feed.ahead.append((first_line + k, raw, 0))
        self._run(final=False)

    def end_file(self) -> None:
        """The current file is complete: lines held for a packet's bytes are read as at a file's end."""
        self._run(final=True)

    def _run(self, final: bool) -> None:
        feed, fr = self._feed, self._fr
        while feed.ahead:
            assert fr is not None
            _, raw, start = feed.ahead[0]
            binary = start > 0 or (raw.lstrip(b" \t")[:1] != b"{" and UNPRINTABLE_RE.search(text_of(raw)))
            if binary and not final and _waits_for_more(feed.ahead):
                return
            item = feed.next()
            assert item is not None
            self.parser._line(fr, item, self._stem, feed)

    def settle(self, final: bool = False) -> tuple[pd.DataFrame, np.ndarray]:
        """The rows no later line can change (every row when ``final``), in the order the batch reader
        made them, with their ids (0, 1, … in that order); they leave the parser."""
        rows = self.parser.rows
        n = len(rows)
        ids = np.concatenate([self._open_ids, np.arange(self._next_id, self._next_id + n - len(self._open_ids))])
        self._next_id += n - len(self._open_ids)
        open_rows = set() if final else self.parser.open_rows()
        keep = np.array(sorted(open_rows), np.int64)
        done = np.setdiff1d(np.arange(n), keep)
        settled = rows.subset(done).frame()
        self.parser.rows = rows.subset(keep)
        self._open_ids = ids[keep]
        self.parser.renumber_rows({int(old): new for new, old in enumerate(keep.tolist())})
        return settled, ids[done]
