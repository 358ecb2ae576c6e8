"""A progress bar on stderr, only for big inputs on a terminal: bytes read, MB/s, records/s, ETA."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import Console
    from rich.progress import Progress, TaskID

MIN_BYTES_FOR_PROGRESS = 4 << 20


def _record_rate_column() -> Any:
    """Records per second so far (shown once a reader reports records).  Rich's progress module is
    loaded only when a bar is shown: a small input's start-up does not pay for it."""
    from rich.progress import ProgressColumn, Task
    from rich.text import Text

    class RecordRateColumn(ProgressColumn):
        def render(self, task: Task) -> Text:
            records = int(task.fields.get("records", 0))
            elapsed = task.elapsed or 0.0
            if not records or elapsed <= 0:
                return Text("")
            return Text(f"{records / elapsed:,.0f} records/s", style="progress.data.speed")

    return RecordRateColumn()


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


def _stderr_may_be_terminal() -> bool:
    """Whether Rich could take stderr for a terminal: it is one, or the environment says to treat it as one
    (``TTY_COMPATIBLE``, ``FORCE_COLOR``: Rich's own rules decide then)."""
    if os.environ.get("TTY_COMPATIBLE") or os.environ.get("FORCE_COLOR") is not None:
        return True
    try:
        return sys.stderr is not None and sys.stderr.isatty()
    except ValueError:  # closed
        return False


@contextmanager
def byte_progress(total_bytes: int, label: str, console: Console | None = None) -> Iterator[ByteProgress | None]:
    """Yield a :class:`ByteProgress` (call it with the bytes read), or None when no bar is shown.

    Silent when stderr is not a terminal (cron, pipes) or the input is small.
    """
    if total_bytes < MIN_BYTES_FOR_PROGRESS or (console is None and not _stderr_may_be_terminal()):
        yield None  # Rich not loaded: a script's run does not pay its start-up (~20 ms)
        return
    from rich.console import Console

    console = console or Console(stderr=True)
    if not console.is_terminal:
        yield None
        return
    from rich.progress import (
        BarColumn,
        DownloadColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
        TransferSpeedColumn,
    )

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        DownloadColumn(),
        TransferSpeedColumn(),
        _record_rate_column(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=total_bytes, records=0)
        yield ByteProgress(bar, task)
