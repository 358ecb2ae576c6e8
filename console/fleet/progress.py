"""Tasks done / total on stderr, only on a terminal (cron and pipes get nothing)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


@contextmanager
def task_progress(
    total: int, label: str, console: Console | None = None, host: Progress | None = None
) -> Iterator[Callable[[int], None]]:
    """Yield ``done(n)``: n more tasks finished.  A bar when stderr is a terminal, a no-op otherwise.

    ``host``: a bar the command already shows (Rich allows one live display at
    a time): the tasks get a line of their own in it, removed when done.
    """
    if host is not None and total > 0:
        line = host.add_task(f"{label} (tasks)", total=total)
        try:
            yield lambda n: host.advance(line, n)
        finally:
            host.remove_task(line)
        return
    console = console or Console(stderr=True)
    if not console.is_terminal or total <= 0:
        yield lambda _n: None
        return
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("tasks"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=total)
        yield lambda n: bar.advance(task, n)
