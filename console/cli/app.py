"""The `trackside` command line: assembles the Typer app from console.cli.commands.

Each command lives in its own module under ``console/cli/commands/``; what they
share is in ``console/cli/options.py`` (option types) and
``console/cli/common.py`` (one-line errors, the guard).  Exit codes: 0 ok, 1 findings (``--strict``,
``--fail-on``), 2 usage errors and unreadable inputs (one line on stderr,
never a traceback).
"""

from __future__ import annotations

import sys
from typing import Annotated, Any

import typer

from console import __version__
from console.cli.commands import (
    analyze,
    approach,
    ato,
    crossing,
    follow,
    forecast,
    frames,
    gnss,
    health,
    ingest,
    query,
    report,
    sections,
    simulate,
    speeds,
    station,
)
from console.cli.common import OUTPUT_ERRNOS, install_process_guards, output_failed
from console.cli.examples import APP_EXAMPLES, EXAMPLES, epilog

__all__ = ["app"]


class _Trackside(typer.Typer):
    """The app, plus: output that fails outside a command body (``--help > /dev/full``) is one line, not a traceback."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        try:
            return super().__call__(*args, **kwargs)
        except SystemExit as exc:
            # Click ends a help or usage text cut by a closed pipe (`--help | head -1`) with exit 1;
            # a reader that stopped early is not a failure, as with every command's own output.
            if exc.code == 1 and type(sys.stdout).__name__ == "PacifyFlushWrapper":
                raise SystemExit(0) from None
            raise
        except OSError as exc:
            if isinstance(exc, BrokenPipeError) or exc.errno in OUTPUT_ERRNOS:
                raise SystemExit(output_failed(exc)) from None
            raise


app = _Trackside(
    name="trackside",
    help="Terminal console and log analyzer for railway train detection.",
    no_args_is_help=True,
    # Shell completion: `trackside --install-completion` (bash, zsh, fish, PowerShell).
    add_completion=True,
    pretty_exceptions_enable=False,
    # Help is plain text: Rich markup would eat examples such as `[[crossings]]`.
    rich_markup_mode=None,
    epilog=epilog(
        APP_EXAMPLES,
        "Exit codes: 0 ok; 1 findings (--strict, --fail-on); 2 bad input or usage; 130 Ctrl-C; 143 SIGTERM."
        " A file argument '-' reads standard input. Walk-throughs and tables: the README and docs/.",
    ),
)

for _module in (
    analyze,
    speeds,
    sections,
    health,
    frames,
    approach,
    gnss,
    crossing,
    simulate,
    ato,
    station,
    report,
    follow,
    ingest,
    query,
    forecast,
):
    _name = _module.__name__.rsplit(".", 1)[1]
    # A command without examples still works; tests/test_examples.py asks for them.
    _examples = EXAMPLES.get(_name)
    app.command(name=_name, epilog=epilog(_examples) if _examples else None)(getattr(_module, _name))


def _version(value: bool) -> None:
    if value:
        print(f"trackside {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    ctx: typer.Context,
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")
    ] = False,
) -> None:
    """Terminal console and log analyzer for railway train detection."""
    # Closed stdout, SIGTERM (exit 143, partial files removed) and the flush at exit.
    ctx.call_on_close(install_process_guards())
