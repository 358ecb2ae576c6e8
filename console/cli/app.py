"""The `trackside` command line: assembles the Typer app from console.cli.commands.

Each command lives in its own module under ``console/cli/commands/``; what they
share is in ``console/cli/options.py`` (option types) and
``console/cli/common.py`` (one-line errors, the guard).  Exit codes: 0 ok, 1 findings (``--strict``,
``--fail-on``), 2 usage errors and unreadable inputs (one line on stderr,
never a traceback).
"""

from __future__ import annotations

import importlib
import sys
from typing import Annotated, Any

import typer

# Typer 0.28 parses with a Click of its own: its usage errors are these (pyproject pins Typer 0.28).
from typer._click.exceptions import ClickException, UsageError
from typer.core import TyperCommand, TyperGroup
from typer.models import CommandInfo

from console import __version__, exit_codes
from console.cli.common import OUTPUT_ERRNOS, exit_at_once, finite_numbers, install_process_guards, output_failed
from console.cli.examples import APP_EXAMPLES, EXAMPLES, epilog
from console.safe_text import clean

# The commands, in the order help lists them; each is the function of its name in console.cli.commands.<name>.
COMMANDS = (
    "analyze",
    "speeds",
    "sections",
    "health",
    "frames",
    "approach",
    "gnss",
    "crossing",
    "layout",
    "simulate",
    "ato",
    "station",
    "report",
    "follow",
    "ingest",
    "query",
    "verify",
    "forecast",
)

__all__ = ["app", "run"]


class _Trackside(typer.Typer):
    """The app, plus: output that fails outside a command body (``--help > /dev/full``) is one line, not a traceback;
    and its commands' modules are imported when the commands are first asked for.

    A command line that names a command (``trackside query …``) builds an app of that command alone: its help,
    usage errors and run are the same (they never list the others), without importing and building the fifteen
    others (a third of a short query's start-up).
    """

    _pending = False  # the commands are not registered yet

    @property
    def registered_commands(self) -> list[CommandInfo]:
        if self._pending:
            self._pending = False
            _register(self, COMMANDS)
        return self._registered

    @registered_commands.setter
    def registered_commands(self, value: list[CommandInfo]) -> None:
        self._registered = value

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        named = sys.argv[1] if not args and not kwargs and len(sys.argv) > 1 else None
        if self._pending and named in COMMANDS:
            one = _new_app()
            _register(one, (named,))
            return one()
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


class _OneLineUsageError(ClickException):
    """A usage error said in one line (Click writes the usage, a hint and the error: three)."""

    exit_code = exit_codes.USAGE

    def __init__(self, error: UsageError) -> None:
        super().__init__(error.format_message())
        self.path = error.ctx.command_path if error.ctx is not None else "trackside"

    def show(self, file: Any = None) -> None:
        typer.echo(f"trackside: error: {clean(self.message)} (see {self.path} --help)", file=file, err=file is None)


def _one_line(error: UsageError) -> UsageError | _OneLineUsageError:
    # No arguments at all shows the help (no_args_is_help): that one stays as it is.
    return error if type(error).__name__ == "NoArgsIsHelpError" else _OneLineUsageError(error)


class _OneLineUsage:
    """Usage errors met while parsing a command line (a bad option value, a missing argument) said in one line."""

    def make_context(self, info_name: str | None, args: list[str], parent: Any = None, **extra: Any) -> Any:
        try:
            return super().make_context(info_name, args, parent=parent, **extra)  # type: ignore[misc]
        except UsageError as error:
            raise _one_line(error) from None


class _Command(_OneLineUsage, TyperCommand):
    """A command of the app."""


class _Group(_OneLineUsage, TyperGroup):
    """The app's group: an unknown command is one line too."""

    def resolve_command(self, ctx: Any, args: list[str]) -> Any:
        if args[:1] == ["help"]:  # not "Did you mean 'health'?"
            raise _one_line(
                UsageError(
                    "'help' is not a command: trackside --help lists the commands, trackside COMMAND --help "
                    "explains one",
                    ctx,
                )
            )
        try:
            return super().resolve_command(ctx, args)
        except UsageError as error:
            raise _one_line(error) from None


def _new_app() -> _Trackside:
    new = _Trackside(
        cls=_Group,
        name="trackside",
        help="Terminal console and log analyzer for railway train detection.",
        no_args_is_help=True,
        context_settings={"help_option_names": ["-h", "--help"]},  # -h as most tools take it
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
    new.callback()(main)
    return new


def _register(target: typer.Typer, names: tuple[str, ...]) -> None:
    for name in names:
        module = importlib.import_module(f"console.cli.commands.{name}")
        # A command without examples still works; tests/test_examples.py asks for them.
        examples = EXAMPLES.get(name)
        command = finite_numbers(getattr(module, name))
        target.command(name=name, epilog=epilog(examples) if examples else None, cls=_Command)(command)


def _version(value: bool) -> None:
    if value:
        print(f"trackside {__version__}")
        raise typer.Exit()


def main(
    ctx: typer.Context,
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="Show the version and exit.")
    ] = False,
) -> None:
    """Terminal console and log analyzer for railway train detection."""
    # Closed stdout, SIGTERM (exit 143, partial files removed) and the flush at exit.
    ctx.call_on_close(install_process_guards())


app = _new_app()
app._pending = True


def run() -> None:
    """The ``trackside`` program: the app, ended at once when it is done (:func:`exit_at_once`).  Not for an
    embedding process, which calls :data:`app` and goes on."""
    try:
        app()
    except SystemExit as exc:
        exit_at_once(exc)
        raise
