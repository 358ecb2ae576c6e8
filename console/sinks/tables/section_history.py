"""The section engine's history as it is made: the first rows, totals, and every row spilled as JSON.

A section run's history (state timeline, count ledger) grows with the
traffic, not the heads: :class:`SectionsSink` takes it from the pipeline as
it is made, keeps the first rows and per-(section, head) totals for the
tables, and, for ``--json`` and the report, spills each row's JSON text to a
temporary file that the document copies in at the end.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from array import array
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import IO, Any

from console.analysis.sections.state import LedgerEntry, ResetRecord, Transition
from console.analysis.timefmt import fraction_text, iso
from console.engine.sinks import Sink
from console.jsonout import valid_unicode
from parsers.units import NS

TIMELINE_ROWS_KEPT = 201  # the text table shows 200 and says whether there are more
SPILL_BLOCK_BYTES = 1 << 20  # spilled rows copied out at a time


def _row_json(row: dict[str, Any] | str) -> str:
    return valid_unicode(json.dumps(row, ensure_ascii=True, separators=(",", ":"), allow_nan=False))


def transition_json(t: Transition) -> str:
    """One timeline row as ``sections --json`` writes it."""
    return _row_json(
        {"section": t.section, "state": str(t.state), "count": t.count, "reason": t.reason, "time": iso(t.time_ns)}
    )


def ledger_json(x: LedgerEntry) -> str:
    """One ledger row as ``sections --json`` writes it (:func:`LedgerText` writes the same, faster)."""
    return _row_json({"section": x.section, "head": x.head, "delta": x.delta, "count": x.count, "time": iso(x.time_ns)})


class LedgerText:
    """:func:`ledger_json` for a row per counted axle: the JSON of each (section, head) and of each
    second's time text made once (``tests/test_stream_sections.py`` holds them equal).

    ``depth`` None: compact, as ``sections --json`` writes a row; else the row as
    ``json.dumps(indent=1)`` writes an array item at that depth, its newline and
    indent first (the report's JSON: ``console.sinks.report.jsonwrite``).
    """

    def __init__(self, depth: int | None = None) -> None:
        self._prefix: dict[tuple[str, str], str] = {}
        self._second: dict[int, str] = {}
        if depth is None:
            self._open, self._sep, self._colon, self._close = "{", ",", ":", "}"
        else:
            member = "\n" + " " * (depth + 1)
            self._open, self._sep, self._colon = "\n" + " " * depth + "{" + member, "," + member, ": "
            self._close = "\n" + " " * depth + "}"

    def __call__(self, x: LedgerEntry) -> str:
        prefix = self._prefix.get((x.section, x.head))
        sep, colon = self._sep, self._colon
        if prefix is None:
            text = f'{self._open}"section"{colon}{_row_json(x.section)}{sep}"head"{colon}{_row_json(x.head)}'
            prefix = self._prefix[(x.section, x.head)] = f'{text}{sep}"delta"{colon}'
        whole, frac = divmod(x.time_ns, NS)
        second = self._second.get(whole)
        if second is None:
            if len(self._second) > 1 << 16:
                self._second.clear()
            second = self._second[whole] = str(iso(whole * NS))[:-5]  # without ".000Z"
        time_text = f"{second}{fraction_text(frac)}Z"
        return f'{prefix}{x.delta}{sep}"count"{colon}{x.count}{sep}"time"{colon}"{time_text}"{self._close}'


def reset_json(r: ResetRecord) -> str:
    return _row_json({"section": r.section, "accepted": r.accepted, "reason": r.reason, "time": iso(r.time_ns)})


class _Spill:
    """JSON array items written to a temporary file as they come (``track``: where each one starts, to read it back)."""

    def __init__(self, track: bool = False) -> None:
        self.file: IO[bytes] = tempfile.TemporaryFile()  # noqa: SIM115 (closed by close())
        self.n = 0
        self.size = 0
        self.starts: array[int] | None = array("q") if track else None

    def add(self, text: str) -> None:
        data = (b"," if self.n else b"") + text.encode("ascii")
        if self.starts is not None:
            self.starts.append(self.size + (1 if self.n else 0))
        self.file.write(data)
        self.size += len(data)
        self.n += 1

    def read_back(self) -> Iterator[str]:
        """Each spilled item's JSON text, in order, read back a block at a time (no ``track`` needed)."""
        decoder = json.JSONDecoder()
        self.file.seek(0)
        text = ""
        while True:
            block = self.file.read(SPILL_BLOCK_BYTES).decode("ascii")
            text += block
            pos = 0
            while True:
                while pos < len(text) and text[pos] == ",":
                    pos += 1
                try:
                    _, end = decoder.raw_decode(text, pos)
                except ValueError:  # the item goes on in the next block
                    break
                yield text[pos:end]
                pos = end
            text = text[pos:]
            if not block:
                if text:
                    raise ValueError("spilled rows end inside an item")
                return

    def copy_to(self, out: IO[str]) -> None:
        out.write("[")
        out.flush()
        self.file.seek(0)
        buf = getattr(out, "buffer", None)
        if buf is not None:
            shutil.copyfileobj(self.file, buf, 1 << 20)
            buf.flush()
        else:
            while block := self.file.read(1 << 20):
                out.write(block.decode("ascii"))
        out.write("]")

    def blocks(self) -> Iterator[str]:
        """The items as written (comma-separated, no brackets), in pieces of ``SPILL_BLOCK_BYTES``."""
        self.file.flush()
        fd, step = self.file.fileno(), SPILL_BLOCK_BYTES
        for offset in range(0, self.size, step):
            yield os.pread(fd, min(step, self.size - offset), offset).decode("ascii")

    def items(self, rows: Iterable[int] | None = None) -> Iterator[str]:
        """Items one by one (``rows``: these, in this order; needs ``track``)."""
        assert self.starts is not None
        self.file.flush()
        fd, starts, n = self.file.fileno(), self.starts, self.n
        for i in range(n) if rows is None else rows:
            end = starts[i + 1] - 1 if i + 1 < n else self.size  # the next item's comma
            yield os.pread(fd, end - starts[i], starts[i]).decode("ascii")

    def close(self) -> None:
        self.file.close()


@dataclass
class SectionsSink(Sink):
    """The section engine's history as it is made: first rows, totals, and (``spill``) every row as JSON.

    ``spill`` writes each state change with ``timeline_text`` (where each
    starts is kept, to read rows back) and, with ``spill_ledger``, each
    counted axle with ``ledger_text``: by default as ``sections --json``
    writes them; the report gives its own form (``console.sinks.report.spooled``).
    """

    spill: bool = False
    keep_all: bool = False  # the whole history in memory as well (report's collect(whole=True), tests)
    spill_ledger: bool = True
    timeline_text: Callable[[Transition], str] = transition_json
    ledger_text: Callable[[LedgerEntry], str] = field(default_factory=LedgerText)
    timeline_rows: int = 0
    timeline_first: list[Transition] = field(default_factory=list)
    ledger_rows: int = 0
    # (section, head) → [in, out, first, last]
    ledger_totals: dict[tuple[str, str], list[int]] = field(default_factory=dict)
    reset_rows: list[ResetRecord] = field(default_factory=list)
    timeline_all: list[Transition] = field(default_factory=list)
    ledger_all: list[LedgerEntry] = field(default_factory=list)
    # Per state change: its section (numbered as first seen: `section_number`) and time, for plots.
    section_number: dict[str, int] = field(default_factory=dict)
    timeline_section: array[int] = field(default_factory=lambda: array("i"))
    timeline_time_ns: array[int] = field(default_factory=lambda: array("q"))
    # (section, state) → when the section last entered that state.
    entered_ns: dict[tuple[str, str], int] = field(default_factory=dict)
    _timeline: _Spill | None = None
    _ledger: _Spill | None = None

    def __post_init__(self) -> None:
        if self.spill:
            self._timeline = _Spill(track=True)
            self._ledger = _Spill() if self.spill_ledger else None

    def transitions(self, trs: Sequence[Transition]) -> None:
        self.timeline_rows += len(trs)
        room = TIMELINE_ROWS_KEPT - len(self.timeline_first)
        if room > 0:
            self.timeline_first += trs[:room]
        if self.keep_all:
            self.timeline_all += trs
        numbers, entered = self.section_number, self.entered_ns
        for t in trs:  # per state change: a few per train and section
            n = numbers.setdefault(t.section, len(numbers))
            self.timeline_section.append(n)
            self.timeline_time_ns.append(t.time_ns)
            entered[(t.section, str(t.state))] = t.time_ns
            if self._timeline is not None:
                self._timeline.add(self.timeline_text(t))

    def ledger(self, led: Sequence[LedgerEntry]) -> None:
        self.ledger_rows += len(led)
        totals = self.ledger_totals
        text = self.ledger_text
        for x in led:  # per counted axle: a dict update
            tot = totals.get((x.section, x.head))
            if tot is None:
                tot = totals[(x.section, x.head)] = [0, 0, x.time_ns, x.time_ns]
            tot[0 if x.delta > 0 else 1] += 1
            tot[2] = min(tot[2], x.time_ns)
            tot[3] = max(tot[3], x.time_ns)
            if self._ledger is not None:
                self._ledger.add(text(x))
        if self.keep_all:
            self.ledger_all += led

    def resets(self, rows: Sequence[ResetRecord]) -> None:
        self.reset_rows += rows

    def restart(self, passages: bool) -> None:
        """The log is read again: the history taken so far is forgotten."""
        self.close()
        fresh = SectionsSink(
            spill=self.spill,
            keep_all=self.keep_all,
            spill_ledger=self.spill_ledger,
            timeline_text=self.timeline_text,
            ledger_text=self.ledger_text,
        )
        self.__dict__.update(fresh.__dict__)

    def timeline_items(self, rows: Iterable[int] | None = None) -> Iterator[str]:
        """The spilled state changes' texts, one by one (``rows``: these, in this order)."""
        assert self._timeline is not None
        return self._timeline.items(rows)

    def spilled_blocks(self, what: str) -> Iterator[str]:
        """The spilled ``timeline`` or ``ledger`` rows' texts, comma-separated, in pieces."""
        spill = self._timeline if what == "timeline" else self._ledger
        assert spill is not None, f"the {what} was not spilled"
        return spill.blocks()

    @property
    def ledger_spilled(self) -> bool:
        return self._ledger is not None

    def write_json_arrays(self, out: IO[str]) -> None:
        """``"timeline":[…],"ledger":[…],"resets":[…]`` (spilled rows copied in)."""
        assert self._timeline is not None and self._ledger is not None
        out.write('"timeline":')
        self._timeline.copy_to(out)
        out.write(',"ledger":')
        self._ledger.copy_to(out)
        out.write(',"resets":[' + ",".join(reset_json(r) for r in self.reset_rows) + "]")

    def json_items(self) -> Iterator[tuple[str, str]]:
        """(type, JSON text) of every row, as ``--jsonl`` writes them: state changes, ledger rows, resets."""
        assert self._timeline is not None and self._ledger is not None
        yield from (("section", text) for text in self._timeline.read_back())
        yield from (("ledger", text) for text in self._ledger.read_back())
        yield from (("reset", reset_json(r)) for r in self.reset_rows)

    def close(self) -> None:
        for s in (self._timeline, self._ledger):
            if s is not None:
                s.close()
