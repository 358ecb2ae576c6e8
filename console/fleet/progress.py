"""Tasks done / total on stderr, only on a terminal (cron and pipes get nothing)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rich.console import Console, RenderableType
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.text import Text

TASKS = "tasks"  # the unit field of the engine's line in a command's bar


class TasksOr(ProgressColumn):
    """In a command's bar: its own column for its lines, "done/total tasks" (or nothing) for the engine's line."""

    def __init__(self, column: ProgressColumn, show_tasks: bool = True) -> None:
        super().__init__()
        self.column = column
        self.show_tasks = show_tasks

    def render(self, task: Task) -> RenderableType:
        if task.fields.get("unit") != TASKS:
            return self.column.render(task)
        return Text(f"{int(task.completed)}/{int(task.total or 0)} tasks" if self.show_tasks else "")


@contextmanager
def task_progress(
    total: int, label: str, console: Console | None = None, host: Progress | None = None
) -> Iterator[Callable[[int], None]]:
    """Yield ``done(n)``: n more tasks finished.  A bar when stderr is a terminal, a no-op otherwise.

    ``host``: a bar the command already shows (Rich allows one live display at
    a time): the tasks get a line of their own in it (``unit`` field
    ``"tasks"``: wrap the bar's unit columns in :class:`TasksOr`), removed when done.
    """
    if host is not None and total > 0:
        line = host.add_task(f"{label} (tasks)", total=total, unit=TASKS)
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
