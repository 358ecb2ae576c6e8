"""trackside verify."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated

import typer

from console import exit_codes
from console.cli.commands.ingest import ArchiveOpt
from console.cli.common import fail, guard, print_json

if TYPE_CHECKING:
    from collections.abc import Callable

    from rich.progress import Progress

    from console.archive.verify import Verification
    from console.cli.common import Console


def verify(
    archive: ArchiveOpt = None,
    deep: Annotated[
        bool,
        typer.Option("--deep", help="Decode every column of every part too (a part damaged inside, not only cut)."),
    ] = False,
    json_out: Annotated[bool, typer.Option("--json", help="Print the result as one JSON document.")] = False,
) -> None:
    """Check the archive against its manifest: every part there and readable, every input file's records and
    rejected lines all stored once. Read-only. Exit 1 when the archive is damaged (a part, a count, or its
    CURRENT or manifest: that one a line on stderr), 2 when there is no archive to check."""
    from console.archive.store import ArchiveDamaged, ArchiveError, archive_dir
    from console.archive.verify import verify_archive
    from console.cli.common import Console

    root = archive_dir(archive)
    err = Console(stderr=True, highlight=False)

    def body() -> int:
        from console.archive.views import require_archive

        try:
            require_archive(root)
            with _bar(err) as on_part:
                result = verify_archive(root, deep=deep, on_part=on_part)
        except ArchiveDamaged as exc:  # damage verify exists to find: its exit code, as for a damaged part
            raise fail(str(exc), exit_codes.FINDINGS) from None
        except ArchiveError as exc:
            raise fail(str(exc)) from None
        if json_out:
            print_json({"schema": "trackside.verify/1", **result.to_json()})
        else:
            _print(result)
        return exit_codes.OK if result.intact else exit_codes.FINDINGS

    raise typer.Exit(guard(body))


class _bar:
    """Parts checked, on a terminal (stderr); nothing in a pipe."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self.progress: Progress | None = None

    def __enter__(self) -> Callable[[int, int], None] | None:
        if not self.console.is_terminal:
            return None
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        bar = Progress(TextColumn("verify"), BarColumn(), MofNCompleteColumn(), console=self.console, transient=True)
        bar.start()
        self.progress = bar
        task = bar.add_task("verify", total=None)

        def on_part(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        return on_part

    def __exit__(self, *exc: object) -> None:
        if self.progress is not None:
            self.progress.stop()


def _print(result: Verification) -> None:
    from rich.table import Table

    from console.cli.common import Console
    from console.plural import count
    from console.safe_text import clean, inert, show_path

    out = Console(highlight=False)
    # Lines that name files are never wrapped (grep finds them whole) and never markup (inert).
    out.print(inert(f"Archive {show_path(result.root)}, generation {result.generation}"), soft_wrap=True)
    t = Table()
    t.add_column("Table")
    t.add_column("Parts", justify="right")
    t.add_column("Rows", justify="right")
    for table in sorted(result.parts):
        t.add_row(table, f"{result.parts[table]:,}", f"{result.rows[table]:,}")
    out.print(t)
    for d in result.damaged:
        out.print(inert(f"damaged  {d.table}: {d.part}: {d.problem}"), soft_wrap=True)
    for m in result.mismatches:
        line = f"counts   {clean(m.file)}: {m.table}: the ledger says {m.ledger:,}, {m.stored:,} stored"
        out.print(inert(line), soft_wrap=True)
    how = "every column decoded" if result.deep else "footers read; --deep decodes every column"
    parts = count(sum(result.parts.values()), "part")
    if result.intact:
        verdict = f"intact: {parts} ({how}); {count(result.files_checked, 'input file')}, each stored whole"
    else:
        wrong = [count(len(result.damaged), "part") + " missing or unreadable"] if result.damaged else []
        if result.mismatches:
            wrong.append(count(len(result.mismatches), "count") + " not as the ledger says")
        # The logs are what an archive is made from: a new archive from them is the repair.
        verdict = f"DAMAGED: {', '.join(wrong)}; ingest the logs again into a new archive"
    if result.unlisted:
        verdict += f"; {count(result.unlisted, 'file')} under data/ no manifest names (the next ingest removes them)"
    out.print(verdict, markup=False, soft_wrap=True)
