"""trackside ingest."""

from __future__ import annotations

import errno
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from console import exit_codes
from console.cli.common import fail, guard, print_json

if TYPE_CHECKING:
    from console.cli.common import Console
from console.fleet.options import EngineOpt, SchedulerOpt, WorkersOpt

ArchiveOpt = Annotated[
    Path | None,
    typer.Option(
        "--archive",
        metavar="DIR",
        help="Archive directory [default: $TRACKSIDE_ARCHIVE, else $XDG_DATA_HOME/trackside/archive].",
        show_default=False,
    ),
]


def ingest(
    paths: Annotated[
        list[Path],
        typer.Argument(
            metavar="PATH...",
            help="Files, directories (a `trackside simulate` output reads whole), .gz, or - for stdin.",
        ),
    ],
    archive: ArchiveOpt = None,
    layout: Annotated[
        str | None,
        typer.Option(
            "--layout",
            metavar="LAYOUT",
            help="Layout for the derived tables (file, or osong / example).",
            show_default=False,
        ),
    ] = None,
    no_wait: Annotated[
        bool, typer.Option("--no-wait", help="Fail at once when another ingest holds the archive.")
    ] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the summary as one JSON document.")] = False,
    engine: EngineOpt = "local",
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
) -> None:
    """Ingest logs into the archive, once each: a file seen before adds nothing; a grown file is read from where
    the last ingest stopped."""
    from console.memory import one_malloc_arena

    one_malloc_arena()  # before pyarrow is imported: its first thread would take a heap of its own
    from console.archive.ingest import IngestSummary, run_ingest
    from console.archive.store import ArchiveError, archive_dir
    from console.cli.common import Console
    from parsers.sources import InputError

    root = archive_dir(archive)
    err = Console(stderr=True, highlight=False)

    def waiting() -> None:
        err.print(f"waiting for another ingest to finish writing {root} …", markup=False)

    def body() -> int:
        from console.cli.commands.engine import checked_spec, engine_failure
        from console.fleet import engine_scope
        from console.fleet.options import FleetError

        spec = checked_spec(engine, workers, scheduler)  # a usage mistake: one line, before anything is read
        if layout is not None:
            from console.cli.common import load_layout

            load_layout(layout)  # a bad layout fails before anything is read
        summary: IngestSummary
        try:
            with _progress(err) as bar:
                on_bytes, on_file = bar.callbacks()
                # The derivation's partitions run on the engine; their tasks get a line in the ingest's bar.
                with engine_scope(
                    spec, say=lambda line: err.print(line, markup=False, soft_wrap=True), console=err, host=bar.host
                ):
                    summary = run_ingest(
                        paths,
                        root,
                        layout=layout,
                        wait=not no_wait,
                        on_wait=waiting,
                        on_bytes=on_bytes,
                        on_file=on_file,
                    )
        except FleetError as exc:
            raise engine_failure(exc) from None
        except ArchiveError as exc:
            raise fail(str(exc)) from None
        except InputError as exc:
            raise fail(f"{exc} (archive unchanged)") from None
        except OSError as exc:
            if exc.errno == errno.ENOSPC:
                raise fail(f"{root}: no space left on device: archive unchanged") from None
            if exc.errno in (errno.EACCES, errno.EROFS, errno.EDQUOT):
                raise fail(f"{exc.filename or root}: {exc.strerror}: archive unchanged") from None
            raise
        if json_out:
            print_json(summary.to_dict())
        else:
            _print_summary(summary)
        return exit_codes.OK

    raise typer.Exit(guard(body))


class _progress:
    """Files, bytes and records/s on a terminal (stderr); nothing in a pipe."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.bar: Any = None

    def __enter__(self) -> _progress:
        return self

    def host(self) -> Any:
        """The live bar, if any (the engine's task line goes in it)."""
        return self.bar

    def callbacks(self) -> tuple[Callable[[int], None] | None, Callable[[str], None] | None]:
        if not self.console.is_terminal:
            return None, None
        from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn, TransferSpeedColumn

        from console.fleet.progress import TasksOr

        bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TasksOr(DownloadColumn()),  # the engine's line (--engine dask) counts tasks, not bytes
            TasksOr(TransferSpeedColumn(), show_tasks=False),
            console=self.console,
            transient=True,
        )
        bar.start()
        task = bar.add_task("ingest", total=None)
        self.bar = bar
        files = [0]

        def on_bytes(n: int) -> None:
            bar.advance(task, n)

        def on_file(name: str) -> None:
            files[0] += 1
            short = name if len(name) < 40 else "…" + name[-39:]
            bar.update(task, description=f"file {files[0]}: {short}")

        return on_bytes, on_file

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()


def _print_summary(summary: object) -> None:
    from console.archive.ingest import IngestSummary

    assert isinstance(summary, IngestSummary)
    from console.plural import count
    from console.safe_text import clean

    lines: list[str] = [f"warning  {clean(w)}" for w in summary.warnings]
    rate = summary.records / summary.seconds if summary.seconds > 0 else 0.0
    for f in summary.files:
        if f.action in ("new", "grown", "replace"):
            held = (
                f"; {count(f.held_back_bytes, 'byte')} after the last line end held back"
                " (an unfinished line, read when the file grows; lines that end in CR alone are not taken)"
                if f.held_back_bytes
                else ""
            )
            lines.append(
                f"added    {clean(f.path)}: {count(f.records, 'record')}, {f.rejected} rejected ({clean(f.note)})"
                + held
            )
        elif f.kind == "layout":
            lines.append(f"layout   {clean(f.path)}: {clean(f.note)}")
        else:
            lines.append(f"skipped  {clean(f.path)}: {clean(f.note)}")
    state = f"generation {summary.generation}" if summary.published else "nothing new: archive unchanged"
    lines.append(
        f"{count(len(summary.added), 'file')} added, {len(summary.skipped)} skipped;"
        f" {count(summary.records, 'record')}, "
        f"{count(summary.rejected, 'rejected line')}, {summary.seconds:.1f} s ({rate:,.0f} records/s); {state}"
    )
    if summary.rejected:
        lines.append('rejected lines: trackside query "SELECT * FROM rejected"')
    # Plain lines, never wrapped: scripts grep them.
    sys.stdout.write("\n".join(lines) + "\n")
    sys.stdout.flush()
