"""The queue between the sources' threads and the live engine: a followed file's reader waits for room,
so following a big file from its start takes memory bounded by the backlog, not by the file."""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from console.inputs.base import LineBlock, Source
from console.inputs.follow import FileSource
from console.inputs.gpsd import GpsdSource
from console.live.backlog import Backlog
from tests.live_fixtures import wait_until

BLOCK = 1 << 16


def _block(k: int) -> LineBlock:
    return LineBlock("file:x", "x", 1 + k, b"%08d\n" % k * (BLOCK // 9), time.monotonic())


def _producer(backlog: Backlog, source: FileSource | GpsdSource, n: int, done: list[int]) -> threading.Thread:
    put = backlog.putter(source)

    def body() -> None:
        for k in range(n):
            put(_block(k))
            done.append(k)

    t = threading.Thread(target=body, daemon=True)
    t.start()
    return t


def test_a_files_reader_waits_while_the_backlog_is_full_and_every_block_arrives_in_order(tmp_path: Path) -> None:
    backlog = Backlog(limit_bytes=4 * BLOCK)
    done: list[int] = []
    t = _producer(backlog, FileSource("file:x", tmp_path / "x.log"), 40, done)
    # The producer fills the backlog (a fixed 0.5 s was not always enough for its thread on a loaded
    # machine), then gets no further while nothing is taken out.
    assert wait_until(lambda: len(done) >= 4, 30), done
    time.sleep(0.5)
    # Held: what it handed over is at most the limit and one block more, not the 40 blocks.
    assert 4 <= len(done) <= 6, done
    got = []
    while len(got) < 40:
        item = backlog.get(5.0)
        assert isinstance(item, LineBlock)
        got.append(item.first_line - 1)
    t.join(5.0)
    assert got == list(range(40)) and not t.is_alive()
    with pytest.raises(queue.Empty):
        backlog.get()
    assert backlog.empty()


def test_a_network_source_is_never_held_but_a_stopping_file_reader_is_until_the_backlog_closes(tmp_path: Path) -> None:
    backlog = Backlog(limit_bytes=2 * BLOCK)
    done: list[int] = []
    _producer(backlog, GpsdSource("gpsd://127.0.0.1:1", "127.0.0.1", 1), 20, done).join(5.0)
    assert len(done) == 20  # its sender sets the rate

    stopping = FileSource("file:y", tmp_path / "y.log")
    stopping.request_stop()  # read to its end on the way out: in bounded memory too (follow drains meanwhile)
    held: list[int] = []
    t = _producer(backlog, stopping, 5, held)
    time.sleep(0.3)
    assert held == []  # the backlog is over its limit: the stopping reader waits ...
    backlog.close()  # ... until the consumer will take no more: it is let go, and the rest is dropped, on record
    t.join(5.0)
    assert held == list(range(5)) and backlog.empty()
    dropped, n = backlog.not_analysed()
    assert dropped == {"x": 1} and n == 20 + 5  # the first line of the first block dropped; every item counted
    with pytest.raises(queue.Empty):
        backlog.get()


def test_an_abandoned_file_reader_stops_reading_and_ends(tmp_path: Path) -> None:
    """A second Ctrl-C or a closed view: the reader of a big file followed from its start stops where it is."""
    log = tmp_path / "big.log"
    station = Path(__file__).parents[1] / "sample_logs" / "example_station.log"
    log.write_bytes(station.read_bytes() * 16)  # 7 MB of a diagnostic log: handed over as blocks of lines
    backlog = Backlog(limit_bytes=BLOCK)
    source = FileSource("file:big", log, from_start=True)
    source.start(backlog.putter(source))
    assert wait_until(lambda: not backlog.empty(), 30)
    source.request_stop()
    time.sleep(0.3)
    assert source.running  # stopping, held: it would read on to the end as the backlog is drained
    source.abandon()
    backlog.close()
    assert wait_until(lambda: not source.running, 10)
    assert source.bytes_read < log.stat().st_size
    dropped, _ = backlog.not_analysed()
    assert list(dropped) == [str(log)]


def test_follow_from_start_through_a_small_backlog_gives_what_an_unbounded_one_gives(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``follow --from-start`` of the shipped station log (450 kB) read in blocks of 16 kB, its reader held to
    8 kB of backlog (each block waits for the one before): the same events as with room for the whole file."""
    from typer.testing import CliRunner

    import console.inputs.follow as follow
    import console.live.backlog as backlog
    from console.cli.app import app

    log = Path(__file__).parents[1] / "sample_logs" / "example_station.log"
    args = ["follow", f"file:{log}", "--from-start", "--jsonl", "--layout", "example", "--idle-exit", "0.5"]

    def lines() -> list[str]:
        res = CliRunner().invoke(app, args)
        assert res.exit_code == 0, res.output
        # The summary's source rate and message age are wall-clock figures.
        return [ln for ln in res.stdout.splitlines() if '"type": "summary"' not in ln]

    monkeypatch.setattr(follow, "READ_BYTES", 16 << 10)
    roomy = lines()
    monkeypatch.setattr(backlog, "BACKLOG_BYTES", 8 << 10)
    assert Backlog().limit_bytes == 8 << 10
    assert lines() == roomy
    assert sum('"type": "passage"' in ln for ln in roomy) > 20


class _SlowLastRead(Source):
    """A source whose last read, on stop, delivers ``blocks`` blocks ``gap_s`` apart (a followed file with a
    long unread tail on a busy machine): longer in all than a fixed 3 s wait for its thread."""

    def __init__(self, blocks: int, gap_s: float) -> None:
        super().__init__("file:slow")
        self.blocks, self.gap_s = blocks, gap_s

    def run(self) -> None:
        while not self.stopping:
            time.sleep(0.01)
        for k in range(self.blocks):
            time.sleep(self.gap_s)
            self.emit(LineBlock(self.uri, "slow", k + 1, b"x\n", time.monotonic()))


class _Counting:
    """The engine's side of run_sources, counting what it is handed."""

    def __init__(self) -> None:
        self.handled: list[int] = []
        self.finished_after = -1

    def handle(self, item: LineBlock) -> None:
        self.handled.append(item.first_line)

    def idle(self) -> None:
        pass

    def tick(self) -> None:
        pass

    def next_wake_s(self) -> None:
        return None

    def finish(self) -> None:
        self.finished_after = len(self.handled)


def test_what_a_source_delivers_while_it_stops_is_analysed_however_long_that_takes() -> None:
    from console.live.engine import run_sources

    engine = _Counting()
    source = _SlowLastRead(blocks=40, gap_s=0.1)  # 4 s of last read
    told: list[str] = []
    run_sources(engine, [source], duration_s=0.2, tell=told.append)  # type: ignore[arg-type]
    assert engine.handled == list(range(1, 41)) and engine.finished_after == 40
    # Over a second of stopping: said once, with the way to cut it short.
    assert len(told) == 1 and told[0].startswith("stopping:") and told[0].endswith("Ctrl-C stops at once")


class _LastReadAtOnce(Source):
    """A source whose last read, on stop, hands over ``blocks`` blocks at once."""

    def __init__(self, blocks: int) -> None:
        super().__init__("file:slow")
        self.blocks = blocks

    def run(self) -> None:
        while not self.stopping:
            time.sleep(0.01)
        for k in range(self.blocks):
            self.emit(LineBlock(self.uri, "slow", k + 1, b"x\n", time.monotonic()))


def test_a_second_interrupt_while_stopping_stops_at_once_and_says_what_was_not_analysed() -> None:
    import signal

    from console.live.engine import run_sources

    source = _LastReadAtOnce(blocks=300)

    class Interrupted(_Counting):
        def handle(self, item: LineBlock) -> None:
            super().handle(item)
            if item.first_line == 5:
                # The last read is all queued by now; the user presses Ctrl-C (the run ended by its duration).
                assert wait_until(lambda: not source.running, 10)
                signal.raise_signal(signal.SIGINT)

    engine = Interrupted()
    engine.not_analysed, engine.items_not_analysed = {}, 0  # type: ignore[attr-defined]
    stopped_by = run_sources(engine, [source], duration_s=0.2)  # type: ignore[arg-type]
    assert stopped_by == signal.SIGINT
    assert engine.handled == [1, 2, 3, 4, 5] and engine.finished_after == 5
    assert engine.not_analysed == {"slow": 6} and engine.items_not_analysed == 295  # type: ignore[attr-defined]


def test_closing_the_live_view_stops_a_big_files_reader_where_it_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The station view over a big file followed from its start, closed at once: its reader is let go and stops
    (it was left reading the rest into an unbounded queue, nothing showing it)."""
    import console.live.backlog as backlog_module
    from console.cli.common import load_layout
    from console.inputs.uri import open_source
    from console.tui.live_source import LiveSource

    monkeypatch.setattr(backlog_module, "BACKLOG_BYTES", 4 * BLOCK)
    log = tmp_path / "big.log"
    log.write_bytes((Path(__file__).parents[1] / "sample_logs" / "example_station.log").read_bytes() * 16)
    reader = open_source(f"file:{log}", from_start=True)
    assert isinstance(reader, FileSource)
    view = LiveSource(load_layout("example"), [reader])
    view.start()
    assert wait_until(lambda: view.pending(), 30)
    view.stop()
    assert wait_until(lambda: not reader.running, 10)  # stop waits 3 s for it: a loaded machine may need more
    assert reader.bytes_read < log.stat().st_size


@given(
    blocks=st.lists(st.integers(1, 40), min_size=1, max_size=3),
    taken=st.integers(0, 60),
    limit_blocks=st.integers(1, 6),
)
@settings(max_examples=25, deadline=None, derandomize=True)
def test_every_block_is_analysed_or_dropped_on_record_whenever_the_backlog_closes(
    blocks: list[int], taken: int, limit_blocks: int
) -> None:
    """Readers of several files hand blocks over through a small backlog; the consumer takes ``taken`` items and
    closes it.  Nothing is lost and nothing silent: per file, the blocks taken are its first ones in order and
    the record of what was dropped starts at the very next line; taken + dropped is all that was handed over."""
    backlog = Backlog(limit_bytes=limit_blocks * BLOCK)
    threads = []
    for f, n in enumerate(blocks):
        source = FileSource(f"file:f{f}", Path(f"/nonexistent/f{f}.log"))
        put = backlog.putter(source)

        def body(put: Callable[[LineBlock], None] = put, f: int = f, n: int = n) -> None:
            for k in range(n):
                put(LineBlock(f"file:f{f}", f"f{f}", 1 + k, b"%08d\n" % k * (BLOCK // 9), time.monotonic()))

        threads.append(threading.Thread(target=body, daemon=True))
    for t in threads:
        t.start()
    got: dict[str, list[int]] = {}
    for _ in range(min(taken, sum(blocks))):
        item = backlog.get(10.0)
        assert isinstance(item, LineBlock)
        got.setdefault(item.file, []).append(item.first_line)
    backlog.close()
    for t in threads:
        t.join(10.0)
        assert not t.is_alive()  # a reader waiting for room is let go
    dropped, n_dropped = backlog.not_analysed()
    assert sum(len(v) for v in got.values()) + n_dropped == sum(blocks)
    for f, n in enumerate(blocks):
        lines = got.get(f"f{f}", [])
        assert lines == list(range(1, len(lines) + 1))
        assert dropped.get(f"f{f}") == (len(lines) + 1 if len(lines) < n else None)
