"""A progress bar on stderr, only for big inputs on a terminal: bytes read, MB/s, records/s, ETA."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    ProgressColumn,
    Task,
    TaskID,
    TextColumn,
    TimeRemainingColumn,
    TransferSpeedColumn,
)
from rich.text import Text

MIN_BYTES_FOR_PROGRESS = 4 << 20


class RecordRateColumn(ProgressColumn):
    """Records per second so far (shown once a reader reports records)."""

    def render(self, task: Task) -> Text:
        records = int(task.fields.get("records", 0))
        elapsed = task.elapsed or 0.0
        if not records or elapsed <= 0:
            return Text("")
        return Text(f"{records / elapsed:,.0f} records/s", style="progress.data.speed")


class ByteProgress:
    """``advance(n_bytes)``; a reader that counts records also calls :meth:`records`."""

    def __init__(self, bar: Progress, task: TaskID) -> None:
        self._bar = bar
        self._task = task
        self._records = 0

    def __call__(self, n_bytes: int) -> None:
        self._bar.advance(self._task, n_bytes)

    def records(self, n: int) -> None:
        self._records += n
        self._bar.update(self._task, records=self._records)


@contextmanager
def byte_progress(total_bytes: int, label: str, console: Console | None = None) -> Iterator[ByteProgress | None]:
    """Yield a :class:`ByteProgress` (call it with the bytes read), or None when no bar is shown.

    Silent when stderr is not a terminal (cron, pipes) or the input is small.
    """
    console = console or Console(stderr=True)
    if not console.is_terminal or total_bytes < MIN_BYTES_FOR_PROGRESS:
        yield None
        return
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        DownloadColumn(),
        TransferSpeedColumn(),
        RecordRateColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=total_bytes, records=0)
        yield ByteProgress(bar, task)
