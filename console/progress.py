"""A byte progress bar on stderr, only for big inputs on a terminal."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    TextColumn,
    TimeRemainingColumn,
    TransferSpeedColumn,
)

MIN_BYTES_FOR_PROGRESS = 4 << 20


@contextmanager
def byte_progress(
    total_bytes: int, label: str, console: Console | None = None
) -> Iterator[Callable[[int], None] | None]:
    """Yield an ``advance(n_bytes)`` callback, or None when no bar is shown.

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
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=total_bytes)
        yield lambda n: bar.advance(task, n)
